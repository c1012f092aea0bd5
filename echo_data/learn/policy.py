"""Trained run folders as the objects `echo-data evaluate` drives (see docs/learners.md).

`SkillPolicy.from_run(folder)` (or `SkillPolicy(checkpoint=folder)`, how an `agent.json` checkpoint
folder is constructed) for a skill run of any algorithm: `reset(info)`, then `act(obs) -> float32
(A,)` per control step (A: the cloned action column's size),
with `obs` holding the dataset's observation keys (and `GOAL_POSE` for a run trained with the
target position). It is a learned policy: it reads observations only, never the world. Observations go through the same
`features.prepare` as the training rows did. `PlannerModel.from_run(folder).plan(first_obs)`
returns the skill chain in the planner export's JSON shape.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.schema import STATE
from echo_data.learn import runs
from echo_data.learn.features import FeatureError, FeatureSpec, from_action_form, kind_index, prepare, single
from echo_data.records import GOAL_POSE


def learner_observations(spec: FeatureSpec) -> tuple[str, ...]:
    """The observation keys a skill learner with these features reads (what an evaluation must
    render for it), the goal observation included when it reads the target."""
    return tuple(spec.columns) + ((GOAL_POSE,) if "target" in spec.inputs else ())


def _load(folder: Path, config_cls: Any, build: Any) -> tuple[Any, Any, FeatureSpec, Path]:
    """(config, model in eval mode with the best weights, feature spec, the weights' file) of a run folder."""
    cfg = config_cls.from_dict(runs.read_json(folder / runs.CONFIG))
    model = build(cfg)
    state, path = runs.load_weights(folder)
    model.load_state_dict(state)
    return cfg, model.eval(), FeatureSpec.from_dict(cfg.features), path


def goal_from_obs(obs: Mapping[str, Any]) -> np.ndarray:
    """The active skill's goal pose (x, y, yaw, world) from the observation `GOAL_POSE`, which the
    runtime adds for a policy that lists it in `observations` (learned policies never read the
    world or the episode spec: echo_data.protocols). In training the same input is the segment's
    final base pose, where the expert went."""
    if GOAL_POSE not in obs:
        raise FeatureError(f"this policy reads the target position: the observation has no {GOAL_POSE!r} "
                           "(run it through echo_data.agents.runtime.run_episode, which adds it)")
    return np.asarray(obs[GOAL_POSE], dtype=np.float32).reshape(-1)[:3]


class SkillPolicy:
    """A trained skill run of any algorithm (config.json's "algo"), loaded from its run folder.

    Acting follows the algorithm's config: a recurrent model carries its hidden state from step
    to step (zero after `reset`, as at a segment's start in training); a chunking model predicts
    `window` actions and either executes the first `execute_steps` of them before predicting
    again (a queue) or, with ACT's temporal ensembling, predicts at every step and executes the
    weighted mean of every prediction made for this step (w_i = exp(-m i), i = 0 the oldest).
    Binary action entries are thresholded at 0.5 after averaging, or, with `switch_ahead` h > 1,
    follow `switched`: the entry changes as soon as the newest chunk changes it within h steps."""

    def __init__(self, checkpoint: Path | str) -> None:
        from echo_data.learn.algos import build_model, config_from_run

        self.checkpoint = Path(checkpoint)
        self.config = cfg = config_from_run(runs.read_json(self.checkpoint / runs.CONFIG))
        model = build_model(cfg)
        state, path = runs.load_weights(self.checkpoint)
        model.load_state_dict(state)
        self.model = model.eval()
        self.weights_sha256 = runs.file_sha256(path)  # what an evaluation's results name (evaluation.provenance)
        self.spec = FeatureSpec.from_dict(cfg.features)
        self.algo = cfg.ALGO
        self.mean = np.asarray(cfg.action_mean, dtype=np.float32)
        self.std = np.asarray(cfg.action_std, dtype=np.float32)
        self.binary = list(cfg.binary)
        self.execute = cfg.execute_steps()
        self.switch_ahead = cfg.switch_ahead  # 1 for runs written before the option (SkillConfig.from_dict)
        self.ensemble = cfg.ensemble_weight()
        self.skill = cfg.skill
        self.recurrent = cfg.SEQUENCE
        self.action_form = cfg.action_form
        self.action_dim = len(cfg.action_names)
        # a run trained with --stop ends its skill itself: `act` returns None (STOP) when the
        # predicted skill_stop passes the run's `stop_threshold`, and the runtime judges the skill where it stopped
        self.ends_itself = bool(cfg.stop)
        # a Place run trained --from-stance starts where a drive handed it over: the runtime carries for it
        # with the drive policy first (`agents.runtime.carry_call`; the run's config is the one fact)
        self.starts_in_stance = bool(cfg.from_stance)
        # entries the demonstrations never varied, acted exactly (`algos.base.held_entries`)
        self.held_at = np.array([int(i) for i, _ in cfg.held_entries], dtype=np.int64)
        self.held_to = np.array([v for _, v in cfg.held_entries], dtype=np.float32)
        # what evaluate must render for it, and the goal observation when the model reads the target
        self.observations = learner_observations(self.spec)
        self._queue: deque[np.ndarray] = deque()
        self._past: deque[np.ndarray] = deque()  # temporal ensembling: earlier chunks, each shifted to start at the next step
        self._rest: np.ndarray | None = None  # the newest chunk from this step on (the binary look-ahead)
        self._last_binary: np.ndarray | None = None  # the binary entries this policy last commanded
        self._kind = -1
        self._gen: Any = None
        self._history: deque[dict[str, Any]] = deque(maxlen=cfg.history())  # the last observations' inputs (history > 1)
        self.hidden: Any = None  # the GRU's state (recurrent runs); None = zero, as at a segment's start in training

    @classmethod
    def from_run(cls, folder: Path | str) -> SkillPolicy:
        return cls(checkpoint=folder)

    def reset(self, info: Mapping[str, Any] | None = None) -> None:
        """Start a new skill segment: forget queued and ensembled actions and the recurrent state
        (training started every segment from zero), reseed sampling, read the target kind if the
        model needs it (the goal position comes with each observation, `GOAL_POSE`)."""
        import torch

        info = info or {}
        self._queue.clear()
        self._past.clear()
        self._history.clear()
        self._rest = None
        self._last_binary = None
        self.hidden = None
        self._gen = torch.Generator().manual_seed(self.config.seed % 2**63)
        self._kind = kind_index(self.spec, info.get("target_kind")) if "kind" in self.spec.inputs else -1

    def inputs(self, obs: Mapping[str, Any]) -> dict[str, Any]:
        """One observation -> the model's prepared inputs (batch of one), as training rows are."""
        import torch

        goal = torch.from_numpy(goal_from_obs(obs)[None]) if "target" in self.spec.inputs else None
        return prepare(single(obs, self.spec), self.spec, goal=goal, kind=np.array([self._kind]))

    def _stacked(self) -> dict[str, Any]:
        """The remembered steps as (1, history, ...) inputs: the segment's first observation repeated
        until there are enough, as training clamps a window at the segment's start."""
        import torch

        steps = list(self._history)
        steps = [steps[0]] * (int(self._history.maxlen or 1) - len(steps)) + steps
        return {k: torch.stack([s[k] for s in steps], dim=1) for k in steps[0]}

    def _predict(self, obs: Mapping[str, Any]) -> np.ndarray:
        """The model's chunk for this observation, (window, A) in the cloned action's units."""
        import torch

        x = self.inputs(obs) if not self._history else self._stacked()
        with torch.no_grad():
            pred, self.hidden = self.model.predict(x, self.hidden, self._gen)
        return pred[0].cpu().numpy() * self.std + self.mean

    def act(self, obs: Mapping[str, Any]) -> np.ndarray | None:
        """One observation (dataset keys) -> the next action, float32 (A,); None: STOP (`ends_itself`)."""
        if self._gen is None:  # acting without a reset: a segment's start
            self.reset({})
        if self._history.maxlen and self._history.maxlen > 1:  # every step is remembered, predicted on or not
            self._history.append(self.inputs(obs))
        if self.ensemble is not None:
            chunk = self._predict(obs)
            self._past.append(chunk)
            while len(self._past[0]) == 0:
                self._past.popleft()
            now = np.stack([c[0] for c in self._past])  # oldest first
            w = np.exp(-self.ensemble * np.arange(len(now)))
            pred = (w[:, None] * now).sum(axis=0) / w.sum()
            self._past = deque(c[1:] for c in self._past)
            self._rest = chunk
            return self._finish(pred, obs)
        if not self._queue:
            chunk = self._predict(obs)
            self._rest = chunk
            for a in chunk[: self.execute]:
                self._queue.append(a)
        return self._finish(self._queue.popleft(), obs)

    def _finish(self, pred: np.ndarray, obs: Mapping[str, Any]) -> np.ndarray | None:
        """Binary entries (see `switched`); turn the run's action form back into the env's action;
        None when the run learned the STOP and predicts it."""
        out = np.array(pred, dtype=np.float32)
        stop = bool(out[self.action_dim] > self.config.stop_threshold) if self.ends_itself else False  # before the 0.5 of the other binaries
        if self.binary:
            if self.switch_ahead > 1 and self._rest is not None:
                out[self.binary] = switched(self._rest[: self.switch_ahead][:, self.binary], self._last_binary)
            else:
                out[self.binary] = (out[self.binary] > 0.5).astype(np.float32)
            self._last_binary = out[self.binary].copy()
        if self._rest is not None:
            self._rest = self._rest[1:]  # the next step's look-ahead (a queue's chunk moves on with the queue)
        out[self.held_at] = self.held_to
        if stop:
            return None
        state = np.asarray(obs[STATE], dtype=np.float32) if self.action_form != "absolute" else None
        action = from_action_form(out[: self.action_dim], state, self.action_form).astype(np.float32)
        assert action.shape == (self.action_dim,)
        return action


def switched(ahead: np.ndarray, last: np.ndarray | None) -> np.ndarray:
    """Binary commands (0/1, float32) from the probabilities a chunk predicts for the next steps,
    `ahead` (h, n): each entry switches from `last` (what was commanded; None at a segment's
    start: the current step's prediction) as soon as any of the h steps predicts the other value.

    Why: an expert that closes its jaws after waiting a few steps at the grasp pose (settling,
    a fixed hold) labels that same state "open" several times and "close" once, so the current
    step's probability stays near 1/(wait + 1) and a policy thresholding it never closes
    (measured: `close` is 15 % of the Pick labels within 1 cm of the grasp pose, and a state-only
    chunked learner picked up the object in 0/10 validation episodes, 6/10 with h = 6; docs/learners.md). A
    chunk knows the switch is coming within its horizon; acting on that is the chunk's use."""
    votes = np.asarray(ahead, dtype=np.float32) > 0.5
    if last is None:
        return votes[0].astype(np.float32)
    prev = np.asarray(last, dtype=np.float32) > 0.5
    change = (votes != prev[None, :]).any(axis=0)
    return np.where(change, ~prev, prev).astype(np.float32)


BCPolicy = SkillPolicy  # run folders written before the registry name this class in agent.json


class PlannerModel:
    """A planner run: `plan(first_obs)` -> [{"skill": ..., "target": ...}, ...] (export shape)."""

    def __init__(self, checkpoint: Path | str) -> None:
        from echo_data.learn.planner import PlannerConfig, build_model

        self.checkpoint = Path(checkpoint)
        cfg, self.model, self.spec, path = _load(self.checkpoint, PlannerConfig, build_model)
        self.weights_sha256 = runs.file_sha256(path)  # what an evaluation's results name (evaluation.provenance)
        self.categories = cfg.categories
        self.templates = cfg.templates
        self.sets = cfg.event_sets if cfg.decode == "sets" else None  # the decoder chosen on validation
        self.priority = cfg.priority if cfg.order == "priority" else None
        self.observations = tuple(self.spec.columns)

    @classmethod
    def from_run(cls, folder: Path | str) -> PlannerModel:
        return cls(checkpoint=folder)

    def events(self, first_obs: Mapping[str, Any]) -> list[str]:
        """Sounding event categories, most urgent first."""
        import torch

        from echo_data.learn.planner import decode

        with torch.no_grad():
            logits, scores = self.model(prepare(single(first_obs, self.spec), self.spec))
        return decode(logits[0].numpy(), scores[0].numpy(), self.categories, self.sets, self.priority)

    def plan(self, first_obs: Mapping[str, Any]) -> list[dict[str, str]]:
        from echo_data.learn.planner_data import chain_of

        return chain_of(self.events(first_obs), self.templates)
