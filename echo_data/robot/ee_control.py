"""The end-effector action space: one deterministic map between `action.ee` and the joint `action`.

An `action.ee` (`echo_data.records.EE_ACTION_NAMES`, 11 floats) commands the base and torso as
the joint form does, moves the tool centre point (TCP) by a small change expressed in the base
frame's axes, and opens or closes the gripper with a binary command. Like ManiSkill3's
`pd_ee_delta_pose` with `use_target=True`, the change is applied to the *commanded* TCP pose
(forward kinematics of the joint targets the drives hold now), not the measured one, so that a
zero change holds the arm exactly (a carried object's weight never makes the target creep) and
the map depends only on the robot's commanded state. The arm joints then come from inverse
kinematics seeded at the commanded joints.

Frames: the TCP pose is taken relative to the torso (the arm's shape); the torso target moves
the whole arm up and down with it. The change's axes are the base frame's (the torso only
translates along the base's z), rotation as a rotation vector applied on the left
(R' = Exp(dr) R).

Why this module exists and who calls it: the environment in `action_mode="ee_delta"` turns each
action into joint targets here; the experts compute their commands in this space; the recorder
stores both forms of every step from here. Because every caller uses the same function on the
same commanded state, a replay from `action.ee.executed` (ee mode) and one from
`action.executed` (joint mode) apply the same float32 joint targets: bit-identical episodes.

Kinematics and IK are SAPIEN's built-in pinocchio model of the robot's articulation (closed-loop
IK, CLIK, on the seven arm joints only). CLIK ignores joint limits
(docs/SIMULATION_NOTES.md#robot-and-planning); here every solve starts at the commanded joints
and moves them by at most one control step's change, so the answer stays near the seed, and it
is clipped to the limits afterwards.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from echo_data.records import ACTION_DIM, EE_ACTION_DIM
from echo_data.robot import urdf as U

if TYPE_CHECKING:
    from echo_data.robot.robot import Robot

# Largest TCP change one action may ask for (per axis, m; rotation-vector norm, rad). At 10 Hz
# this is 0.5 m/s and ~115 deg/s: above what any expert commands (they move <= 0.25 m/s), so it
# only bounds a learner's outliers.
MAX_EE_STEP = 0.05
MAX_EE_TURN = 0.2
GRIPPER_CLOSE_AT = 0.5  # a binary command >= this closes the gripper
IK_EPS = 1e-5  # m / rad: the solve stops below this pose error
IK_ITERATIONS = 30
IK_DAMPING = 0.02  # damped least squares: bounded joint steps near singular poses
POSTURE_GAIN = 0.1  # share of the way to the posture the redundant degree of freedom moves per control step


def clip_delta(d: np.ndarray) -> np.ndarray:
    """A TCP change (6: dx, dy, dz, drx, dry, drz) limited to one action's reach (see MAX_EE_STEP)."""
    d = np.asarray(d, dtype=np.float64).copy()
    d[:3] = np.clip(d[:3], -MAX_EE_STEP, MAX_EE_STEP)
    n = float(np.linalg.norm(d[3:]))
    if n > MAX_EE_TURN:
        d[3:] *= MAX_EE_TURN / n
    return d


