"""The scripted experts as the build runs them: every step in both action forms, perturbed so
that the demonstrations show recovery.

Behaviour cloning compounds its errors on states the expert never visited; DART (Laskey et al.,
"DART: Noise Injection for Robust Imitation Learning", CoRL 2017) perturbs the *executed*
action of the supervisor with noise of about the learner's error, so the demonstrations pass
through those states, while the label stays the supervisor's own command there.

`Demonstrator` wraps `OracleSkills` and, at every control step, knows four vectors (the four
action columns of a step row, docs/action_spaces.md): the label and the executed action, each
in joint form (`action`, `action.executed`) and in end-effector form (`action.ee`,
`action.ee.executed`). Which form is exact depends on how the expert computed its command:

- **ee-born** (an expert yielding `action.ee`, the closed-loop experts on `skills/servo`): the
  ee form is the expert's own; the perturbation (`experts.perturbation`) is added to it in ee
  space; both joint forms are `robot.ee.to_joint` of their ee twins from the commanded state the
  robot is in, which is exactly what `EchoDataEnv(action_mode="ee_delta")` computes when it is
  handed the ee form, so a replay from either `action.executed` (joint mode) or
  `action.ee.executed` (ee mode) applies the same float32 joint targets: bit-identical. The
  expert reads the commanded state (servo) and so labels from the perturbed state: it corrects.
- **joint-born** (an expert yielding 12-float joint actions: no built-in expert does any more;
  the path stays for experts a caller hands `OracleSkills(experts=...)`, and the recipe key
  `experts.action_noise` and the shipped recipes that set it still name it): the joint
  form is exact; the legacy joint-space DART noise (`experts.action_noise`) perturbs it; the ee
  forms are `robot.ee.to_ee` twins (approximate: a replay of those in ee mode is close, not
  bit-identical; docs/action_spaces.md).

Perturbation in ee space (`EePerturbation`): zero-mean Gaussian per control step, σ from the
recipe in cm and degrees, on the TCP change (dx..dz, drx..drz) while the expert moves the hand
(a nonzero TCP change) and on the base velocities while it drives (a nonzero base command: the
same distance and angle per control period, i.e. σ·control_hz per second). Never on the torso or
the binary gripper, and nothing at all for `QUIET_STEPS` control steps from a change of the
gripper command (the jaws are closing on, or letting go of, an object, a handle or a lever; a
jolt then is a missed grasp rather than a state worth demonstrating from).

Joint-space DART (`JointNoise`, legacy): `level * NOISE_STD` per joint-action dimension; the
robot is told the label (`Robot.intend`) so a joint expert continuing "from where the arm is
commanded" continues from its own command. A dimension is left unperturbed where the former
joint-space experts could not correct it: base velocities only while driving; the gripper only while held
open; nothing for `QUIET_STEPS` from a gripper change.

Each noise is drawn every step from its own stream salted onto the episode seed
(`seeds.ACTION_NOISE`, `seeds.EE_PERTURBATION`), so an episode's noise repeats with its seed and
the stream never depends on the gate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.agents.builtin import OracleSkills
from echo_data.records import ACTION_DIM, ARM_JOINTS, EE_ACTION_DIM
from echo_data.robot.robot import GRIPPER_OPEN, Robot
from echo_data.seeds import ACTION_NOISE, EE_PERTURBATION, derived_rng

if TYPE_CHECKING:
    from echo_data.recipe import ExpertsConfig, Perturbation

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
    """Which joint-action elements may be perturbed at a step whose expert action is `label` (see the module doc)."""
    mask = np.ones(ACTION_DIM, dtype=bool)
    if quiet:
        return ~mask
    mask[:3] = bool(np.any(label[:3] != 0.0))
    mask[11] = bool(label[11] >= GRIPPER_OPEN)
    return mask


def ee_noise_mask(label_ee: np.ndarray, quiet: bool) -> np.ndarray:
    """Which `action.ee` elements may be perturbed at a step whose expert command is `label_ee`:
    base velocities while driving, the TCP change while the hand moves, never torso or gripper."""
    mask = np.zeros(EE_ACTION_DIM, dtype=bool)
    if quiet:
        return mask
    mask[:3] = bool(np.any(label_ee[:3] != 0.0))
    mask[4:10] = bool(np.any(label_ee[4:10] != 0.0))
    return mask


def ee_noise_std(perturbation: Perturbation, control_hz: int) -> np.ndarray:
    """Per-element σ of the ee perturbation (`action.ee` units) from the recipe's cm and degrees per step."""
    pos = perturbation.position_cm / 100.0
    rot = math.radians(perturbation.rotation_deg)
    std = np.zeros(EE_ACTION_DIM, dtype=np.float64)
    std[:2] = pos * control_hz  # m/s: the same travel per control period as the hand's
    std[2] = rot * control_hz  # rad/s
    std[4:7] = pos
    std[7:10] = rot
    return std


