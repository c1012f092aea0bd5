"""Per-control-step records produced by a rollout, and the layout of `action` and `state`.

The fixed-length vectors are described here once so that the robot, the dataset schema,
the stats and the loaders agree on what each element means.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec

ARM_JOINTS = 7
# action = [base vx, base vy, base wz (robot frame, m/s, rad/s), torso target (m),
#           7 arm joint targets (rad), gripper target opening (m, 0 closed .. 0.1 open)]
ACTION_NAMES: tuple[str, ...] = (
    ("base_vx", "base_vy", "base_wz", "torso")
    + tuple(f"arm_{i}" for i in range(ARM_JOINTS))
    + ("gripper",)
)
ACTION_DIM = len(ACTION_NAMES)  # 12

# state = [base x, y, yaw (world), torso (m), 7 arm joint positions, gripper opening (m),
#          base vx, vy, wz, torso vel, 7 arm joint velocities, gripper vel, holding (0/1)]
STATE_NAMES: tuple[str, ...] = (
    ("base_x", "base_y", "base_yaw", "torso")
    + tuple(f"arm_{i}" for i in range(ARM_JOINTS))
    + ("gripper",)
    + ("base_vx", "base_vy", "base_wz", "torso_vel")
    + tuple(f"arm_{i}_vel" for i in range(ARM_JOINTS))
    + ("gripper_vel", "holding")
)
STATE_DIM = len(STATE_NAMES)  # 25

# The end-effector form of the same command (`robot.action_space: ee_delta`, the env's
# `action_mode`; docs/action_spaces.md): base velocities and torso target as in ACTION_NAMES, then
# the tool-centre-point change this step, expressed in the base frame's axes and applied to the
# commanded TCP pose relative to the torso (m, and a rotation vector in rad), and a binary
# gripper command (1 = close, 0 = open). Every step row stores both forms (`action`, `action.ee`).
EE_ACTION_NAMES: tuple[str, ...] = (
    ("base_vx", "base_vy", "base_wz", "torso")
    + ("ee_dx", "ee_dy", "ee_dz", "ee_drx", "ee_dry", "ee_drz")
    + ("gripper_close",)
)
EE_ACTION_DIM = len(EE_ACTION_NAMES)  # 11
ACTION_SPACES: tuple[str, ...] = ("joint", "ee_delta")

# Where the robot is in the world says which apartment it is in, not what to do: a learner's
# default proprioception leaves the world pose out (issue: no scene memorising).
WORLD_POSE_STATE: tuple[str, ...] = ("base_x", "base_y", "base_yaw")
BASE_FRAME_STATE: tuple[str, ...] = tuple(n for n in STATE_NAMES if n not in WORLD_POSE_STATE)

# Step-row columns that only a simulator knows (the target's pose, the handle's angle, ...):
# their names start with this prefix, the schema flags them privileged, and no learner reads
# them unless asked by name (the privileged sanity learner does).
PRIVILEGED_PREFIX = "observation.privileged."
# The privileged step columns (float32 vectors; computed by `echo_data.envs.privileged` from the
# world, docs/privileged_observations.md). "Target" is the current skill's target: the object
# (Pick, Place's carried object is the hand's business), the handle bar of a door, the faucet
# lever's tip, the place spot on a piece of furniture. Base frame: x forward, y left, z up from
# the floor under the base centre (the frame `action.ee` moves the hand in).
PRIVILEGED_COLUMNS: dict[str, int] = {
    PRIVILEGED_PREFIX + "target_pose": 7,
    PRIVILEGED_PREFIX + "tcp_to_target": 3,
    PRIVILEGED_PREFIX + "joint_angle": 1,
    PRIVILEGED_PREFIX + "place_spot": 3,
}
# What each privileged column holds (the dataset card and docs/privileged_observations.md say it).
PRIVILEGED_NOTES: dict[str, str] = {
    PRIVILEGED_PREFIX + "target_pose": (
        "the current skill's target in the base frame: position (m) and orientation as a unit quaternion "
        "(w, x, y, z; w >= 0). Object: its body pose; door: the swing-side handle bar's centre, yawed with "
        "the leaf; faucet: the lever's tip, yawed with the lever; furniture: in a Place `place_spot`, else the "
        "top's point nearest the base; yaw 0"
    ),
    PRIVILEGED_PREFIX + "tcp_to_target": "target position minus the measured tool-centre-point position (m), in the base frame's axes",
    PRIVILEGED_PREFIX + "joint_angle": "the target door's hinge angle or the faucet lever's angle (rad, 0 = closed); 0 for objects and furniture",
    PRIVILEGED_PREFIX + "place_spot": (
        "in a Place, where the object goes, in the base frame (m, z = the top's height): the Place "
        "expert's best free spot on the goal receptacle from where the base stands (else the top's point "
        "nearest the base); zeros in every other skill"
    ),
}
# The active skill's goal as the runtime hands it to a policy that asks for it (the paper's starred
# rows, given the target's position): float32 (x, y, yaw) in the world, the interaction pose of
# the skill's target with the doors where they stood when the skill began (`skills.navigate.goal_pose`).
GOAL_POSE = PRIVILEGED_PREFIX + "goal_pose"


@dataclass
class StepRecord:
    """Everything observed and done at one control step (audio features are added later)."""

    frame_index: int
    timestamp: float  # seconds since episode start = frame_index / control_hz
    skill: str
    skill_index: int  # index into EpisodeSpec.chain
    action: np.ndarray  # float32 (ACTION_DIM,): the controller's own action (the label to clone)
    state: np.ndarray  # float32 (STATE_DIM,)
    head_rgb: np.ndarray | None  # uint8 (H, W, 3)
    head_depth: np.ndarray | None  # uint16 (H, W) millimetres
    wrist_depth: np.ndarray | None  # uint16 (H, W) millimetres
    ear_position: tuple[float, float, float]  # head centre in world (for audio)
    ear_yaw: float  # head yaw in world (rad)
    sounding: tuple[bool, ...]  # per event: still playing at this step
    skill_success: tuple[bool, ...] = field(default_factory=tuple)  # per chain entry: the env's latched tests after this step's action
    done: bool = False
    # camera name ("head", "wrist") -> 4x4 camera-to-world, OpenCV axes (echo_data.camera)
    camera_poses: dict[str, np.ndarray] = field(default_factory=dict)
    # float32 (ACTION_DIM,) the robot executed, when it differs from `action` (DART noise or an
    # end-effector perturbation, echo_data.agents.dart); None: the action itself was executed
    executed: np.ndarray | None = None
    # The end-effector form of the same step (EE_ACTION_NAMES, float32 (EE_ACTION_DIM,)): the
    # label and, when it differs, what was executed. Exact for commands born in ee form (the
    # joint form is derived from it); the `to_ee` twin of joint-born commands (docs/action_spaces.md).
    action_ee: np.ndarray | None = None
    executed_ee: np.ndarray | None = None
    # PRIVILEGED_COLUMNS name -> float32 vector: what only the simulator knows at this step
    privileged: dict[str, np.ndarray] = field(default_factory=dict)
    # True on the last row of each skill segment (the expert ended the skill after this action)
    skill_stop: bool = False

    @property
    def action_executed(self) -> np.ndarray:
        """What the robot was sent at this step (replaying these reproduces the episode)."""
        return self.action if self.executed is None else self.executed

    @property
    def action_ee_executed(self) -> np.ndarray | None:
        """The end-effector form of what the robot was sent (replaying these in ee mode reproduces the episode)."""
        return self.action_ee if self.executed_ee is None else self.executed_ee


@dataclass
class HandOverRecord:
    """Where a chain entry's drive handed over (docs/handover.md): the stance it ends in (the
    `skill_table.HandOver` of entry `index`, named by `handover_call`) and where the base stood
    when the entry ended, against that target's interaction pose (doors as they stood then)."""

    skill: str  # the skill whose stance it is
    index: int  # that skill's chain entry (the next one for a Navigate, itself for Place)
    distance: float  # the stance's radius (m)
    heading: float  # the stance's heading tolerance (rad)
    end: tuple[float, float, float]  # base x, y, yaw (world) when the entry ended
    goal: tuple[float, float, float] | None  # the interaction pose (None: the target has no free one)
    goal_distance: float | None  # m from `goal` (None without one)
    heading_error: float | None  # rad from `goal`'s heading, wrapped to [0, pi]
    inside: bool  # the environment's `handed_over` for the entry when it ended
    # build --handover-from: True when the Navigate expert stopped at a learner's recorded end
    # pose, False when that pose was no usable cell (it stopped at its own goal); None: none given
    learner_stop: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able record (the dataset's `outcomes[k].handover`, evaluate's `skills[k].handover`)."""
        return {"skill": self.skill, "index": self.index, "distance": self.distance, "heading": self.heading,
                "end": [float(v) for v in self.end], "goal": None if self.goal is None else [float(v) for v in self.goal],
                "goal_distance": self.goal_distance, "heading_error": self.heading_error, "inside": bool(self.inside),
                "learner_stop": self.learner_stop}


@dataclass
class SkillOutcome:
    """How one entry of the skill chain ended."""

    skill: str
    target: str
    success: bool
    reason: str  # "" on success, else why it failed (e.g. "no IK solution", "timeout")
    steps: int
    handover: HandOverRecord | None = None  # set by the runtime for an entry that hands over (skill_table.handover_call)

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able record the dataset's `outcomes` and evaluate's `skills` hold."""
        return {"skill": self.skill, "target": self.target, "success": bool(self.success), "reason": self.reason,
                "steps": int(self.steps), "handover": None if self.handover is None else self.handover.to_dict()}


