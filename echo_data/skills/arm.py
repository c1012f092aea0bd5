"""Arm-motion helpers shared by the manipulation experts (pick, place, door, sink).

Everything here yields whole 12-float actions (base still, torso/arm/gripper targets), so an
expert composes them with `yield from` and the caller applies each action with `world.step`.

Typical use in an expert::

    planner = arm_planner(world, exclude={"phone_0"})        # nearby boxes as obstacles
    q0 = commanded_group(world.robot)                         # (torso, 7 arm)
    goal = planner.ik(top_down_pose(x, y, z, yaw), q0)         # None -> "no IK solution"
    path = planner.path(q0, goal)                              # None -> "no motion plan"
    yield from follow_path(world, path, gripper=GRIPPER_OPEN)
    qs = cartesian_path(planner, goal, [pose_a, pose_b])      # straight TCP moves
    yield from set_gripper(world, 0.0, steps=8)

Speeds: arm joints <= ARM_SPEED rad/s, torso <= TORSO_SPEED m/s (targets are interpolated
per control step; the drives follow with about 0.1 s lag).
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import sapien

from echo_data.robot import urdf as U
from echo_data.robot.planner import ArmPlanner, Box
from echo_data.robot.robot import GRIPPER_OPEN, HEAD_PAN, HEAD_TILT, READY_GROUP, TUCK_QPOS, Robot
from echo_data.scene.objects import object_size
from echo_data.skills.servo import jaw_yaw as servo_jaw_yaw
from echo_data.skills.servo import top_down

if TYPE_CHECKING:
    from echo_data.world import World

ARM_SPEED = 1.3  # rad/s per joint
TORSO_SPEED = 0.15  # m/s
SETTLE_TOL = 0.03  # rad: a path ends when every joint is this close to its target ...
SETTLE_MAX = 8  # ... or after this many extra steps
OBSTACLE_RADIUS = 2.0  # m around the base: furniture/walls/objects given to the planner
SLOW = 0.35  # speed scale of careful moves: descending to and lifting from a surface (Pick, Place)

Actions = Generator[np.ndarray, None, Any]


def top_down_pose(x: float, y: float, z: float, yaw: float) -> sapien.Pose:
    """TCP pose pointing straight down with the fingers closing across `yaw` + 90 deg
    (`echo_data.skills.servo.top_down` as a sapien.Pose)."""
    return sapien.Pose(top_down(x, y, z, yaw))


def jaw_yaw(pose: sapien.Pose) -> float:
    """The `yaw` of `top_down_pose` that gives this TCP pose's jaw direction (inverse of it)."""
    return servo_jaw_yaw(pose.to_transformation_matrix())


def group_q(robot: Robot) -> np.ndarray:
    """Measured (torso, 7 arm joints)."""
    return np.concatenate([[robot.torso()], robot.arm_qpos()])


def commanded_group(robot: Robot) -> np.ndarray:
    """Commanded (torso, 7 arm joints): where the arm is going; use as a path start."""
    a = robot.last_action()
    return np.asarray(a[3:11], dtype=np.float64)


def scene_boxes(world: World, exclude: Iterable[str] = (), radius: float = OBSTACLE_RADIUS) -> list[Box]:
    """Furniture, walls and objects (live poses) within `radius` of the base as planner boxes."""
    plan = world.plan
    bx, by, _ = world.robot.base_pose()
    skip = set(exclude)
    boxes: list[Box] = []

    def near(r_xmin: float, r_ymin: float, r_xmax: float, r_ymax: float) -> bool:
        dx = max(r_xmin - bx, 0.0, bx - r_xmax)
        dy = max(r_ymin - by, 0.0, by - r_ymax)
        return math.hypot(dx, dy) <= radius

    for f in plan.furniture:
        fp = f.footprint
        if near(fp.xmin, fp.ymin, fp.xmax, fp.ymax):
            boxes.append(Box(f"furniture_{f.index}", (f.center[0], f.center[1], f.size[2] / 2.0), (f.size[0], f.size[1], f.size[2])))
    for i, w in enumerate(plan.walls):
        fp = w.footprint
        if near(fp.xmin, fp.ymin, fp.xmax, fp.ymax):
            c = fp.center
            boxes.append(Box(f"wall_{i}", (c[0], c[1], w.height / 2.0), (fp.size[0], fp.size[1], w.height)))
    objects = world.handles.objects
    for o in plan.objects:
        if o.name in skip or o.name not in objects:
            continue
        p = objects[o.name].pose
        if math.hypot(p.p[0] - bx, p.p[1] - by) > radius:
            continue
        sx, sy, sz = object_size(o.category, o.scale)
        r = sapien.Pose(p.p, p.q).to_transformation_matrix()[:3, :3]
        yaw = math.atan2(r[1, 0], r[0, 0])
        boxes.append(Box(f"object_{o.name}", (float(p.p[0]), float(p.p[1]), float(p.p[2])), (sx, sy, sz), yaw))
    return boxes


