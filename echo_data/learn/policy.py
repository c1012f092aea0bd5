"""Trained run folders as the objects `echo-data evaluate` drives (see docs/learners.md).

`BCPolicy.from_run(folder)` (or `BCPolicy(checkpoint=folder)`, how an `agent.json` checkpoint
folder is constructed): `reset(info)`, then `act(obs) -> float32 (12,)` per control step,
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
from echo_data.records import ACTION_DIM, GOAL_POSE


def _load(folder: Path, config_cls: Any, build: Any) -> tuple[Any, Any, FeatureSpec]:
    """(config, model in eval mode with the best weights, feature spec) of a run folder."""
    cfg = config_cls.from_dict(runs.read_json(folder / runs.CONFIG))
    model = build(cfg)
    path = folder / runs.BEST if (folder / runs.BEST).is_file() else folder / runs.CHECKPOINT
    model.load_state_dict(runs.load_torch(path)["model"])
    return cfg, model.eval(), FeatureSpec.from_dict(cfg.features)


def goal_from_obs(obs: Mapping[str, Any]) -> np.ndarray:
    """The active skill's goal pose (x, y, yaw, world) from the observation `GOAL_POSE`, which the
    runtime adds for a policy that lists it in `observations` (learned policies never read the
    world or the episode spec: echo_data.protocols). In training the same input is the segment's
    final base pose, where the expert went."""
    if GOAL_POSE not in obs:
        raise FeatureError(f"this policy reads the target position: the observation has no {GOAL_POSE!r} "
                           "(run it through echo_data.agents.runtime.run_episode, which adds it)")
    return np.asarray(obs[GOAL_POSE], dtype=np.float32).reshape(-1)[:3]


class BCPolicy:
    """A behaviour-cloned skill policy loaded from its run folder."""

    def __init__(self, checkpoint: Path | str) -> None:
        from echo_data.learn.bc import BCConfig, build_model

        self.checkpoint = Path(checkpoint)
        cfg, self.model, self.spec = _load(self.checkpoint, BCConfig, build_model)
        self.mean = np.asarray(cfg.action_mean, dtype=np.float32)
        self.std = np.asarray(cfg.action_std, dtype=np.float32)
        self.execute = cfg.execute
        self.skill = cfg.skill
        self.recurrent = cfg.recurrent
        self.action_form = cfg.action_form
        # what evaluate must render for it, and the goal observation when the model reads the target
        self.observations = tuple(self.spec.columns) + ((GOAL_POSE,) if "target" in self.spec.inputs else ())
        self._queue: deque[np.ndarray] = deque()
        self._kind = -1
        self.hidden: Any = None  # the GRU's state (recurrent runs); None = zero, as at a segment's start in training

    @classmethod
    def from_run(cls, folder: Path | str) -> BCPolicy:
        return cls(checkpoint=folder)

    def reset(self, info: Mapping[str, Any] | None = None) -> None:
        """Start a new skill segment: forget queued actions and the recurrent state (training
        started every segment from zero), read the target kind if the model needs it (the goal
        position comes with each observation, `GOAL_POSE`)."""
        info = info or {}
        self._queue.clear()
        self.hidden = None
        self._kind = kind_index(self.spec, info.get("target_kind")) if "kind" in self.spec.inputs else -1

    def inputs(self, obs: Mapping[str, Any]) -> dict[str, Any]:
        """One observation -> the model's prepared inputs (batch of one), as training rows are."""
        import torch

        goal = torch.from_numpy(goal_from_obs(obs)[None]) if "target" in self.spec.inputs else None
        return prepare(single(obs, self.spec), self.spec, goal=goal, kind=np.array([self._kind]))

    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        """One observation (dataset keys) -> the next action, float32 (ACTION_DIM,)."""
        import torch

        if not self._queue:
            with torch.no_grad():
                if self.recurrent:
                    y, self.hidden = self.model({k: v[:, None] for k, v in self.inputs(obs).items()}, self.hidden)
                    pred = y[0, 0].numpy()
                else:
                    pred = self.model(self.inputs(obs))[0].numpy()
            state = np.asarray(obs[STATE], dtype=np.float32) if self.action_form != "absolute" else None
            for a in pred[: self.execute]:
                self._queue.append(from_action_form((a * self.std + self.mean).astype(np.float32), state, self.action_form))
        action = self._queue.popleft()
        assert action.shape == (ACTION_DIM,)
        return action


class PlannerModel:
    """A planner run: `plan(first_obs)` -> [{"skill": ..., "target": ...}, ...] (export shape)."""

    def __init__(self, checkpoint: Path | str) -> None:
        from echo_data.learn.planner import PlannerConfig, build_model

        self.checkpoint = Path(checkpoint)
        cfg, self.model, self.spec = _load(self.checkpoint, PlannerConfig, build_model)
        self.categories = cfg.categories
        self.templates = cfg.templates
        self.sets = cfg.event_sets if cfg.decode == "sets" else None  # the decoder chosen on validation
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
        return decode(logits[0].numpy(), scores[0].numpy(), self.categories, self.sets)

    def plan(self, first_obs: Mapping[str, Any]) -> list[dict[str, str]]:
        from echo_data.learn.planner import chain_of

        return chain_of(self.events(first_obs), self.templates)
