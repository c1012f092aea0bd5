"""Built-in agents: the scripted experts as the upper bound, a random and a still baseline, the true plan.

`OracleSkills` runs the scripted expert of each skill (`echo_data.skills.EXPERTS`) on the live
world, so it is privileged (`privileged = True`): it reads the world handle the runtime puts in
its reset info for privileged policies only (echo_data.protocols). It
ends each skill itself (the expert returns), which is also how the build records its
demonstrations. `RandomSkills` samples the action space from a generator seeded by the episode
and skill, so evaluations repeat; `StillSkills` holds every joint where it is.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from echo_data.dataset.schema import STATE
from echo_data.records import ACTION_DIM, EE_ACTION_DIM


class OracleSkills:
    """Scripted experts driven by the true chain (the upper bound of the benchmark)."""

    name = "oracle"
    ends_itself = True  # the expert says when the skill is over (act returns None)
    privileged = True  # reset info carries the world, the call and the spec (echo_data.protocols)
    observations = (STATE,)  # experts read the world, not the observation

    def __init__(self, experts: Any = None) -> None:
        if experts is None:
            from echo_data.skills import EXPERTS

            experts = EXPERTS
        self.experts = experts
        self._gen: Any = None
        self.outcome: Any = None
        self.last_ee: np.ndarray | None = None  # the expert's own end-effector command of the last act()
        self._robot: Any = None
        self.action_mode = "joint"

    def reset(self, info: dict[str, Any]) -> None:
        self.close()
        self.outcome = None
        self.last_ee = None
        self.action_mode = info.get("action_mode", "joint")
        self._robot = info["world"].robot
        self._gen = self.experts[info["skill"]](info["world"], info["call"], info["spec_object"])

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray | None:
        """The expert's next command as a joint action. Experts compute theirs in end-effector form
        (`action.ee`, docs/action_spaces.md): it is kept in `last_ee` and turned into joint targets by
        the robot's one ee map, so the recorded ee form replays exactly. (An expert yielding joint
        actions, e.g. one a caller passes in `experts`, passes through; no built-in one does.) In an environment in ee
        mode (`info["action_mode"]`) the ee form is returned: the expert's own, or the joint
        action's `to_ee` twin."""
        try:
            a = np.asarray(next(self._gen), dtype=np.float32)
        except StopIteration as stop:
            self.outcome = stop.value
            self._gen = None
            return None
        if a.shape == (EE_ACTION_DIM,):
            self.last_ee = a
            return a if self.action_mode == "ee_delta" else self._robot.ee.to_joint(a)
        self.last_ee = None
        return self._robot.ee.to_ee(a) if self.action_mode == "ee_delta" else a

    def close(self) -> None:
        """Stop a running expert (it releases what it holds: planners, door attachments)."""
        if self._gen is not None:
            self._gen.close()
            self._gen = None


class RandomSkills:
    """Uniform samples of the action space, seeded per (episode seed, skill index)."""

    name = "random"
    ends_itself = False
    observations = (STATE,)

    def __init__(self) -> None:
        from echo_data.envs.env import action_space

        self.space = action_space()
        self.rng = np.random.default_rng(0)

    def reset(self, info: dict[str, Any]) -> None:
        from echo_data.envs.env import action_space

        self.space = action_space(info.get("action_mode", "joint"))
        self.rng = np.random.default_rng([int(info["episode_seed"]) & 0xFFFFFFFF, int(info["skill_index"])])

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        lo, hi = self.space.low.astype(np.float64), self.space.high.astype(np.float64)
        return (lo + (hi - lo) * self.rng.random(lo.shape[0])).astype(np.float32)


class StillSkills:
    """Does nothing: zero base velocity, every joint held at its current position."""

    name = "still"
    ends_itself = False
    observations = (STATE,)

    def __init__(self) -> None:
        self.action_mode = "joint"

    def reset(self, info: dict[str, Any]) -> None:
        self.action_mode = info.get("action_mode", "joint")

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        s = np.asarray(obs[STATE], dtype=np.float32)
        if self.action_mode == "ee_delta":  # no TCP change; torso and gripper where they are
            from echo_data.robot.robot import GRIPPER_OPEN

            e = np.zeros(EE_ACTION_DIM, dtype=np.float32)
            e[3] = s[3]
            e[10] = 1.0 if s[11] < GRIPPER_OPEN / 2.0 else 0.0
            return e
        a = np.zeros(ACTION_DIM, dtype=np.float32)
        a[3:12] = s[3:12]  # torso, 7 arm joints, gripper opening: hold where they are
        return a


class OraclePlanner:
    """Returns the episode's true skill chain (the paper's starred rows score low-level skills alone)."""

    name = "oracle"
    privileged = True  # reset info carries the true chain (echo_data.protocols)
    observations: tuple[str, ...] = ()  # reads the true chain, no observation

    def __init__(self) -> None:
        self._chain: list[dict[str, str]] = []

    def reset(self, info: dict[str, Any]) -> None:
        self._chain = list(info["true_chain"])

    def plan(self, first_obs: dict[str, np.ndarray]) -> list[dict[str, str]]:
        return [dict(c) for c in self._chain]


BUILTIN_POLICIES = {"oracle": OracleSkills, "random": RandomSkills, "still": StillSkills}
BUILTIN_PLANNERS = {"oracle": OraclePlanner}
