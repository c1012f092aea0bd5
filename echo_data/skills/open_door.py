"""The OpenDoor expert: grasp the door handle, swing the base about the hinge, let go.

Where it wants to start: on the door's swing side (the side the leaf opens towards), facing
the closed leaf, roughly in front of the handle — `interaction_pose(plan, "door:<i>")` of
`echo_data.scene.nav` (0.8 m from the leaf, facing the swing-side handle) is fine. The
expert first drives the base itself (holonomic, a few decimetres at most) to its grasp
stance: 0.88 m from the swing-side handle bar along the leaf normal and 0.3 m towards the
hinge, facing the leaf — the first of `STANCES` whose whole swing stays on free floor and
whose grasp the arm reaches.

Then (FINDINGS: 19-20/20 this way): reach a pre-grasp 7 cm in front of the bar with a
planned arm motion, move in, close the fingers on the vertical bar; once both fingers touch
the bar the world completes the grasp with a stiff drive between gripper and leaf (a heavy
door otherwise slips out of a parallel gripper; see `echo_data.world`). The base then turns about the hinge as one rigid
body with the leaf — constant robot-frame velocity for a rigid rotation, ramped over ≈1 s,
with feedback on the pose error — while the arm holds still, until the hinge is
`OPEN_MARGIN` beyond `Door.open_threshold`; the door is let go at rest, the base backs off
and the arm tucks.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np
import sapien

from echo_data.records import ACTION_DIM, SkillOutcome
from echo_data.robot.planner import ArmPlanner, Box
from echo_data.robot.robot import HEAD_PAN, HEAD_TILT
from echo_data.scene.articulated import door_handle_world
from echo_data.scene.floorplan import Door
from echo_data.skills import arm
from echo_data.skills.success import DOOR_REST_QVEL, door_open_success

# Grasp stances, preferred first: (distance from the bar along the leaf normal, shift along the
# leaf towards its free edge). Standing 0.3 m towards the hinge keeps the swing radius small
# (≈1.2 m) and the arm well inside its limits (a head-on reach at < 0.9 m needs the shoulder
# beyond its lift limit).
STANCES = ((0.88, -0.3), (0.95, -0.3), (0.88, -0.15), (0.95, -0.15), (0.95, 0.0), (0.8, -0.3))
PREGRASP_BACK = 0.07  # m, pre-grasp in front of the bar (4 cm clear of the open fingers)
GRASP_TORSO = 0.15  # m, preferred torso height for a handle at ≈1 m
SWING_RATE = 0.35  # rad/s hinge rate while the base swings
SWING_RAMP = 1.0  # s, velocity ramp at the start of the swing (FINDINGS)
K_POSE = 2.0  # 1/s, base pose feedback during the swing
OPEN_MARGIN = 0.12  # rad beyond the open threshold before letting go
LOST_GRIP = 0.35  # rad between commanded and measured hinge angle: the handle slipped
BACK_OFF = 0.15  # m the base backs away after letting go

# ---------------------------------------------------------------------------------------------
# Helpers shared with the CloseSink expert: planning on `echo_data.robot.planner.ArmPlanner`
# (via `echo_data.skills.arm`) from a stance the base has not reached yet, a short holonomic
# base approach.

REACH_REF = np.array([0.0, -1.0, 0.0, 1.6, 0.0, -0.6, 0.0])  # arm bent forward: IK reference
APPROACH_SPEED = 0.4  # m/s, final base approach
APPROACH_MIN_SPEED = 0.04  # m/s, so the last centimetres do not crawl
APPROACH_TURN = 0.8  # rad/s
APPROACH_TOL = 0.015  # m
APPROACH_YAW_TOL = math.radians(1.5)


def wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def door_boxes(world: object) -> list[Box]:
    """Door leaves at their current hinge angles (handles left out: the gripper takes them) and
    the floor, as planner boxes; `arm.scene_boxes` has walls, furniture and objects."""
    plan = world.plan  # type: ignore[attr-defined]
    angles = world.handles.door_angles()  # type: ignore[attr-defined]
    x, y, _ = world.robot.base_pose()  # type: ignore[attr-defined]
    boxes = [Box("floor", (x, y, -0.05), (6.0, 6.0, 0.1))]
    for d in plan.doors:
        yaw = d.leaf_yaw(angles.get(d.index, d.angle))
        mid = (d.hinge[0] + d.width / 2.0 * math.cos(yaw), d.hinge[1] + d.width / 2.0 * math.sin(yaw))
        if math.hypot(mid[0] - x, mid[1] - y) < arm.OBSTACLE_RADIUS + d.width:
            boxes.append(Box(f"door_{d.index}", (mid[0], mid[1], d.height / 2.0), (d.width, d.thickness, d.height), yaw))
    return boxes


def planner_at(world: object, base: tuple[float, float, float] | None = None) -> ArmPlanner:
    """The world's arm planner with the apartment's nearby boxes, its base at `base` (default: where it is)."""
    robot = world.robot  # type: ignore[attr-defined]
    planner = arm.arm_planner(world, extra=door_boxes(world))
    if base is not None:
        planner.sync(base, arm.commanded_group(robot), robot.gripper_opening(), (HEAD_PAN, HEAD_TILT))
        planner.set_obstacles(arm.scene_boxes(world) + door_boxes(world))  # re-expressed in the new base frame
    return planner


def tcp_pose(position: np.ndarray, rotation: np.ndarray) -> sapien.Pose:
    """A world TCP pose from a position and a 3x3 rotation (columns: approach, finger travel, normal)."""
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = position
    return sapien.Pose(m)


def reach_ik(planner: ArmPlanner, position: np.ndarray, rotation: np.ndarray, torso: float, ref: np.ndarray, fix_torso: bool = False) -> np.ndarray | None:
    """IK for a first reach: the solution nearest the reference arm shape `ref` at `torso`."""
    return planner.ik(tcp_pose(position, rotation), np.concatenate([[torso], ref]), fix_torso=fix_torso, tries=40)


def near_ik(planner: ArmPlanner, position: np.ndarray, rotation: np.ndarray, seed: np.ndarray, fix_torso: bool = False) -> np.ndarray | None:
    """IK next to `seed` (smooth sequences): None when only a different arm branch reaches it."""
    q = planner.ik(tcp_pose(position, rotation), seed, fix_torso=fix_torso, tries=8)
    if q is None or float(np.max(np.abs(q - seed))) > 0.6:
        return None
    return q


def arm_action(robot: object, q: np.ndarray, gripper: float, base: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """An action holding torso + arm at `q` (8 values) and the gripper at `gripper` (m)."""
    a = np.zeros(ACTION_DIM, dtype=np.float32)
    a[0:3] = base
    a[3] = q[0]
    a[4:11] = q[1:8]
    a[11] = gripper
    return a


@dataclass
class Moved:
    """How a base approach ended."""

    success: bool
    reason: str
    steps: int


def approach_base(
    world: object, goal: tuple[float, float, float], hold: np.ndarray, max_steps: int
) -> Generator[np.ndarray, None, Moved]:
    """Drive the (holonomic) base straight to a nearby pose, holding torso/arm/gripper as in `hold`.

    For the last few decimetres in front of a door or counter, where the path is clear by
    construction of the interaction pose; longer trips are Navigate's job.
    """
    robot = world.robot  # type: ignore[attr-defined]
    steps = 0
    while True:
        x, y, yaw = robot.base_pose()
        ex, ey, eyaw = goal[0] - x, goal[1] - y, wrap(goal[2] - yaw)
        if math.hypot(ex, ey) < APPROACH_TOL and abs(eyaw) < APPROACH_YAW_TOL:
            break
        if steps >= max_steps:
            return Moved(False, "timeout", steps)
        c, s = math.cos(yaw), math.sin(yaw)
        v = 2.0 * np.array([c * ex + s * ey, -s * ex + c * ey])
        speed = float(np.linalg.norm(v))
        if speed > APPROACH_SPEED:
            v *= APPROACH_SPEED / speed
        elif 0.0 < speed < APPROACH_MIN_SPEED:
            v *= APPROACH_MIN_SPEED / speed
        action = np.array(hold, dtype=np.float32)
        action[0:3] = (v[0], v[1], float(np.clip(2.0 * eyaw, -APPROACH_TURN, APPROACH_TURN)))
        yield action
        steps += 1
    stop = np.array(hold, dtype=np.float32)
    stop[0:3] = 0.0
    yield stop
    return Moved(True, "", steps + 1)


def untuck_waypoints(start: np.ndarray, goal: np.ndarray) -> list[np.ndarray]:
    """Joint waypoints from `start` to a reach `goal`: out of the tuck with the upper arm raised
    while the torso already travels (shorter than passing through the robot's READY pose)."""
    if not arm.is_tucked(start):
        return [start, goal]
    raised = arm.tuck_group(float(goal[0]))
    raised[2] = arm.UNTUCK_LIFT
    return [start, raised, goal]


def tuck_arm(world: object, gripper: float) -> Generator[np.ndarray, None, int | None]:
    """Bring the arm back into the tuck (upper arm raised on the way in); None when no path is found."""
    robot = world.robot  # type: ignore[attr-defined]
    planner = planner_at(world)
    start = arm.commanded_group(robot)
    raised = arm.tuck_group(float(start[0]))
    raised[2] = arm.UNTUCK_LIFT
    path = arm.plan_through(planner, [start, raised, arm.tuck_group(float(start[0]))], gripper=gripper)
    if path is None:
        return None
    return (yield from arm.follow_path(world, path, gripper=gripper))


def _swing_frame(door: Door) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of the closed leaf (hinge -> free edge) and of its swing-side normal."""
    u = np.array([math.cos(door.closed_yaw), math.sin(door.closed_yaw)])
    n = door.open_sign * np.array([-u[1], u[0]])
    return u, n


def _rotate_about(p: np.ndarray, centre: np.ndarray, ang: float) -> np.ndarray:
    c, s = math.cos(ang), math.sin(ang)
    d = p - centre
    return centre + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])


def door_stances(door: Door, q: float = 0.0) -> list[tuple[float, float, float]]:
    """Candidate grasp stances (x, y, yaw) for the door at hinge angle q, preferred first."""
    u, n = _swing_frame(door)
    handle = door_handle_world(door, 0.0, door.open_sign)[:2]
    yaw = math.atan2(-n[1], -n[0])
    out = []
    for dist, shift in STANCES:
        p = _rotate_about(handle + dist * n + shift * u, np.asarray(door.hinge), door.open_sign * q)
        out.append((float(p[0]), float(p[1]), wrap(yaw + door.open_sign * q)))
    return out


def _swing_is_free(world: object, door: Door, stance: tuple[float, float, float], q0: float, q1: float) -> bool:
    """True when the base stays on free floor while it turns about the hinge from q0 to q1."""
    grid = getattr(world, "nav", None)
    if grid is None:
        return True
    hinge = np.asarray(door.hinge)
    for q in np.linspace(0.0, q1 - q0, 12):
        p = _rotate_about(np.asarray(stance[:2]), hinge, door.open_sign * float(q))
        if not grid.is_free(float(p[0]), float(p[1])):
            return False
    return True


def _grasp_rotation(door: Door, q: float) -> np.ndarray:
    """World rotation of the gripper grasping the swing-side bar: approach into the leaf, fingers along it."""
    yaw = door.leaf_yaw(q)
    u = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    n = door.open_sign * np.array([-u[1], u[0], 0.0])
    x_axis = -n
    y_axis = u
    z_axis = np.cross(x_axis, y_axis)
    if z_axis[2] < 0:
        y_axis, z_axis = -y_axis, -z_axis
    return np.stack([x_axis, y_axis, z_axis], axis=1)


def _swing(
    world: object, door: Door, art: object, hold: np.ndarray, q_goal: float, max_steps: int
) -> Generator[np.ndarray, None, Moved]:
    """Turn the base about the hinge as one rigid body with the held leaf until the hinge is at
    `q_goal` and at rest: feed-forward rigid rotation (ramped over SWING_RAMP) plus pose feedback."""
    robot = world.robot  # type: ignore[attr-defined]
    dt = 1.0 / robot.cfg.control_hz
    hinge = np.asarray(door.hinge)
    x0, y0, yaw0 = robot.base_pose()
    p0 = np.array([x0, y0])
    q_ref = q_cmd = float(art.get_qpos()[0])  # type: ignore[attr-defined]
    steps = 0
    while True:
        if steps >= max_steps:
            return Moved(False, "timeout", steps)
        rate = SWING_RATE * min(1.0, (steps + 1) * dt / SWING_RAMP)
        q_cmd = min(q_cmd + rate * dt, q_goal)
        ang = door.open_sign * (q_cmd - q_ref)
        p_des = _rotate_about(p0, hinge, ang)
        x, y, yaw = robot.base_pose()
        w_ff = door.open_sign * (rate if q_cmd < q_goal else 0.0)
        rel = np.array([x, y]) - hinge
        v_world = w_ff * np.array([-rel[1], rel[0]]) + K_POSE * (p_des - [x, y])
        wz = w_ff + K_POSE * wrap(yaw0 + ang - yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        action = hold.copy()
        action[0:3] = (c * v_world[0] + s * v_world[1], -s * v_world[0] + c * v_world[1], wz)
        yield action
        steps += 1
        q = float(art.get_qpos()[0])  # type: ignore[attr-defined]
        if q_cmd - q > LOST_GRIP:
            return Moved(False, "lost_handle", steps)
        if q_cmd >= q_goal and q >= door.open_threshold and abs(float(art.get_qvel()[0])) < DOOR_REST_QVEL:  # type: ignore[attr-defined]
            return Moved(True, "", steps)


def open_door(world: object, call: object, spec: object) -> Generator[np.ndarray, None, SkillOutcome]:
    """The OpenDoor expert for `call.target` = "door:<i>" (see the module docstring)."""
    skill, target = call.skill, call.target  # type: ignore[attr-defined]
    robot = world.robot  # type: ignore[attr-defined]
    max_steps = int(robot.cfg.max_steps["OpenDoor"])
    dt = 1.0 / robot.cfg.control_hz
    i = int(target.partition(":")[2])
    door: Door = world.plan.doors[i]  # type: ignore[attr-defined]
    art = world.handles.doors[i]  # type: ignore[attr-defined]
    leaf = art.links[1]
    steps = 0

    def fail(reason: str) -> SkillOutcome:
        return SkillOutcome(skill, target, False, reason, steps)

    q_start = float(art.get_qpos()[0])
    q_goal = min(door.open_threshold + OPEN_MARGIN, door.max_angle - 0.02)
    if q_start >= door.open_threshold:
        ok = door_open_success(world, i)
        return SkillOutcome(skill, target, ok, "" if ok else "door_moving", 0)

    # 1. stance and grasp solution: the first stance whose swing is free and whose grasp is reachable
    rot = _grasp_rotation(door, q_start)
    handle = door_handle_world(door, q_start, door.open_sign)
    pre_point = handle - PREGRASP_BACK * rot[:, 0]
    plan_choice = None
    for stance in door_stances(door, q_start):
        if not _swing_is_free(world, door, stance, q_start, q_goal):
            continue
        planner = planner_at(world, stance)
        grasp = reach_ik(planner, handle, rot, GRASP_TORSO, REACH_REF)
        pre = None if grasp is None else near_ik(planner, pre_point, rot, grasp)
        if pre is not None:
            plan_choice = (stance, grasp, pre)
            break
    if plan_choice is None:
        return fail("no_grasp_stance")
    stance, q_grasp, q_pre = plan_choice

    # 2. drive to the stance (arm tucked)
    hold = robot.rest_action()
    moved = yield from approach_base(world, stance, hold, max_steps - steps)
    steps += moved.steps
    if not moved.success:
        return fail(moved.reason)

    # 3. arm: out of the tuck to the pre-grasp, straight in, close the fingers
    planner = planner_at(world)  # from where the base really stands
    q_grasp = near_ik(planner, handle, rot, q_grasp)
    q_pre = None if q_grasp is None else near_ik(planner, pre_point, rot, q_grasp)
    if q_grasp is None or q_pre is None:
        return fail("no_ik")
    path = arm.plan_through(planner, untuck_waypoints(arm.commanded_group(robot), q_pre), gripper=arm.GRIPPER_OPEN)
    if path is None:
        return fail("arm_plan_failed")
    steps += yield from arm.follow_path(world, path, gripper=arm.GRIPPER_OPEN)
    steps += yield from arm.follow_path(world, [q_pre, q_grasp], gripper=arm.GRIPPER_OPEN, speed_scale=0.4)
    if steps >= max_steps:
        return fail("timeout")
    leaf_entity = leaf.entity
    closed = arm_action(robot, q_grasp, gripper=0.0)
    touching = False
    for _ in range(8):
        yield closed
        steps += 1
        left, right = robot.finger_contacts()
        if leaf_entity in left and leaf_entity in right:
            touching = True
            break
    if not touching:
        return fail("grasp_failed")

    # 4. swing the base about the hinge as one rigid body with the leaf (the world holds the
    #    leaf in the closed gripper from the step both fingers touched it; opening lets go)
    swung = yield from _swing(world, door, art, closed, q_goal, max_steps - steps)
    steps += swung.steps
    if not swung.success:
        return fail(swung.reason)

    # 5. let go, back off, tuck
    released = closed.copy()
    released[11] = arm.GRIPPER_OPEN
    for _ in range(4):
        yield released
        steps += 1
    back = released.copy()
    back[0] = -BACK_OFF / 0.8
    for _ in range(int(round(0.8 / dt))):
        yield back
        steps += 1
    tucked = yield from tuck_arm(world, gripper=arm.GRIPPER_OPEN)
    if tucked is None:
        return fail("tuck_failed")
    steps += tucked
    ok = door_open_success(world, i)
    return SkillOutcome(skill, target, ok, "" if ok else "not_open", steps)
