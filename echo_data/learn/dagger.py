"""DAgger for every skill: roll the learner in the world, ask the scripted expert what it would do
from each state the learner reached, add those labelled rows, retrain (Ross et al. 2011,
"A Reduction of Imitation Learning and Structured Prediction to No-Regret Online Learning").

Every expert can be asked from any state a learner reaches:
- Navigate's (the chain's approach skill) is a planner plus a path follower
  (`echo_data.skills.navigate.Relabeller`: the expert's own planning and re-planning, its speed
  ramp started from the base's current commanded velocity);
- the manipulation experts (Pick, Place, OpenDoor, CloseSink) are closed-loop end-effector
  controllers (`echo_data.skills.servo`, docs/manipulation_experts.md), asked through
  `echo_data.skills.labeller.ExpertLabeller`: the expert advanced once per learner step from the
  learner's state, started afresh on that state when it ends or the grasp changes against its
  command (a missed grasp: it re-aims and regrasps; a leaf already held: it goes on swinging).

A rollout starts where the skill starts in the episode's chain: the chain's earlier skills are
run by the experts (`agents.compose.SkillDispatch`), then the learner acts in its first call of
the skill and every state it visits there is labelled (`run_episode`'s `on_step` hook), until its
success test holds, its budget or `--dagger-steps` runs out, or the expert has nothing to do from
there. Episodes whose chain lacks the skill are skipped. Labels are in the run's action column:
`action.ee` as the expert commands it, or `action`, its joint form from the commanded state.

Only train-split episodes of the dataset's recipe are rolled (indices below the train split's
size in the dataset), never the test split. Rollouts act with the learner alone (beta = 0).
Rows added by DAgger train only; validation stays on the expert's held-out episodes so the
losses of rounds stay comparable.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import dataset_recipe
from echo_data.learn import runs
from echo_data.skill_table import SKILLS, skill

DAGGER_LOG = runs.DAGGER_LOG


class DaggerError(runs.RunError):
    """DAgger cannot run as asked (one line)."""


@dataclass
class Rollouts:
    """Labelled rows from learner rollouts (the `SkillRows` fields training appends)."""

    inputs: dict[str, Any]
    actions: np.ndarray  # (n, 1, A): the expert's labels in the run's action column
    success: list[bool]  # per rollout: the learner's success test at its end
    agreement: float  # mean |learner - expert| over the visited states (a drive: of (vx, wz))

    def __len__(self) -> int:
        return len(self.actions)


Label = Callable[[np.ndarray], "np.ndarray | None"]


def labeller(env: Any, call: Any, column: str) -> Label:
    """The expert of `call.skill` as a label function: the learner's last action -> the label of
    the state now in `column`'s form (None: the expert has nothing to do from here)."""
    from echo_data.dataset.schema import ACTION
    from echo_data.skill_table import SKILLS
    from echo_data.skills.labeller import ExpertLabeller
    from echo_data.skills.navigate import Relabeller

    ee = env.world.robot.ee
    if SKILLS[call.skill].role == "approach":  # a planner + follower: re-planned, its ramp resumed from the learner's last command
        relabel = Relabeller(env.world, call.target, env.nav_grid())

        def drive(last: np.ndarray) -> np.ndarray | None:
            y = relabel(last[:3])
            return y if y is None or column == ACTION else ee.to_ee(y)

        return drive
    expert = ExpertLabeller(env.world, call, env.episode)

    def manipulate(last: np.ndarray) -> np.ndarray | None:
        y = expert()
        return y if y is None or column != ACTION else expert.joint(y)

    return manipulate


class _Labels:
    """`run_episode`'s step hook: at each learner step of chain entry `k`, before the action, the
    expert's label for the state and the learner's inputs; ends the episode when the labeller has
    nothing more to say or `limit` states are labelled."""

    def __init__(self, policy: Any, column: str, limit: int | None) -> None:
        self.policy, self.column, self.limit = policy, column, limit
        self.parts: dict[str, list[Any]] = {}
        self.labels: list[np.ndarray] = []
        self.gaps: list[float] = []
        self.label: Label | None = None
        self.k = 0
        self.n = 0
        self.last = np.zeros(3, dtype=np.float32)

    def start(self, k: int) -> None:
        self.label, self.k, self.n, self.last = None, k, 0, np.zeros(3, dtype=np.float32)

    def __call__(self, env: Any, obs: dict[str, Any], a: np.ndarray, k: int, call: Any, flags: tuple[bool, ...]) -> None:
        from echo_data.agents.runtime import StopEpisode
        from echo_data.skill_table import SKILLS

        if k != self.k or call.skill != self.policy.skill:  # the experts' skills before it, a carry before it (agents.runtime.carry_call)
            return
        if self.limit is not None and self.n >= self.limit:
            raise StopEpisode
        if self.label is None:  # at the skill's first step, before anything moved
            self.label = labeller(env, call, self.column)
        y = self.label(self.last)
        if y is None:
            raise StopEpisode
        for key, v in self.policy.inputs(obs).items():
            self.parts.setdefault(key, []).append(v)
        self.labels.append(y)
        dims = [0, 2] if SKILLS[call.skill].role == "approach" else slice(None)  # a drive: its (vx, wz); else the whole action
        self.gaps.append(float(np.abs(a[dims] - y[dims]).mean()))
        self.last = a
        self.n += 1