@dataclass
class EpisodeResult:
    """A finished rollout (the experts' or any agent's run in the environment) with what it
    heard, ready for the dataset writer.

    Audio arrays are aligned with `steps`; `success` is every skill of the chain succeeding, in order.
    """

    spec: EpisodeSpec
    steps: list[StepRecord]
    outcomes: list[SkillOutcome]
    success: bool
    audio: np.ndarray | None = None  # (n_samples, 2) float32 binaural track
    audio_offsets: np.ndarray | None = None  # (n_steps,) int64: sample index at each step
    spectrogram: np.ndarray | None = None  # (n_steps, 65, 26, 2) float32, SoundSpaces-style
    mel: np.ndarray | None = None  # (n_steps, n_mels, 101, 2) float32 log-mel of the last 1 s
    rejected: dict[str, int] = field(default_factory=dict)  # sampling rejections on the way
    resolved_frame: list[int | None] = field(default_factory=list)  # per event: frame at which its sound stops
    # (frame, hinge angles of every door) after each successful OpenDoor: the acoustics
    # switch to the opened geometry from that frame on.
    door_changes: list[tuple[int, dict[int, float]]] = field(default_factory=list)
    # Set when the recipe's `outputs.max_frames` cut the episode after this many steps: the steps
    # are the whole episode's first ones, `success` and the outcomes are as they stood at the cut.
    truncated_at: int | None = None

    @property
    def complete(self) -> bool:
        """Worth storing: the chain succeeded, or the episode ran cleanly up to the recipe's cut."""
        return self.success or self.truncated_at is not None


def records_digest(steps: list[StepRecord]) -> str:
    """sha256 over every field of every step record: equal digests mean bit-identical rollouts."""
    import hashlib

    h = hashlib.sha256()
    for s in steps:
        h.update(f"{s.frame_index}|{s.timestamp!r}|{s.skill}|{s.skill_index}|{s.ear_position!r}|{s.ear_yaw!r}|{s.sounding}|{s.skill_success}|{s.done}|{s.skill_stop}".encode())
        privileged = [s.privileged[k] for k in sorted(s.privileged)]
        for arr in (s.action, s.executed, s.action_ee, s.executed_ee, s.state, s.head_rgb, s.head_depth, s.wrist_depth, *privileged):
            if arr is not None:
                a = np.ascontiguousarray(arr)
                h.update(f"{a.dtype}{a.shape}".encode())
                h.update(a.tobytes())
    return h.hexdigest()