class _GripperQuiet:
    """Counts down QUIET_STEPS from each change of the gripper command."""

    def __init__(self) -> None:
        self.grip: float | None = None
        self.left = 0

    def update(self, grip: float) -> bool:
        """Record this step's gripper command; True while the step is quiet."""
        if self.grip is not None and grip != self.grip:
            self.left = QUIET_STEPS
        self.grip = grip
        quiet = self.left > 0
        self.left = max(self.left - 1, 0)
        return quiet


class JointNoise:
    """Legacy joint-space DART noise for joint-born commands (`experts.action_noise`)."""

    def __init__(self, level: float, seed: int) -> None:
        self.std = float(level) * NOISE_STD
        self.rng = derived_rng(ACTION_NOISE, seed)
        self.quiet = _GripperQuiet()

    def __call__(self, label: np.ndarray) -> np.ndarray:
        quiet = self.quiet.update(float(label[11]))
        draw = self.rng.standard_normal(ACTION_DIM) * self.std  # drawn every step: the stream never depends on the gate
        return np.where(noise_mask(label, quiet), draw, 0.0).astype(np.float32)


class EePerturbation:
    """End-effector perturbation for ee-born commands (`experts.perturbation`)."""

    def __init__(self, perturbation: Perturbation, control_hz: int, seed: int) -> None:
        self.std = ee_noise_std(perturbation, control_hz)
        self.rng = derived_rng(EE_PERTURBATION, seed)
        self.quiet = _GripperQuiet()

    def __call__(self, label_ee: np.ndarray) -> np.ndarray:
        quiet = self.quiet.update(float(label_ee[10]))
        draw = self.rng.standard_normal(EE_ACTION_DIM) * self.std
        return np.where(ee_noise_mask(label_ee, quiet), draw, 0.0).astype(np.float32)


@dataclass
class DemoStep:
    """One control step of a demonstration in both forms (float32). `ee_born`: the ee form is
    the expert's own and exact; else the joint form is, and the ee form its `to_ee` twin."""

    label: np.ndarray  # (ACTION_DIM,) `action`
    executed: np.ndarray  # (ACTION_DIM,) `action.executed`: what the robot is sent
    label_ee: np.ndarray  # (EE_ACTION_DIM,) `action.ee`
    executed_ee: np.ndarray  # (EE_ACTION_DIM,) `action.ee.executed`
    ee_born: bool


class Demonstrator:
    """The scripted experts (`OracleSkills`) recording both action forms, with the recipe's
    perturbations on what they execute. `act` returns the executed joint action; `step` holds
    the four forms of that step (see the module doc)."""

    name = "oracle"
    ends_itself = True
    privileged = True
    observations = OracleSkills.observations

    def __init__(self, experts_cfg: ExpertsConfig, control_hz: int, seed: int, experts: Any = None) -> None:
        self.inner = OracleSkills(experts)
        self.joint_noise = JointNoise(experts_cfg.action_noise, seed) if experts_cfg.action_noise > 0 else None
        p = experts_cfg.perturbation
        self.ee_noise = EePerturbation(p, control_hz, seed) if p.active else None
        self.step: DemoStep | None = None
        self._robot: Robot | None = None

    @property
    def outcome(self) -> Any:
        return self.inner.outcome

    def reset(self, info: dict[str, Any]) -> None:
        self._robot = info["world"].robot
        self.inner.reset(info)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray | None:
        robot = self._robot
        assert robot is not None, "reset() first"
        last = self.step
        if (
            last is not None and not last.ee_born and not np.array_equal(last.label, last.executed)
            and np.array_equal(robot.applied_action(), Robot.clip_action(last.executed).astype(np.float32))
        ):
            robot.intend(last.label)  # a joint expert goes on from its own last command, not from the noise
        joint = self.inner.act(obs)
        if joint is None:
            self.step = None
            return None
        label = np.asarray(joint, dtype=np.float32)
        ee = self.inner.last_ee
        if ee is not None:  # ee-born: exact; the joint forms through the one map from this commanded state
            label_ee = np.asarray(ee, dtype=np.float32)
            executed_ee = label_ee + self.ee_noise(label_ee) if self.ee_noise is not None else label_ee
            executed = label if np.array_equal(executed_ee, label_ee) else robot.ee.to_joint(executed_ee)
            if self.joint_noise is not None:
                self.joint_noise.rng.standard_normal(ACTION_DIM)  # keep its stream step-aligned
        else:  # joint-born (legacy experts): exact joint form, approximate ee twins
            executed = label + self.joint_noise(label) if self.joint_noise is not None else label
            if self.ee_noise is not None:
                self.ee_noise.rng.standard_normal(EE_ACTION_DIM)
            label_ee = robot.ee.to_ee(label)
            executed_ee = label_ee if np.array_equal(executed, label) else robot.ee.to_ee(executed)
        self.step = DemoStep(label, np.asarray(executed, np.float32), label_ee, np.asarray(executed_ee, np.float32), ee is not None)
        return self.step.executed.copy()

    def close(self) -> None:
        self.inner.close()
