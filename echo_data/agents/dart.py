"""DART noise injection: the scripted experts demonstrate while perturbed, and correct themselves.

Behaviour cloning compounds its errors on states the expert never visited; DART (Laskey et al.,
"DART: Noise Injection for Robust Imitation Learning", CoRL 2017) perturbs the *executed*
action of the supervisor with noise of about the learner's error, so the demonstrations pass
through those states, while the label stays the supervisor's own action there.

Here, at every control step: label = the expert's action from the state it is in (the
`action` column); executed = label + noise (`action.executed`, what the robot does and what a
replay applies). The robot is told the label (`Robot.intend`), so an expert that continues
"from where the arm is commanded" continues from its own command and the noise does not
accumulate into a random walk; position targets are absolute, so the next label pulls a
perturbed joint back, and the base experts steer from the measured pose.

The noise is zero-mean Gaussian, `level * NOISE_STD` per action dimension, drawn from the
episode's own stream (`seeds.ACTION_NOISE` salted onto the episode seed), so an episode's noise repeats with its seed.
A dimension is left unperturbed where a perturbation could not be corrected by the expert:
- base velocities only while the expert drives the base (a nonzero base command): a standing
  manipulation expert plans its arm in the base frame it measured once, so drift while it
  stands would be an error it never sees;
- the gripper only while the expert holds it open: closed, its command is grip force on an
  object or a door handle (a perturbation there is a drop, which the experts cannot retry);
  at full opening the finger limit clips positive draws, so the fingers only close a little;
- nothing at all for `QUIET_STEPS` control steps from a change of the gripper command: the
  fingers are closing on (or letting go of) an object, a handle or a lever, and a jolt of the
  arm then is a missed grasp rather than a state worth demonstrating from.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from echo_data.agents.builtin import OracleSkills
from echo_data.records import ACTION_DIM, ARM_JOINTS
from echo_data.robot.robot import GRIPPER_OPEN, Robot
from echo_data.seeds import ACTION_NOISE, derived_rng

# Standard deviation of the executed-action noise at level 1.0, per element of the action
# (echo_data.records.ACTION_NAMES). About a tenth of what each command changes in one 0.1 s
# control step at the experts' speeds, i.e. the size of a learner's per-step error:
BASE_LINEAR_STD = 0.05  # m/s on vx, vy (navigate cruises at 0.6 m/s: 5 mm per step)
BASE_ANGULAR_STD = 0.1  # rad/s on wz (turns run at up to 1 rad/s)
TORSO_STD = 0.005  # m on the torso target (it moves at <= 0.15 m/s)
ARM_STD = 0.01  # rad on each arm joint target (joints move <= 0.13 rad per step; ~5 mm at the hand per joint)
GRIPPER_STD = 0.005  # m on the opening target (0 .. 0.1 m)
NOISE_STD = np.array(
    [BASE_LINEAR_STD, BASE_LINEAR_STD, BASE_ANGULAR_STD, TORSO_STD] + [ARM_STD] * ARM_JOINTS + [GRIPPER_STD], dtype=np.float64
)
assert NOISE_STD.shape == (ACTION_DIM,)
QUIET_STEPS = 10  # control steps without noise from each change of the gripper command (1 s at 10 Hz)


def noise_mask(label: np.ndarray, quiet: bool) -> np.ndarray:
    """Which action elements may be perturbed at a step whose expert action is `label` (see the module doc)."""
    mask = np.ones(ACTION_DIM, dtype=bool)
    if quiet:
        return ~mask
    mask[:3] = bool(np.any(label[:3] != 0.0))
    mask[11] = bool(label[11] >= GRIPPER_OPEN)
    return mask


class NoisyExperts:
    """The scripted experts (`OracleSkills`) with DART noise on what they execute.

    `act` returns the executed action; `label` holds the expert's own action for that step
    and `noise` the difference (executed = label + noise in float32).
    """

    name = "oracle+dart"
    ends_itself = True
    privileged = True
    observations = OracleSkills.observations

    def __init__(self, level: float, seed: int, experts: Any = None) -> None:
        self.inner = OracleSkills(experts)
        self.std = float(level) * NOISE_STD
        self.rng = derived_rng(ACTION_NOISE, seed)
        self.label: np.ndarray | None = None
        self.noise = np.zeros(ACTION_DIM, dtype=np.float32)
        self._executed: np.ndarray | None = None
        self._robot: Robot | None = None
        self._grip: float | None = None
        self._quiet = 0

    @property
    def outcome(self) -> Any:
        return self.inner.outcome

    def reset(self, info: dict[str, Any]) -> None:
        self._robot = info["world"].robot
        self.inner.reset(info)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray | None:
        robot = self._robot
        assert robot is not None, "reset() first"
        last, executed = self.label, self._executed
        if last is not None and executed is not None and np.array_equal(robot.applied_action(), Robot.clip_action(executed).astype(np.float32)):
            robot.intend(last)  # the expert goes on from its own last command, not from the noise
        label = self.inner.act(obs)
        if label is None:
            return None
        grip = float(label[11])
        if self._grip is not None and grip != self._grip:
            self._quiet = QUIET_STEPS
        self._grip = grip
        draw = self.rng.standard_normal(ACTION_DIM) * self.std  # drawn every step: the stream never depends on the gate
        noise = np.where(noise_mask(label, self._quiet > 0), draw, 0.0).astype(np.float32)
        self._quiet = max(self._quiet - 1, 0)
        self.label = np.asarray(label, dtype=np.float32)
        self.noise = noise
        self._executed = self.label + noise
        return self._executed.copy()

    def close(self) -> None:
        self.inner.close()
