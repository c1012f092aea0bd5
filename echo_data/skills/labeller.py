"""A skill's scripted expert asked, at every control step of someone else's rollout, what it would
command from the state that rollout reached (DAgger's labels, `echo_data.learn.dagger`).

Why this works for the manipulation skills: their experts are closed-loop (`skills/servo.py`,
docs/manipulation_experts.md): each command is computed from the state its step starts in, so an
expert generator advanced once per step of a learner's rollout (instead of its own) answers from
the learner's state: a hand off its goal is servoed back, a pushed object followed, a half-turned
lever pushed on from where it is. What the state cannot tell a running expert is a change of its
phase that it did not command; two rules cover those:

- the expert ended (it reached its end, or gave up: a missed grasp, a lost handle, a timeout):
  a fresh expert is started on the state as it is, and it infers where it is (Pick with the
  object in the hand lifts and carries; with the jaws closed on nothing its untuck and hover
  re-aim and open them, then it regrasps; OpenDoor with the leaf in the hand goes on swinging;
  CloseSink reads the lever's angle). A fresh expert with nothing to do: no label (None);
- the grasp (an object between the fingers, a door leaf held) changed against the last label's
  gripper command (the learner closed where the expert said open, or lost what it held): the
  expert's phase no longer holds, so a fresh one starts too.

Asking has no side effect on the world: an expert only reads the world until its action is
applied, and the labeller never applies one. Ask once per control step: each answer advances
the expert by one step.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.records import ACTION_DIM

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World


class ExpertLabeller:
    """`labeller()` -> the `action.ee` (11 floats) the expert of `call.skill` commands from the
    world's state now, or None when it has nothing to do from here; `joint(ee)` its joint form."""

    def __init__(self, world: World, call: SkillCall, spec: EpisodeSpec, expert: Callable[..., Any] | None = None) -> None:
        from echo_data.skill_table import SKILLS

        self.world, self.call, self.spec = world, call, spec
        self.expert = expert or SKILLS[call.skill].expert_fn()
        self.gen: Generator[Any, None, Any] | None = None
        self.grasp = self._grasp()  # the grasp when the last label was given ...
        self.closing = False  # ... and whether that label closed the gripper
        self.restarts = 0  # fresh experts started after the first (how often the learner left the expert's phase)

    def _grasp(self) -> tuple[str | None, bool]:
        return self.world.robot.holding, self.world.holding_door

    def _next(self) -> np.ndarray | None:
        if self.gen is None:
            self.gen = self.expert(self.world, self.call, self.spec)
        try:
            a = np.asarray(next(self.gen), dtype=np.float32)
        except StopIteration:
            self.gen = None
            return None
        return a if a.shape != (ACTION_DIM,) else self.world.robot.ee.to_ee(a)  # a joint-born expert's ee twin

    def _restart(self) -> None:
        self.close()
        self.restarts += 1

    def __call__(self) -> np.ndarray | None:
        grasp = self._grasp()
        if self.gen is not None and grasp != self.grasp and (grasp != (None, False)) != self.closing:
            self._restart()  # the grasp changed against the label: the running expert's phase is gone
        a = self._next()
        if a is None:  # the expert ended: a fresh one from this state
            self._restart()
            a = self._next()
        self.grasp = grasp
        if a is not None:
            self.closing = bool(a[10] > 0.5)
        return a

    def joint(self, ee: np.ndarray) -> np.ndarray:
        """The joint action (`action`) of an ee label, through the robot's one ee map from the
        commanded state now: what the build records beside it."""
        return self.world.robot.ee.to_joint(ee)

    def close(self) -> None:
        if self.gen is not None:
            self.gen.close()
            self.gen = None
