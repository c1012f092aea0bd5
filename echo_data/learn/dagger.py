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
the skill and every state it visits there is labelled (`run_episode`'s `on_step` hook), until it
ends as evaluation ends it (below), its budget or `--dagger-steps` runs out, or the expert has
nothing to do from there. Episodes whose chain lacks the skill are skipped. Labels are in the run's action column:
`action.ee` as the expert commands it, or `action`, its joint form from the commanded state.

Only train-split episodes of the dataset's recipe are rolled (indices below the train split's
size in the dataset), never the test split. Rollouts act with the learner alone (beta = 0).
Rows added by DAgger train only; validation stays on the expert's held-out episodes so the
losses of rounds stay comparable.

A rollout is kept as one segment, like a skill segment of the dataset: its rows in the order the
learner visited them. So every learner takes DAgger rows the way it takes the dataset's: a
recurrent one (BC-RNN) trains on the rollout as a whole segment, its state zero at the rollout's
first row; a chunking one (ACT, Diffusion Policy, `bc --chunk k`) takes at row t the labels of
rows t .. t+k-1 of the same rollout (the expert's action at each state the learner went on to
visit; padding past the rollout's end masked), as the dataset's chunks take the expert's next
actions; an observation history is clamped at the rollout's first row.

The expert's take-over (`--dagger-chunk takeover`, after HG-DAgger, Kelly et al. 2019, "HG-DAgger:
Interactive Imitation Learning with Human Experts"): the learner acts until a step drawn uniformly
from 0 .. the mean length of the skill's demonstration segments, then the expert takes over and
acts from the learner's state to the skill's end; only the states from the take-over on are added,
labelled with what the expert executed there. So each added rollout is a demonstration the expert
really gave from where the learner had led the robot, and a chunk of it is the expert's own next
actions, as a dataset segment's (the "path" chunks above are not: the learner's later states).
Where HG-DAgger's human judges when to step in, the step is drawn: no gate to tune. A rollout that
ends before its take-over step adds nothing; the log counts take-overs.

The STOP (`--stop`): each row also says whether the expert would end the skill in that state:
for a drive that hands over (Navigate before a skill acting on its target) the environment's
`handed_over` for the chain entry (docs/handover.md), for any other drive its success test; for
a manipulation skill its success test holds and the expert has nothing left to do (that state
is added with the expert's last command as its action, as a dataset segment's last row carries
it, and the rollout ends). A rollout goes on the way evaluation runs the learner: a drive that
does not STOP past the paper's 1.5 m region until it hands over (`run_episode`'s default
`drive_end`), a learner that STOPs until it STOPs (that state is labelled too: a STOP where the
expert would go on is labelled 0) or its budget runs out.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
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
    """Labelled learner rollouts, each one segment (contiguous rows, in the order visited)."""

    inputs: dict[str, Any]  # the learner's prepared inputs at each state, leading dimension = rows
    labels: np.ndarray  # (n, A): the expert's label of each state in the run's action column
    stops: np.ndarray  # (n,) 1.0 where the expert would end the skill in that state (see the module docstring)
    segments: np.ndarray  # (n,) the rollout each row belongs to, 0 .. rollouts-1, contiguous
    success: list[bool]  # per rolled episode: the learner's success test at its end
    agreement: float  # mean |learner - expert| over the visited states (a drive: of (vx, wz))
    first_only: bool = False  # a chunk target supervises only its first action (`--dagger-chunk first`)
    takeovers: int = 0  # rollouts the expert took over (`--dagger-chunk takeover`)
    # per take-over: (what the learner would have commanded, what the expert commanded) in the state it took over
    switches: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.labels)

    @property
    def rollouts(self) -> int:
        """Segments (rollouts with at least one labelled row)."""
        return len(np.unique(self.segments))

    def windows(self, chunk: int, stop: bool) -> tuple[np.ndarray, np.ndarray]:
        """Training targets as the dataset's windows: (n, chunk, A (+1 with `stop`)) the labels of
        rows t .. t+chunk-1 of each row's own rollout, clamped at its last row, and (n, chunk) the
        pad mask (True past the rollout's end; a padded STOP entry is 0, as the reader's)."""
        rows = np.arange(len(self))
        _, first, inverse, count = np.unique(self.segments, return_index=True, return_inverse=True, return_counts=True)
        end = (first + count)[inverse]  # each row's rollout end (exclusive): rollouts are contiguous
        at = rows[:, None] + np.arange(chunk)[None, :]
        pad = at >= end[:, None]
        if self.first_only:  # only the expert's label of the state itself: the rest of the chunk is the learner's path, not the expert's
            pad[:, 1:] = True
        at = np.minimum(at, end[:, None] - 1)
        acts = self.labels[at]
        if stop:
            acts = np.concatenate([acts, (self.stops[at] * ~pad)[..., None]], axis=-1)
        return acts.astype(np.float32), pad


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