def arm_planner(world: World, exclude: Iterable[str] = (), extra: Sequence[Box] = ()) -> ArmPlanner:
    """The world's ArmPlanner (one per world, seeded by the episode), synced to the robot now."""
    planner = world.arm_planner
    if planner is None:
        planner = ArmPlanner(seed=int(world.spec.seed) & 0xFFFF_FFFF)
        world.arm_planner = planner
    robot: Robot = world.robot
    planner.sync(robot.base_pose(), commanded_group(robot), robot.gripper_opening(), (HEAD_PAN, HEAD_TILT))
    planner.set_obstacles(list(scene_boxes(world, exclude)) + list(extra))
    return planner


def _action(robot: Robot, g: np.ndarray, gripper: float) -> np.ndarray:
    a = robot.rest_action()
    a[3] = g[0]
    a[4:11] = g[1:]
    a[11] = gripper
    return a


def follow_path(
    world: World, waypoints: Sequence[np.ndarray], gripper: float | None = None, speed_scale: float = 1.0, settle: bool = True
) -> Actions:
    """Yield actions that move (torso, arm) through `waypoints` at bounded joint speeds.

    The gripper target stays where it is unless `gripper` is given. With `settle`, ends when
    the measured joints are within SETTLE_TOL of the last waypoint or after SETTLE_MAX extra
    steps; returns the number of actions yielded.
    """
    robot: Robot = world.robot
    dt = 1.0 / robot.cfg.control_hz
    grip = float(robot.last_action()[11]) if gripper is None else float(gripper)
    limit = np.array([TORSO_SPEED] + [ARM_SPEED] * 7) * dt * speed_scale
    n = 0
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        k = max(1, int(math.ceil(float(np.max(np.abs(b - a) / limit)))))
        for i in range(1, k + 1):
            yield _action(robot, a + (b - a) * (i / k), grip)
            n += 1
    goal = np.asarray(waypoints[-1], dtype=np.float64)
    for _ in range(SETTLE_MAX if settle else 0):
        if np.max(np.abs(group_q(robot) - goal)) < SETTLE_TOL:
            break
        yield _action(robot, goal, grip)
        n += 1
    return n


def set_gripper(world: World, opening: float, steps: int = 8) -> Actions:
    """Hold the arm and drive the gripper to `opening` (m) for `steps` control steps."""
    robot: Robot = world.robot
    for _ in range(steps):
        a = robot.rest_action()
        a[11] = opening
        yield a
    return steps


def hold(world: World, steps: int) -> Actions:
    """Yield `steps` rest actions (everything held, base still)."""
    for _ in range(steps):
        yield world.robot.rest_action()
    return steps


def cartesian_path(planner: ArmPlanner, start: np.ndarray, poses: Sequence[sapien.Pose], check_collision: bool = False, gripper: float | None = None) -> list[np.ndarray] | None:
    """Joint waypoints through TCP `poses`, each IK seeded by the previous (a straight-ish line).

    Collisions are not checked by default: these short moves end in contact on purpose
    (descending onto an object, onto a table). None if any pose has no nearby IK solution.
    """
    out = [np.asarray(start, dtype=np.float64)]
    for p in poses:
        q = planner.ik(p, out[-1], fix_torso=True, tries=1, check_collision=check_collision, gripper=gripper)
        if q is None or float(np.max(np.abs(q[1:] - out[-1][1:]))) > 0.6:
            return None
        out.append(q)
    return out


