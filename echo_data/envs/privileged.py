"""Privileged observations: what only the simulator knows at a step, for the dataset's
`observation.privileged.*` columns (names, sizes and meanings: `echo_data.records.PRIVILEGED_COLUMNS`;
docs/privileged_observations.md).

A real robot has none of these; they exist so that a state-only learner (the privileged sanity
learner) can separate "the demonstrations cannot teach this" from "the cameras are too weak",
and so that traces can be read. The recorder computes them from the world before each step's
action (the state the row's observation shows); no learner reads them unless it names them.

Everything is expressed in the base frame of the base where it stands now (x forward, y left,
z up from the floor), the frame `action.ee` moves the hand in, so no column carries the world
position of the robot (no scene memorising through the back door).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from echo_data.records import PRIVILEGED_PREFIX
from echo_data.robot.ee_control import base_frame
from echo_data.skill_table import skill
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

TARGET_POSE = PRIVILEGED_PREFIX + "target_pose"
TCP_TO_TARGET = PRIVILEGED_PREFIX + "tcp_to_target"
JOINT_ANGLE = PRIVILEGED_PREFIX + "joint_angle"
PLACE_SPOT = PRIVILEGED_PREFIX + "place_spot"


def _yaw_pose(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    m = base_frame(x, y, yaw)
    m[2, 3] = z
    return m


def nearest_top_point(world: World, furniture: int, margin: float) -> tuple[float, float]:
    """The point of a furniture top nearest the base, `margin` inside its edges (its centre
    along an axis narrower than twice the margin)."""
    fp = world.plan.furniture[furniture].footprint
    bx, by, _ = world.robot.base_pose()

    def clamp(v: float, lo: float, hi: float) -> float:
        return (lo + hi) / 2.0 if lo + margin > hi - margin else min(max(v, lo + margin), hi - margin)

    return clamp(bx, fp.xmin, fp.xmax), clamp(by, fp.ymin, fp.ymax)


def place_spot_world(world: World, name: str | None, furniture: int) -> np.ndarray:
    """Where the object goes on `furniture` (world, top height): the Place expert's best free spot
    from where the base stands (`skills.place.place_spots`), else the top's point nearest the base."""
    from echo_data.skills.place import EDGE_MARGIN, place_spots

    top = world.plan.furniture[furniture].top_z
    spots = place_spots(world, name, furniture) if name is not None and name in world.handles.objects else []
    x, y = spots[0] if spots else nearest_top_point(world, furniture, EDGE_MARGIN)
    return np.array([x, y, top])


def top_point_world(world: World, furniture: int) -> np.ndarray:
    """The top's point nearest the base (`EDGE_MARGIN` inside its edges), at the top's height."""
    from echo_data.skills.place import EDGE_MARGIN

    return np.array([*nearest_top_point(world, furniture, EDGE_MARGIN), world.plan.furniture[furniture].top_z])


def target_world(world: World, spec: EpisodeSpec, call: SkillCall, spot: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """The 4x4 world pose of what `call` acts on, and that thing's joint angle (0 for objects and furniture).

    Object: its body pose. Door: the centre of the handle bar on the swing side, yawed with the
    leaf. Faucet: the lever's tip, yawed with the lever. Furniture: `spot` (a Place's place spot)
    or else the top's point nearest the base, yaw 0."""
    from echo_data.scene.articulated import lever_tip_world
    from echo_data.scene.door_handle import door_handle_world

    t = Target.parse(call.target)
    if t.kind == "object":
        return world.object_pose(t.name).to_transformation_matrix(), 0.0
    if t.kind == "door":
        door = world.plan.doors[t.index]
        q = float(world.handles.doors[t.index].get_qpos()[0])
        p = door_handle_world(door, q, door.open_sign)
        return _yaw_pose(float(p[0]), float(p[1]), float(p[2]), door.leaf_yaw(q)), q
    if t.kind == "faucet":
        faucet = world.plan.faucets[t.index]
        a = float(world.handles.faucets[t.index].get_qpos()[0])
        p = lever_tip_world(faucet, a)
        return _yaw_pose(float(p[0]), float(p[1]), float(p[2]), faucet.yaw + a), a
    p = top_point_world(world, t.index) if spot is None else spot
    return _yaw_pose(float(p[0]), float(p[1]), float(p[2]), 0.0), 0.0


def rigid_inverse(m: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4x4 transform (R^T, -R^T t): exact, and no LAPACK call (whose
    threads cost more than the whole probe on a busy machine)."""
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -(m[:3, :3].T @ m[:3, 3])
    return out


def pose_vector(m: np.ndarray) -> np.ndarray:
    """4x4 -> (x, y, z, qw, qx, qy, qz), the quaternion's sign fixed by qw >= 0."""
    x, y, z, w = Rotation.from_matrix(m[:3, :3]).as_quat()
    q = np.array([w, x, y, z])
    if q[0] < 0:
        q = -q
    return np.concatenate([m[:3, 3], q])


class PrivilegedProbe:
    """Computes a step's privileged columns. Its one memory is the last place spot with the base
    pose and call it was computed for: searching the top's free spots costs ~5 ms, and during a
    Place the base mostly stands still (a pure cache: the answer is the same without it)."""

    def __init__(self) -> None:
        self._spot: tuple[tuple, np.ndarray] | None = None

    def place_spot(self, world: World, spec: EpisodeSpec, call: SkillCall) -> np.ndarray:
        """`place_spot_world` for a Place call, from where the base stands."""
        from echo_data.skill_table import carried_object

        name = carried_object(spec, call)
        furniture = Target.parse(call.target).index
        key = (world.robot.base_pose(), name, furniture)
        if self._spot is None or self._spot[0] != key:
            self._spot = (key, place_spot_world(world, name, furniture))
        return self._spot[1]

    def __call__(self, world: World, spec: EpisodeSpec, call: SkillCall) -> dict[str, np.ndarray]:
        base = world.robot.base_pose()
        to_base = rigid_inverse(base_frame(*base))
        spot = self.place_spot(world, spec, call) if skill(call.skill).delivers else None
        target, angle = target_world(world, spec, call, spot)
        target_b = to_base @ target
        tcp = np.asarray(world.robot.ee_pose().p, dtype=np.float64)
        c, s = math.cos(base[2]), math.sin(base[2])
        rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world axes -> base axes
        spot_b = np.zeros(3) if spot is None else (to_base @ np.append(spot, 1.0))[:3]
        return {
            TARGET_POSE: pose_vector(target_b).astype(np.float32),
            TCP_TO_TARGET: (rot @ (target[:3, 3] - tcp)).astype(np.float32),
            JOINT_ANGLE: np.array([angle], dtype=np.float32),
            PLACE_SPOT: spot_b.astype(np.float32),
        }