def drive_stops(env: Any, k: int) -> bool | None:
    """Whether chain entry `k`, a drive, is where its expert would stop now: `handed_over` when
    it hands over to a skill's stance, else its success test (what ends a learned drive in
    `run_episode`); None for a skill that is no drive (its expert decides, `_Labels`)."""
    from echo_data.skill_table import SKILLS, handover_call

    chain = env.episode.chain
    if SKILLS[chain[k].skill].role != "approach":
        return None
    return bool(env.handover_flags[k] if handover_call(chain, k) is not None else env.success_flags[k])


class _Labels:
    """`run_episode`'s step hook: at each learner step of chain entry `k`, before the action, the
    expert's label for the state, its STOP and the learner's inputs; ends the episode when the
    labeller has nothing more to say or `limit` states are labelled. `stop`: the learner STOPs
    (`--stop`): the state a manipulation expert ends in is added as a STOP row."""

    def __init__(self, policy: Any, column: str, limit: int | None, stop: bool = False, takeover: tuple[int, int] | None = None) -> None:
        self.policy, self.column, self.limit, self.stop = policy, column, limit, stop
        # `--dagger-chunk takeover`: (seed, horizon): the expert takes over at a step drawn from 0 .. horizon-1 per rollout
        self.rng = np.random.default_rng(takeover[0]) if takeover is not None else None
        self.horizon = takeover[1] if takeover is not None else 0
        self.at: int | None = None  # this rollout's take-over step (None: the learner acts throughout)
        self.steps = 0  # states of this rollout seen so far (labelled or not)
        self.took_over = 0
        self._now: tuple[int, np.ndarray | None] | None = None  # (step, label) computed for the take-over's action
        self.switches: list[tuple[np.ndarray, np.ndarray]] = []  # (learner's, expert's) action where each take-over happened
        self.parts: dict[str, list[Any]] = {}
        self.labels: list[np.ndarray] = []
        self.stops: list[float] = []
        self.segments: list[int] = []
        self.gaps: list[float] = []
        self.label: Label | None = None
        self.k = 0
        self.n = 0
        self.rollout = -1
        self.last = np.zeros(3, dtype=np.float32)

    def start(self, k: int) -> None:
        """A new rollout (segment) of chain entry `k`."""
        self.label, self.k, self.n, self.last = None, k, 0, np.zeros(3, dtype=np.float32)
        self.rollout += 1
        self.steps, self._now = 0, None
        self.at = int(self.rng.integers(0, self.horizon)) if self.rng is not None else None

    def taking_over(self) -> bool:
        """The expert acts in the state now (`--dagger-chunk takeover`, past this rollout's step)."""
        return self.at is not None and self.steps >= self.at

    def expert_action(self, env: Any, call: Any) -> np.ndarray | None:
        """The expert's label of the state now, computed once: the take-over executes it, `record` adds it."""
        if self.label is None:
            self.label = labeller(env, call, self.column)
        if self._now is None or self._now[0] != self.steps:
            self._now = (self.steps, self.label(self.last))
        return self._now[1]

    def __call__(self, env: Any, obs: dict[str, Any], a: np.ndarray, k: int, call: Any, flags: tuple[bool, ...]) -> None:
        if k == self.k and call.skill == self.policy.skill:  # not the experts' skills before it, nor a carry before it (agents.runtime.carry_call)
            self.record(env, obs, a, call)

    def record(self, env: Any, obs: dict[str, Any], a: np.ndarray | None, call: Any) -> None:
        """Label the state now (`a`: the learner's action in it; None: the learner STOPped there)."""
        from echo_data.agents.runtime import StopEpisode
        from echo_data.skill_table import SKILLS

        if self.limit is not None and self.n >= self.limit:
            raise StopEpisode
        y = self.expert_action(env, call)  # the expert asked once per state, before anything moved at the first
        stop = drive_stops(env, self.k)
        before = self.at is not None and self.steps < self.at  # the learner's states before the take-over: not added
        self.took_over += int(self.steps == self.at)
        self.steps += 1
        if y is None:  # nothing to do from here: a manipulation expert that has ended adds its STOP row
            if self.stop and stop is None and self.n and env.success_flags[self.k] and not before:
                self._add(obs, self.labels[-1], True)
            raise StopEpisode
        if not before:
            self._add(obs, y, bool(stop))
        if a is not None:
            if self.at is None or before:  # the learner's own actions (the expert's after a take-over)
                dims = [0, 2] if SKILLS[call.skill].role == "approach" else slice(None)  # a drive: its (vx, wz); else the whole action
                self.gaps.append(float(np.abs(a[dims] - y[dims]).mean()))
            self.last = a

    def _add(self, obs: dict[str, Any], y: np.ndarray, stop: bool) -> None:
        for key, v in self.policy.inputs(obs).items():
            self.parts.setdefault(key, []).append(v)
        self.labels.append(y)
        self.stops.append(float(stop))
        self.segments.append(self.rollout)
        self.n += 1

    def rollouts(self, width: int, success: list[bool]) -> Rollouts:
        """What was labelled, rollouts numbered 0.. in order (those without rows dropped)."""
        import torch

        _, segments = np.unique(np.asarray(self.segments, dtype=np.int64), return_inverse=True)
        labels = np.stack(self.labels).astype(np.float32) if self.labels else np.zeros((0, width), np.float32)
        return Rollouts({k: torch.cat(v) for k, v in self.parts.items()}, labels, np.asarray(self.stops, np.float32),
                        segments.astype(np.int64), success, float(np.mean(self.gaps)) if self.gaps else math.nan, takeovers=self.took_over,
                        switches=list(self.switches))