def collect(run: Path, dataset: Path, episodes: list[int], max_steps: int | None = None) -> Rollouts:
    """Roll the policy in `run` on train episodes `episodes` (the experts up to its skill's first
    call in the chain, then the learner, through `run_episode`), label every state it visits;
    `max_steps`: at most that many learner steps per rollout."""
    import torch

    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.compose import SkillDispatch
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv
    from echo_data.evaluation.run import needs
    from echo_data.learn.policy import BCPolicy
    from echo_data.learn.select import COLUMN_OF_SPACE
    from echo_data.scene.sampling import SamplingError

    policy = BCPolicy.from_run(run)
    column = policy.config.action_column
    mode = next(m for m, c in COLUMN_OF_SPACE.items() if c == column)
    recipe, _ = dataset_recipe(dataset)
    images, audio = needs(policy)
    env = EchoDataEnv(recipe, split="train", images=images, audio=audio, action_mode=mode)
    agent = SkillDispatch({policy.skill: policy}, OracleSkills())
    hook = _Labels(policy, column, max_steps)
    success: list[bool] = []
    try:
        for i in episodes:
            spec = None
            for attempt in range(3):
                try:
                    spec = env.sample_spec("train", i, attempt)
                    break
                except SamplingError:
                    continue
            k = next((j for j, c in enumerate(spec.chain) if c.skill == policy.skill), None) if spec is not None else None
            if k is None:
                continue
            obs, info = env.reset(options={"spec": spec})
            hook.start(k)
            run_episode(env, obs, info, OraclePlanner(), agent, on_step=hook, skills=k + 1)
            success.append(bool(env.success_flags[k]))  # the learner's success test at its end
    finally:
        agent.close()
        env.close()
    inputs = {k: torch.cat(v) for k, v in hook.parts.items()}
    width = len(policy.config.action_names)
    acts = np.stack(hook.labels)[:, None, :] if hook.labels else np.zeros((0, 1, width), np.float32)
    return Rollouts(inputs, acts.astype(np.float32), success, float(np.mean(hook.gaps)) if hook.gaps else math.nan)


def run_dagger(cfg: Any, out: Path, rounds: int, episodes_per_round: int, max_steps: int | None, progress: bool,
               resume: bool = False) -> dict[str, Any]:
    """BC on the dataset, then `rounds` of collect + retrain on the aggregate; returns the last summary.

    `resume`: the BC run already in `out` (finished or not) is continued instead of trained anew,
    so an existing behaviour-cloning run can be DAgger'd without paying for it twice. Rounds
    themselves always start from the first."""
    from echo_data.learn.fit import train_skill as train_bc

    if not skill(cfg.skill).labels_any_state:
        able = ", ".join(n for n, s in SKILLS.items() if s.labels_any_state)
        raise DaggerError(f"--dagger: only {able}'s expert can act from any state (not {cfg.skill!r}; see docs/learners.md)")
    if cfg.window() != 1 or cfg.SEQUENCE:
        raise DaggerError("--dagger: the expert labels one action per state: train bc with --chunk 1")
    _, n_train = dataset_recipe(Path(cfg.dataset))
    if episodes_per_round > n_train:
        raise DaggerError(f"--dagger-episodes {episodes_per_round}: the train split of {cfg.dataset} has {n_train} episodes")
    summary = train_bc(cfg, out, resume=resume, overwrite=not resume, progress=progress)
    agg: Rollouts | None = None
    log = ["round,episodes,rows_added,rows_aggregated,learner_success,learner_expert_gap,best_val_loss"]
    for r in range(1, rounds + 1):
        eps = [((r - 1) * episodes_per_round + j) % n_train for j in range(episodes_per_round)]
        new = collect(out, Path(cfg.dataset), eps, max_steps)
        agg = new if agg is None else _concat(agg, new)
        summary = train_bc(cfg, out, overwrite=True, progress=progress, extra=agg)
        rate = sum(new.success) / len(new.success) if new.success else math.nan
        log.append(f"{r},{' '.join(map(str, eps))},{len(new)},{len(agg)},{rate:.4f},{new.agreement:.4f},{summary['best_val_loss']}")
        runs.write_file(out, DAGGER_LOG, ("\n".join(log) + "\n").encode())
    summary["dagger"] = {"rounds": rounds, "rows_aggregated": len(agg) if agg is not None else 0, "log": str(out / DAGGER_LOG)}
    return summary


def _concat(a: Rollouts, b: Rollouts) -> Rollouts:
    import torch

    if not len(b):
        return a
    if not len(a):
        return b
    return Rollouts({k: torch.cat([a.inputs[k], b.inputs[k]]) for k in a.inputs}, np.concatenate([a.actions, b.actions]),
                    a.success + b.success, (a.agreement * len(a) + b.agreement * len(b)) / (len(a) + len(b)))