class EeController:
    """Forward/inverse kinematics of the arm and the `action.ee` <-> `action` map for one robot."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        art = robot.articulation
        self.model = art.create_pinocchio_model()
        links = [ln.name for ln in art.get_links()]
        self.ee_index = links.index(U.EE_LINK)
        self.torso_link_index = links.index("torso_lift_link")
        self.dof = art.dof
        self.q0 = np.zeros(self.dof)
        self.q0[robot.head_indices] = robot.HEAD_REST
        self.q0[robot.finger_indices] = robot.GRIPPER_OPEN / 2.0
        self.mask = np.zeros(self.dof, dtype=np.int32)
        self.mask[robot.arm_indices] = 1
        lim = np.asarray(art.get_qlimits(), dtype=np.float64).reshape(self.dof, 2)
        self.lower = lim[robot.arm_indices, 0]
        self.upper = lim[robot.arm_indices, 1]
        self.gripper_open = robot.GRIPPER_OPEN
        self.posture = np.asarray(robot.READY_GROUP[1:], dtype=np.float64)

    # ------------------------------------------------------------------ kinematics
    def _full(self, arm: np.ndarray) -> np.ndarray:
        """Articulation qpos with the base at the origin, the torso at 0 and `arm` (the TCP
        relative to the torso does not depend on the torso height)."""
        q = self.q0.copy()
        q[self.robot.arm_indices] = arm
        return q

    def tcp_in_torso(self, arm: np.ndarray) -> np.ndarray:
        """4x4 TCP pose relative to the torso link (axes of the base frame) for 7 arm joints."""
        self.model.compute_forward_kinematics(self._full(np.asarray(arm, dtype=np.float64)))
        torso = self.model.get_link_pose(self.torso_link_index)
        tcp = self.model.get_link_pose(self.ee_index)
        return (torso.inv() * tcp).to_transformation_matrix()

    def tcp_in_base(self, torso: float, arm: np.ndarray) -> np.ndarray:
        """4x4 TCP pose in the base frame for a torso height and 7 arm joints."""
        q = self._full(np.asarray(arm, dtype=np.float64))
        q[self.robot.torso_index] = torso
        self.model.compute_forward_kinematics(q)
        return self.model.get_link_pose(self.ee_index).to_transformation_matrix()  # base at the origin: root = base frame

    def ik(self, target_in_torso: np.ndarray, seed: np.ndarray, posture: np.ndarray | None = None) -> np.ndarray:
        """Arm joints (7) that put the TCP at `target_in_torso` (4x4), starting from `seed`.

        Damped least squares on the TCP's Jacobian (pinocchio's, LOCAL frame rotated to the base
        axes), joints clamped to their limits every iteration, and the arm's redundant seventh
        degree of freedom steered towards `posture` (default: READY, the carry pose) in the
        Jacobian's null space. Why our own loop and not SAPIEN's CLIK: CLIK has no joint limits
        and no posture, so a straight Cartesian move out of the tuck ends pressed against the wrist
        limit (measured: the TCP stops 6 cm short of READY); with both, the same move arrives.
        Deterministic: a fixed number of at most IK_ITERATIONS float64 iterations.
        """
        q = np.clip(np.asarray(seed, dtype=np.float64), self.lower, self.upper)
        home = self.posture if posture is None else np.asarray(posture, dtype=np.float64)
        arm = self.robot.arm_indices
        for it in range(IK_ITERATIONS):
            full = self._full(q)
            self.model.compute_forward_kinematics(full)
            torso = self.model.get_link_pose(self.torso_link_index).to_transformation_matrix()
            tcp = self.model.get_link_pose(self.ee_index).to_transformation_matrix()
            now = np.linalg.inv(torso) @ tcp
            err = np.zeros(6)
            err[:3] = target_in_torso[:3, 3] - now[:3, 3]
            err[3:] = Rotation.from_matrix(target_in_torso[:3, :3] @ now[:3, :3].T).as_rotvec()
            if float(np.linalg.norm(err[:3])) < IK_EPS and float(np.linalg.norm(err[3:])) < IK_EPS:
                break
            local = np.asarray(self.model.compute_single_link_local_jacobian(full, self.ee_index), dtype=np.float64)[:, arm]
            r = tcp[:3, :3]  # torso and base axes coincide with the root's here (base at the origin)
            jac = np.vstack([r @ local[:3], r @ local[3:]])
            jjt = jac @ jac.T + IK_DAMPING**2 * np.eye(6)
            pinv = jac.T @ np.linalg.inv(jjt)
            step = pinv @ err
            if it == 0:  # the posture pull once per solve (one control step), inside the task's null space
                step += (np.eye(7) - pinv @ jac) @ (POSTURE_GAIN * (home - q))
            q = np.clip(q + step, self.lower, self.upper)
        return q

    # ------------------------------------------------------------------ the two forms
    def to_joint(self, ee_action: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
        """The joint action (float32, 12) that executes `ee_action` from the commanded state
        `reference` (a joint action; default: what the drives hold now, `Robot.applied_action`)."""
        a = np.asarray(ee_action, dtype=np.float64).reshape(-1)
        if a.shape != (EE_ACTION_DIM,):
            raise ValueError(f"an end-effector action has {EE_ACTION_DIM} values, got {a.shape}")
        ref = np.asarray(self.robot.applied_action() if reference is None else reference, dtype=np.float32)
        out = ref.copy()
        out[:4] = a[:4]
        d = clip_delta(a[4:10])
        if np.any(d != 0.0):
            arm = ref[4:11].astype(np.float64)
            pose = self.tcp_in_torso(arm)
            goal = np.eye(4)
            goal[:3, :3] = Rotation.from_rotvec(d[3:]).as_matrix() @ pose[:3, :3]
            goal[:3, 3] = pose[:3, 3] + d[:3]
            out[4:11] = self.ik(goal, arm)
        out[11] = 0.0 if a[10] >= GRIPPER_CLOSE_AT else self.gripper_open
        return out.astype(np.float32)

    def to_ee(self, joint_action: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
        """The end-effector form (float32, 11) of a joint action taken from the commanded state
        `reference` (default: now). Exact for base, torso and gripper; the TCP change is the
        forward kinematics' difference (a joint action is only approximately an ee one)."""
        j = np.asarray(joint_action, dtype=np.float64).reshape(-1)
        if j.shape != (ACTION_DIM,):
            raise ValueError(f"a joint action has {ACTION_DIM} values, got {j.shape}")
        ref = np.asarray(self.robot.applied_action() if reference is None else reference, dtype=np.float64)
        out = np.zeros(EE_ACTION_DIM, dtype=np.float64)
        out[:4] = j[:4]
        if np.any(j[4:11] != ref[4:11]):
            a = self.tcp_in_torso(ref[4:11])
            b = self.tcp_in_torso(j[4:11])
            out[4:7] = b[:3, 3] - a[:3, 3]
            out[7:10] = Rotation.from_matrix(b[:3, :3] @ a[:3, :3].T).as_rotvec()
        out[10] = 1.0 if j[11] < self.gripper_open / 2.0 else 0.0
        return out.astype(np.float32)

    def delta_towards(self, goal_in_base: np.ndarray, arm: np.ndarray | None = None, torso: float | None = None) -> np.ndarray:
        """The TCP change (6) from the commanded TCP pose to `goal_in_base` (4x4, base frame), unclipped.
        Experts scale and clip it (echo_data.skills.servo)."""
        ref = self.robot.applied_action().astype(np.float64)
        arm_q = ref[4:11] if arm is None else np.asarray(arm, dtype=np.float64)
        t = float(ref[3]) if torso is None else float(torso)
        now = self.tcp_in_base(t, arm_q)
        d = np.zeros(6)
        d[:3] = goal_in_base[:3, 3] - now[:3, 3]
        d[3:] = Rotation.from_matrix(goal_in_base[:3, :3] @ now[:3, :3].T).as_rotvec()
        return d


def base_frame(x: float, y: float, yaw: float) -> np.ndarray:
    """4x4 world pose of the base frame for a base at (x, y, yaw) (z = 0: the virtual base sits on the floor)."""
    m = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    m[:2, :2] = ((c, -s), (s, c))
    m[0, 3], m[1, 3] = x, y
    return m


def world_to_base(world_pose: np.ndarray, base: tuple[float, float, float]) -> np.ndarray:
    """A 4x4 world pose expressed in the frame of a base at (x, y, yaw)."""
    return np.linalg.inv(base_frame(*base)) @ np.asarray(world_pose, dtype=np.float64)
