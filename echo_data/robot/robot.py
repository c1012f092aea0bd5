"""The simulated Fetch-like robot: loading, drives, actions, proprioception and cameras.

Action and state follow `echo_data.records` exactly:
- action (12): base vx, vy (m/s) and wz (rad/s) in the robot frame, torso target (m), 7 arm
  joint targets (rad), gripper opening target (m, 0 closed .. 0.1 open);
- state (25): base x, y, yaw (world, yaw wrapped to [-pi, pi)), torso, 7 arm joints, gripper
  opening, base vx, vy (robot frame), wz, torso vel, 7 arm joint vels, gripper opening rate,
  holding (1 when an object touches both fingers).

Why this shape (docs/SIMULATION_NOTES.md#robot): the planar base is a virtual x/y/yaw joint chain on a fixed root,
driven by velocity with high damping; gravity is off on every robot link so that position
drives track exactly and a carried object's weight is the only load.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import sapien

from echo_data.recipe import CameraConfig, RobotConfig
from echo_data.records import ACTION_DIM, STATE_DIM
from echo_data.robot import urdf as U

if TYPE_CHECKING:
    from echo_data.robot.ee_control import EeController

# Fetch's tuck: the arm folded beside the torso, inside the base footprint (drive with this).
TUCK_QPOS = np.array([1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0], dtype=np.float64)
# READY / carry configuration: torso up, TCP 0.27 m ahead of the base centre at 1.15 m, pointing
# down (found once with ArmPlanner.ik; reached from the tuck without self-collision via
# UNTUCK_LIFT, and from it straight joint paths reach pre-grasps over 0.6-0.9 m tops).
READY_GROUP = np.array([0.386, 0.605, -0.379, -2.618, 2.145, 0.556, 2.065, 1.102], dtype=np.float64)  # (torso, 7 arm)
HEAD_PAN = 0.0
HEAD_TILT = 0.45  # rad, looking down: sees the floor ahead and table tops (the action has no head)
GRIPPER_OPEN = 0.1  # m, full opening
GRIPPER_CLOSED = 0.0
MAX_BASE_SPEED = 0.6  # m/s, clip of the velocity action
MAX_BASE_TURN = 1.2  # rad/s
FINGER_FRICTION = 2.0  # 29/29 lifts of a phone with 2.0 (docs/SIMULATION_NOTES.md#grasping)

# drive gains (stiffness, damping, force limit); "force" mode
BASE_DRIVE = (0.0, 2.0e5, 1.0e7)
YAW_DRIVE = (0.0, 5.0e4, 1.0e7)
TORSO_DRIVE = (1.0e5, 1.0e4, 1.0e5)
HEAD_DRIVE = (1.0e3, 1.0e2, 100.0)
ARM_DRIVE = (3.0e3, 3.0e2, 500.0)
FINGER_DRIVE = (1.0e3, 1.0e2, 100.0)

# Picture names of the "minimal" shader (camera.get_picture_names() segfaults, docs/SIMULATION_NOTES.md#rendering).
COLOR_PICTURE = "Color"
POSITION_PICTURE = "PositionSegmentation"
MINIMAL_SHADER_DIR = str(Path(sapien.__file__).parent / "vulkan_shader" / "minimal")


def wrap_angle(a: float) -> float:
    """Angle in [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def yaw_of(pose: sapien.Pose) -> float:
    """Heading of a pose's x axis projected on the floor."""
    r = pose.to_transformation_matrix()[:3, :3]
    return math.atan2(r[1, 0], r[0, 0])


def has_render_system(scene: sapien.Scene) -> bool:
    try:
        scene.render_system  # noqa: B018 (raises without a render system)
        return True
    except RuntimeError:
        return False


class Robot:
    """A Fetch-like mobile manipulator in `scene`.

    Attributes other modules use: `articulation`, `links` (name -> link component),
    `joint_index` (name -> index into qpos), `arm_indices`, `ee_link`, `finger_links`,
    `tuck_qpos` (7,), `cfg`. Call `set_base_pose` once before stepping.
    """

    # The rest pose, read through the instance by the end-effector map (`robot.ee_control`,
    # which this module imports: it does not import this module back).
    READY_GROUP = READY_GROUP
    HEAD_REST = (HEAD_PAN, HEAD_TILT)
    GRIPPER_OPEN = GRIPPER_OPEN

    def __init__(self, scene: sapien.Scene, cfg: RobotConfig) -> None:
        self.scene = scene
        self.cfg = cfg
        self.render = has_render_system(scene)
        loader = scene.create_urdf_loader()
        loader.fix_root_link = True
        for name in U.FINGER_LINKS:
            loader.set_link_material(name, FINGER_FRICTION, FINGER_FRICTION, 0.0)
            loader.set_link_patch_radius(name, 0.01)  # torsional friction: held objects do not swing
            loader.set_link_min_patch_radius(name, 0.005)
        builder = loader.load_file_as_articulation_builder(str(U.URDF_PATH), str(U.SRDF_PATH))
        if not self.render:  # a physics-only scene refuses visual shapes
            for lb in builder.link_builders:
                lb.visual_records.clear()
        self.articulation = builder.build()
        self.articulation.name = "robot"
        self.links = {ln.name: ln for ln in self.articulation.links}
        self.joints = {j.name: j for j in self.articulation.active_joints}
        names = [j.name for j in self.articulation.active_joints]
        self.joint_index = {n: i for i, n in enumerate(names)}
        self.base_indices = [self.joint_index[n] for n in U.BASE_JOINTS]
        self._base_joints = [self.articulation.active_joints[i] for i in self.base_indices]  # re-aimed every substep
        self.torso_index = self.joint_index[U.TORSO_JOINT]
        self.head_indices = [self.joint_index[n] for n in U.HEAD_JOINTS]
        self.arm_indices = [self.joint_index[n] for n in U.ARM_JOINTS]
        self.finger_indices = [self.joint_index[n] for n in U.FINGER_JOINTS]
        self.ee_link = self.links[U.EE_LINK]
        self.finger_links = [self.links[n] for n in U.FINGER_LINKS]
        self.tuck_qpos = TUCK_QPOS.copy()
        self._robot_entities = {ln.entity for ln in self.articulation.links}
        for ln in self.articulation.links:
            ln.disable_gravity = True
        for n, j in self.joints.items():
            gains = (
                BASE_DRIVE if n in U.BASE_JOINTS[:2] else YAW_DRIVE if n == U.BASE_JOINTS[2]
                else TORSO_DRIVE if n == U.TORSO_JOINT else HEAD_DRIVE if n in U.HEAD_JOINTS
                else FINGER_DRIVE if n in U.FINGER_JOINTS else ARM_DRIVE
            )
            j.set_drive_properties(gains[0], gains[1], gains[2], "force")
            j.set_friction(0.0)
        self.attached: str | None = None  # an object the world's magic grasp holds (echo_data.world)
        self._intent: np.ndarray | None = None  # see intend()
        self._ee: EeController | None = None  # see `ee`
        self._action = self.rest_action_for(np.zeros(3), 0.0, self.tuck_qpos, GRIPPER_OPEN)
        q = np.zeros(len(names))
        q[self.head_indices] = (HEAD_PAN, HEAD_TILT)
        q[self.arm_indices] = self.tuck_qpos
        q[self.finger_indices] = GRIPPER_OPEN / 2.0
        self.articulation.set_qpos(q)  # link poses are stale until the first set_qpos (docs/SIMULATION_NOTES.md#robot)
        self.articulation.set_qvel(np.zeros(len(names)))
        for i, v in zip(self.head_indices, (HEAD_PAN, HEAD_TILT)):
            self.articulation.active_joints[i].set_drive_target(v)
        self.apply(self._action)
        self.cameras: dict[str, Any] = {}
        if self.render:
            self._mount_camera("head", U.HEAD_CAMERA_LINK, cfg.head_camera)
            self._mount_camera("wrist", U.WRIST_CAMERA_LINK, cfg.wrist_camera)

    # ------------------------------------------------------------------ cameras
    def _mount_camera(self, name: str, link: str, cam: CameraConfig) -> None:
        if not (cam.rgb or cam.depth):
            return
        comp = sapien.render.RenderCameraComponent(cam.width, cam.height, MINIMAL_SHADER_DIR)
        comp.set_fovy(math.radians(cam.fov_deg), compute_x=True)
        comp.near = 0.02
        comp.far = 20.0
        comp.name = f"{name}_camera"
        self.links[link].entity.add_component(comp)
        comp.local_pose = sapien.Pose()
        self.cameras[name] = (comp, cam)

    def camera_poses(self) -> dict[str, np.ndarray]:
        """World pose of each configured camera: 4x4 camera-to-world in OpenCV axes (x right,
        y down, z forward), from its link (cameras sit at their link origin; no render needed)."""
        from echo_data.camera import cv_pose

        out: dict[str, np.ndarray] = {}
        for name, link, cam in (("head", U.HEAD_CAMERA_LINK, self.cfg.head_camera), ("wrist", U.WRIST_CAMERA_LINK, self.cfg.wrist_camera)):
            if cam.rgb or cam.depth:
                out[name] = cv_pose(self.links[link].entity_pose.to_transformation_matrix())
        return out

    def observe(self) -> dict[str, np.ndarray]:
        """Images of the enabled cameras: `head_rgb` uint8 (H,W,3), `head_depth`, `wrist_depth` uint16 mm.

        Depth is the distance along the optical axis; 0 where nothing is hit within `far`.
        Empty when the scene has no render system.
        """
        out: dict[str, np.ndarray] = {}
        if not self.cameras:
            return out
        self.scene.update_render()
        for name, (comp, cam) in self.cameras.items():
            comp.take_picture()
            # Conversions in place on whole contiguous pictures (the same values as the plain
            # expressions, several times faster on 128 x 128 frames).
            if cam.rgb:
                t = comp.get_picture(COLOR_PICTURE) * 255.0  # RGBA; alpha is dropped after the cast
                t += 0.5
                np.clip(t, 0, 255, out=t)
                out[f"{name}_rgb"] = np.ascontiguousarray(t.astype(np.uint8)[..., :3])
            if cam.depth:
                pos = comp.get_picture(POSITION_PICTURE)
                z = np.array(pos[..., 2], dtype=np.float64)
                np.multiply(z, -1000.0 if pos.dtype.kind == "f" else -1.0, out=z)  # metres (or mm) along -z -> mm
                np.fmax(z, 0.0, out=z)  # nothing hit (0), behind or NaN -> 0
                np.rint(z, out=z)
                np.minimum(z, 65535.0, out=z)
                out[f"{name}_depth"] = z.astype(np.uint16)
        return out

    # ------------------------------------------------------------------ base
    def set_base_pose(self, x: float, y: float, yaw: float) -> None:
        """Teleport the base (episode start only) and hold it there."""
        q = self.articulation.get_qpos()
        q[self.base_indices] = (x, y, yaw)
        self.articulation.set_qpos(q)
        qv = self.articulation.get_qvel()
        qv[self.base_indices] = 0.0
        self.articulation.set_qvel(qv)
        self._action[:3] = 0.0
        self._drive_base()

    def base_pose(self) -> tuple[float, float, float]:
        """(x, y, yaw) of the base in the world, yaw wrapped to [-pi, pi)."""
        q = self.articulation.get_qpos()
        return (float(q[self.base_indices[0]]), float(q[self.base_indices[1]]), wrap_angle(float(q[self.base_indices[2]])))

    def _drive_base(self) -> None:
        """Turn the robot-frame velocity command into world-frame joint velocity targets (per substep)."""
        vx, vy, wz = self._action[:3].tolist()
        yaw = float(self.articulation.get_qpos()[self.base_indices[2]])
        c, s = math.cos(yaw), math.sin(yaw)
        jx, jy, jyaw = self._base_joints
        jx.set_drive_velocity_target(c * vx - s * vy)
        jy.set_drive_velocity_target(s * vx + c * vy)
        jyaw.set_drive_velocity_target(wz)

    # ------------------------------------------------------------------ actions
    @staticmethod
    def clip_action(action: np.ndarray) -> np.ndarray:
        """The action as the drives take it (float64): base speed, torso and gripper clipped to their ranges."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (ACTION_DIM,):
            raise ValueError(f"action must have {ACTION_DIM} values, got {a.shape}")
        a = a.copy()
        sp = math.hypot(a[0], a[1])
        if sp > MAX_BASE_SPEED:
            a[:2] *= MAX_BASE_SPEED / sp
        a[2] = np.clip(a[2], -MAX_BASE_TURN, MAX_BASE_TURN)
        a[3] = np.clip(a[3], *U.TORSO_RANGE)
        a[11] = np.clip(a[11], GRIPPER_CLOSED, GRIPPER_OPEN)
        return a

    def apply(self, action: np.ndarray) -> None:
        """Set drive targets from one action (see module doc); base speed is clipped."""
        a = self.clip_action(action)
        self._action = a
        self._intent = None
        joints = self.articulation.active_joints
        joints[self.torso_index].set_drive_target(a[3])
        for i, v in zip(self.arm_indices, a[4:11]):
            joints[i].set_drive_target(v)
        for i in self.finger_indices:
            joints[i].set_drive_target(a[11] / 2.0)
        self._drive_base()

    def before_substep(self) -> None:
        """Re-aim the base velocity at the current heading (called by World before each physics step)."""
        self._drive_base()

    @staticmethod
    def rest_action_for(base_vel: np.ndarray, torso: float, arm: np.ndarray, gripper: float) -> np.ndarray:
        a = np.zeros(ACTION_DIM, dtype=np.float32)
        a[:3] = base_vel
        a[3] = torso
        a[4:11] = arm
        a[11] = gripper
        return a

    def rest_action(self) -> np.ndarray:
        """Hold everything where it is commanded now, with zero base velocity."""
        a = self.last_action()
        a[:3] = 0.0
        return a

    def last_action(self) -> np.ndarray:
        """The command being followed: the last applied action, or the controller's own command
        that noise perturbed (`intend`), so an expert continues from what it meant, not from the noise."""
        a = self._action if self._intent is None else self._intent
        return a.astype(np.float32).copy()

    def applied_action(self) -> np.ndarray:
        """The action the drives hold now, as clipped (what physics follows, noise included)."""
        return self._action.astype(np.float32).copy()

    def intend(self, action: np.ndarray) -> None:
        """Record the controller's own command for the last applied action (DART: the applied one
        was this plus noise). Read only through `last_action`/`rest_action`; physics never sees it."""
        self._intent = self.clip_action(action)

    @property
    def ee(self) -> EeController:
        """The end-effector action map of this robot (`echo_data.robot.ee_control`), made on first use."""
        if self._ee is None:
            from echo_data.robot.ee_control import EeController

            self._ee = EeController(self)
        return self._ee

    # ------------------------------------------------------------------ proprioception
    def torso(self) -> float:
        return float(self.articulation.get_qpos()[self.torso_index])

    def arm_qpos(self) -> np.ndarray:
        return self.articulation.get_qpos()[self.arm_indices].astype(np.float64)

    def gripper_opening(self) -> float:
        return float(np.sum(self.articulation.get_qpos()[self.finger_indices]))

    def state(self) -> np.ndarray:
        """The 25-float proprioception vector of `echo_data.records.STATE_NAMES`."""
        q = self.articulation.get_qpos()
        qv = self.articulation.get_qvel()
        x, y, yaw = (float(q[i]) for i in self.base_indices)
        vxw, vyw, wz = (float(qv[i]) for i in self.base_indices)
        c, s = math.cos(yaw), math.sin(yaw)
        st = np.zeros(STATE_DIM, dtype=np.float32)
        st[0:3] = (x, y, wrap_angle(yaw))
        st[3] = q[self.torso_index]
        st[4:11] = q[self.arm_indices]
        st[11] = q[self.finger_indices].sum()
        st[12:15] = (c * vxw + s * vyw, -s * vxw + c * vyw, wz)
        st[15] = qv[self.torso_index]
        st[16:23] = qv[self.arm_indices]
        st[23] = qv[self.finger_indices].sum()
        st[24] = 1.0 if self.holding is not None else 0.0
        return st

    def ee_pose(self) -> sapien.Pose:
        """World pose of the tool centre point (between the finger pads; +x = approach)."""
        return self.ee_link.entity_pose

    def ear_pose(self) -> tuple[tuple[float, float, float], float]:
        """Head camera position (the robot's 'ears') and its heading in the world."""
        p = self.links[U.HEAD_CAMERA_LINK].entity_pose
        return (float(p.p[0]), float(p.p[1]), float(p.p[2])), yaw_of(p)

    # ------------------------------------------------------------------ grasp
    def finger_contacts(self) -> tuple[set[sapien.Entity], set[sapien.Entity]]:
        """Non-robot entities pressing on the left / right finger after the last physics step."""
        left: set[sapien.Entity] = set()
        right: set[sapien.Entity] = set()
        lf, rf = (ln.entity for ln in self.finger_links)
        for c in self.scene.get_contacts():
            e0, e1 = c.bodies[0].entity, c.bodies[1].entity
            if e0 in (lf, rf):
                finger, other = e0, e1
            elif e1 in (lf, rf):
                finger, other = e1, e0
            else:
                continue
            if other in self._robot_entities:
                continue
            if not any(np.linalg.norm(p.impulse) > 1e-7 for p in c.points):
                continue
            (left if finger is lf else right).add(other)
        return left, right

    @property
    def holding(self) -> str | None:
        """Name of the object the magic grasp holds (`attached`), else of the dynamic body
        squeezed between both fingers, else None."""
        if self.attached is not None:
            return self.attached
        left, right = self.finger_contacts()
        both = [e for e in left & right if e.find_component_by_type(sapien.physx.PhysxRigidDynamicComponent) is not None]
        if not both:
            return None
        return sorted(e.name for e in both)[0]
