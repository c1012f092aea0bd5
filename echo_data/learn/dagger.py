"""DAgger for Navigate: roll the learner in the world, ask the scripted expert what it would do
from each state the learner reached, add those labelled rows, retrain (Ross et al. 2011,
"A Reduction of Imitation Learning and Structured Prediction to No-Regret Online Learning").

Why Navigate only: its expert is a planner plus a path follower, so it can be asked from any
base pose (`echo_data.skills.navigate.Relabeller`: the expert's own planning and re-planning,
its speed ramp started from the base's current commanded velocity). The manipulation experts
(Pick, Place, OpenDoor, CloseSink) are open-loop motion plans with grasp phases: from a state
where the learner holds the handle half-turned or the object half-lifted there is no expert
answer short of restarting the skill, so DAgger refuses any other skill (one-line error).

Only train-split episodes of the dataset's recipe are rolled (indices below the train split's
size in the dataset), never the test split. Rollouts act with the learner alone (beta = 0).
Rows added by DAgger train only; validation stays on the expert's held-out episodes so the
losses of rounds stay comparable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import dataset_recipe
from echo_data.learn import runs
from echo_data.skill_table import SKILLS, approach_skill, skill

DAGGER_LOG = runs.DAGGER_LOG


class DaggerError(runs.RunError):
    """DAgger cannot run as asked (one line)."""


@dataclass
class Rollouts:
    """Labelled rows from learner rollouts (the `SkillRows` fields training appends)."""

    inputs: dict[str, Any]
    actions: np.ndarray  # (n, 1, ACTION_DIM): the expert's labels
    success: list[bool]  # per rollout: the learner's Navigate success test at its end
    agreement: float  # mean |learner - expert| of (vx, wz) over the visited states

    def __len__(self) -> int:
        return len(self.actions)


class _Labels:
    """`run_episode`'s step hook: before each learner action, the expert's label for the state and
    the learner's inputs; ends the episode when the labeller has nothing more to say."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.parts: dict[str, list[Any]] = {}
        self.labels: list[np.ndarray] = []
        self.gaps: list[float] = []
        self.label: Any = None  # echo_data.skills.navigate.Relabeller of the skill being rolled
        self.last = np.zeros(3, dtype=np.float32)

    def start(self) -> None:
        self.label, self.last = None, np.zeros(3, dtype=np.float32)

    def __call__(self, env: Any, obs: dict[str, Any], a: np.ndarray, k: int, call: Any, flags: tuple[bool, ...]) -> None:
        from echo_data.agents.runtime import StopEpisode
        from echo_data.skills.navigate import Relabeller

        if self.label is None:  # at the skill's first step, before anything moved
            self.label = Relabeller(env.world, call.target, env.nav_grid())
        y = self.label(self.last)
        if y is None:
            raise StopEpisode
        for key, v in self.policy.inputs(obs).items():
            self.parts.setdefault(key, []).append(v)
        self.labels.append(y)
        self.gaps.append(float(np.abs(a[[0, 2]] - y[[0, 2]]).mean()))
        self.last = a[:3]


def collect(run: Path, dataset: Path, episodes: list[int], max_steps: int | None = None) -> Rollouts:
    """Roll the policy in `run` on train episodes `episodes` (their first skill, Navigate, through
    `run_episode`), label every visited state."""
    import torch

    from echo_data.agents.builtin import OraclePlanner
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv
    from echo_data.evaluation.run import needs
    from echo_data.learn.policy import BCPolicy
    from echo_data.scene.sampling import SamplingError

    policy = BCPolicy.from_run(run)
    recipe, _ = dataset_recipe(dataset)
    images, audio = needs(policy)
    env = EchoDataEnv(recipe, split="train", images=images, audio=audio)
    hook = _Labels(policy)
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
            if spec is None or spec.chain[0].skill != approach_skill().name:
                continue
            obs, info = env.reset(options={"spec": spec})
            hook.start()
            run_episode(env, obs, info, OraclePlanner(), policy, on_step=hook, max_steps=max_steps, skills=1)
            success.append(bool(env.success_flags[0]))  # the learner's Navigate success test at its end
    finally:
        env.close()
    inputs = {k: torch.cat(v) for k, v in hook.parts.items()}
    acts = np.stack(hook.labels)[:, None, :] if hook.labels else np.zeros((0, 1, 12), np.float32)
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