class _TakeOver:
    """The learner seen by `run_episode` under `--dagger-chunk takeover`: it acts until its
    rollout's take-over step, the expert (its label of each state, executed) from there on."""

    def __init__(self, policy: Any, hook: _Labels, env: Any) -> None:
        self.policy, self.hook, self.env = policy, hook, env

    def __getattr__(self, name: str) -> Any:
        return getattr(self.policy, name)

    def act(self, obs: dict[str, Any]) -> np.ndarray | None:
        hook = self.hook
        if hook.taking_over():
            y = hook.expert_action(self.env, self.env.episode.chain[hook.k])
            if y is not None:  # (None: the expert is done; the hook ends the rollout on this state)
                if hook.steps == hook.at:  # what the learner would have done here, beside what the expert does (the study's record)
                    raw = self.policy.policy if isinstance(self.policy, _Stopping) else self.policy  # (a STOP here is not labelled)
                    mine = raw.act(obs)
                    if mine is not None:
                        hook.switches.append((np.asarray(mine, dtype=np.float32), np.asarray(y, dtype=np.float32)))
                return np.asarray(y, dtype=np.float32)
        return self.policy.act(obs)


class _Stopping:
    """A learner that STOPs, seen by `run_episode`: the state it STOPs in is labelled too (its
    `act` returns None there, so the step hook never sees it); everything else is the learner's."""

    def __init__(self, policy: Any, hook: _Labels, env: Any) -> None:
        self.policy, self.hook, self.env = policy, hook, env

    def __getattr__(self, name: str) -> Any:
        return getattr(self.policy, name)

    def act(self, obs: dict[str, Any]) -> np.ndarray | None:
        from echo_data.agents.runtime import StopEpisode

        a = self.policy.act(obs)
        if a is None:
            with contextlib.suppress(StopEpisode):  # the rollout ends here anyway
                self.hook.record(self.env, obs, None, self.env.episode.chain[self.hook.k])
        return a


def collect(run: Path, dataset: Path, episodes: list[int], max_steps: int | None = None, takeover_seed: int | None = None) -> Rollouts:
    """Roll the policy in `run` on train episodes `episodes` (the experts up to its skill's first
    call in the chain, then the learner, through `run_episode`), label every state it visits;
    `max_steps`: at most that many labelled rows per rollout. Each rollout is one segment.
    `takeover_seed`: the expert takes over each rollout at a step drawn with this seed (module docstring)."""
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
    takeover = None if takeover_seed is None else (takeover_seed, demonstration_length(dataset, policy.skill))
    hook = _Labels(policy, column, max_steps, stop=policy.ends_itself, takeover=takeover)
    acting = _Stopping(policy, hook, env) if policy.ends_itself else policy
    agent = SkillDispatch({policy.skill: _TakeOver(acting, hook, env) if takeover is not None else acting}, OracleSkills())
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
            run_episode(env, obs, info, OraclePlanner(), agent, on_step=hook, skills=k + 1, drive_end="handover")  # as evaluate ends a drive
            if hook.at is None or hook.steps <= hook.at:  # the learner's own success test at its end (a rollout the expert took over is the expert's)
                success.append(bool(env.success_flags[k]))
    finally:
        agent.close()
        env.close()
    return hook.rollouts(len(policy.config.action_names), success)