def line_poses(a: sapien.Pose, b: sapien.Pose, step: float = 0.02) -> list[sapien.Pose]:
    """Poses along the straight line from a to b (orientation of b), excluding a."""
    d = float(np.linalg.norm(np.asarray(b.p) - np.asarray(a.p)))
    n = max(1, int(math.ceil(d / step)))
    return [sapien.Pose(np.asarray(a.p) + (np.asarray(b.p) - np.asarray(a.p)) * (i / n), b.q) for i in range(1, n + 1)]


def tuck_group(torso: float) -> np.ndarray:
    """(torso, tuck arm) - the driving configuration."""
    return np.concatenate([[torso], TUCK_QPOS])


UNTUCK_LIFT = -0.5  # shoulder_lift while leaving / entering the tuck (upper arm raised)


def is_tucked(group: np.ndarray, tol: float = 0.05) -> bool:
    return bool(np.max(np.abs(np.asarray(group)[1:] - TUCK_QPOS)) < tol)


def untuck_waypoints(start: np.ndarray) -> list[np.ndarray]:
    """Waypoints from `start` to READY_GROUP: torso up, upper arm raised, then READY (tucked starts)."""
    start = np.asarray(start, dtype=np.float64)
    if not is_tucked(start):
        return [start, READY_GROUP.copy()]
    up = start.copy()
    up[0] = READY_GROUP[0]
    raised = up.copy()
    raised[2] = UNTUCK_LIFT
    return [start, up, raised, READY_GROUP.copy()]


def tuck_waypoints(start: np.ndarray, torso_end: float | None = None) -> list[np.ndarray]:
    """Waypoints from `start` (near READY) back into the tuck, then the torso to `torso_end`."""
    start = np.asarray(start, dtype=np.float64)
    raised = tuck_group(start[0])
    raised[2] = UNTUCK_LIFT
    pts = [start, READY_GROUP.copy(), raised, tuck_group(start[0])]
    if not np.allclose(start, READY_GROUP, atol=0.05):
        pts = [start] + pts[1:]
    if torso_end is not None:
        pts.append(tuck_group(torso_end))
    return pts


def plan_through(planner: ArmPlanner, waypoints: Sequence[np.ndarray], gripper: float | None = None) -> list[np.ndarray] | None:
    """Join waypoints by straight segments; a colliding segment is replaced by an RRTConnect path.

    Intermediate waypoints that collide here (a wall beside the robot) are skipped; if a
    segment cannot be planned, the rest is planned directly to the last waypoint.
    """
    pts = [np.asarray(w, dtype=np.float64) for w in waypoints]
    pts = [pts[0]] + [w for w in pts[1:-1] if not planner.collisions(w, gripper)] + [pts[-1]]
    out = [pts[0]]
    for i, (a, b) in enumerate(zip(pts[:-1], pts[1:])):
        seg = planner.path(a, b, gripper)
        if seg is None:
            if i + 1 == len(pts) - 1:
                return None
            seg = planner.path(a, pts[-1], gripper)
            if seg is None:
                return None
            out.extend(seg[1:])
            return out
        out.extend(seg[1:])
    return out


__all__ = [
    "ARM_SPEED",
    "TORSO_SPEED",
    "GRIPPER_OPEN",
    "top_down_pose",
    "jaw_yaw",
    "group_q",
    "commanded_group",
    "scene_boxes",
    "arm_planner",
    "follow_path",
    "set_gripper",
    "hold",
    "cartesian_path",
    "line_poses",
    "tuck_group",
    "READY_GROUP",
    "untuck_waypoints",
    "tuck_waypoints",
    "plan_through",
    "is_tucked",
    "U",
]