def demonstration_length(dataset: Path, skill_name: str) -> int:
    """The mean length (rows) of `skill_name`'s segments in the dataset's train split: the range
    a take-over step is drawn from."""
    from echo_data.dataset.reader import StepReader

    idx = StepReader(dataset, "train").index
    mine = idx.skill == skill_name
    segments = len(np.unique(idx.segment[mine]))
    return max(1, round(int(mine.sum()) / segments)) if segments else 1


# How a chunking learner (ACT, Diffusion Policy, `bc --chunk k`) takes a DAgger row: "path", the
# labels of the states the learner went on to visit (the chunk of the rollout, as a dataset
# segment's), "first", the label of the row's own state alone (the rest of the chunk masked), or
# "takeover", the expert taking over each rollout (module docstring): rows from there on, the
# chunk the expert's own executed actions. "path" teaches a sequence the expert never executed
# where the learner strayed; measured on CloseSink (the hand-over study, manipulation_dagger.json).
# A learner of one action per step (BC-RNN, `bc` without a chunk) is the same under "path" and "first".
DAGGER_CHUNKS = ("path", "first", "takeover")


def run_dagger(cfg: Any, out: Path, rounds: int, episodes_per_round: int, max_steps: int | None, progress: bool,
               resume: bool = False, chunk: str = "path") -> dict[str, Any]:
    """BC on the dataset, then `rounds` of collect + retrain on the aggregate; returns the last summary.

    `resume`: the BC run already in `out` (finished or not) is continued instead of trained anew,
    so an existing behaviour-cloning run can be DAgger'd without paying for it twice. Rounds
    themselves always start from the first."""
    from echo_data.learn.fit import train_skill as train_bc

    if not skill(cfg.skill).labels_any_state:
        able = ", ".join(n for n, s in SKILLS.items() if s.labels_any_state)
        raise DaggerError(f"--dagger: only {able}'s expert can act from any state (not {cfg.skill!r}; see docs/learners.md)")
    if cfg.action_form != "absolute":
        raise DaggerError(f"--dagger: --action-form {cfg.action_form} is not labelled (a rollout keeps no states to take the change from); use absolute")
    if chunk not in DAGGER_CHUNKS:
        raise DaggerError(f"--dagger-chunk {chunk}: not one of {', '.join(DAGGER_CHUNKS)}")
    _, n_train = dataset_recipe(Path(cfg.dataset))
    if episodes_per_round > n_train:
        raise DaggerError(f"--dagger-episodes {episodes_per_round}: the train split of {cfg.dataset} has {n_train} episodes")
    summary = train_bc(cfg, out, resume=resume, overwrite=not resume, progress=progress)
    agg: Rollouts | None = None
    log = ["round,episodes,rows_added,rows_aggregated,learner_success,learner_expert_gap,best_val_loss,segments_added,segments_aggregated,stop_rows_added,takeovers"]
    for r in range(1, rounds + 1):
        eps = [((r - 1) * episodes_per_round + j) % n_train for j in range(episodes_per_round)]
        new = collect(out, Path(cfg.dataset), eps, max_steps, takeover_seed=cfg.seed * 1000 + r if chunk == "takeover" else None)
        agg = new if agg is None else _concat(agg, new)
        agg.first_only = chunk == "first"
        summary = train_bc(cfg, out, overwrite=True, progress=progress, extra=agg)
        rate = sum(new.success) / len(new.success) if new.success else math.nan
        log.append(f"{r},{' '.join(map(str, eps))},{len(new)},{len(agg)},{rate:.4f},{new.agreement:.4f},{summary['best_val_loss']},"
                   f"{new.rollouts},{agg.rollouts},{int(new.stops.sum())},{new.takeovers}")
        runs.write_file(out, DAGGER_LOG, ("\n".join(log) + "\n").encode())
    summary["dagger"] = {"rounds": rounds, "chunk": chunk, "rows_aggregated": len(agg) if agg is not None else 0,
                         "segments_aggregated": agg.rollouts if agg is not None else 0, "log": str(out / DAGGER_LOG)}
    return summary


def _concat(a: Rollouts, b: Rollouts) -> Rollouts:
    """Rollouts `a` then `b`, `b`'s segments numbered on after `a`'s."""
    import torch

    if not len(b):
        return a
    if not len(a):
        return b
    return Rollouts({k: torch.cat([a.inputs[k], b.inputs[k]]) for k in a.inputs}, np.concatenate([a.labels, b.labels]),
                    np.concatenate([a.stops, b.stops]), np.concatenate([a.segments, b.segments + a.rollouts]), a.success + b.success,
                    (a.agreement * len(a) + b.agreement * len(b)) / (len(a) + len(b)), takeovers=a.takeovers + b.takeovers,
                    switches=a.switches + b.switches)
