"""The OpenDoor expert: grasp the door handle, swing the base about the hinge, let go.

Where it wants to start: on the door's swing side (the side the leaf opens towards), facing
the closed leaf, roughly in front of the handle — `interaction_pose(plan, "door:<i>")` of
`echo_data.scene.nav` (0.8 m from the leaf, facing the swing-side handle) is fine. The
expert first drives the base itself (holonomic, a few decimetres at most) to its grasp
stance: 0.88 m from the swing-side handle bar along the leaf normal and 0.3 m towards the
hinge, facing the leaf — the first of `STANCES` whose whole swing stays on free floor and
whose grasp the arm reaches.

Then (docs/SIMULATION_NOTES.md#door-opening): reach a pre-grasp 7 cm in front of the bar with a
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
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.records import SkillOutcome
from echo_data.scene.door_handle import door_handle_world
from echo_data.scene.floorplan import Door
from echo_data.skills import arm
from echo_data.skills.reach import (
    Moved,
    approach_base,
    arm_action,
    near_ik,
    planner_at,
    reach_ik,
    tuck_arm,
    untuck_waypoints,
    wrap,
)
from echo_data.skills.success import DOOR_REST_QVEL, door_open_success
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

# Grasp stances, preferred first: (distance from the bar along the leaf normal, shift along the
# leaf towards its free edge). Standing 0.3 m towards the hinge keeps the swing radius small
# (≈1.2 m) and the arm well inside its limits (a head-on reach at < 0.9 m needs the shoulder
# beyond its lift limit).
STANCES = ((0.88, -0.3), (0.95, -0.3), (0.88, -0.15), (0.95, -0.15), (0.95, 0.0), (0.8, -0.3))
PREGRASP_BACK = 0.07  # m, pre-grasp in front of the bar (4 cm clear of the open fingers)
GRASP_TORSO = 0.15  # m, preferred torso height for a handle at ≈1 m
SWING_RATE = 0.35  # rad/s hinge rate while the base swings
SWING_RAMP = 1.0  # s, velocity ramp at the start of the swing (docs/SIMULATION_NOTES.md#door-opening)
K_POSE = 2.0  # 1/s, base pose feedback during the swing
OPEN_MARGIN = 0.12  # rad beyond the open threshold before letting go
LOST_GRIP = 0.35  # rad between commanded and measured hinge angle: the handle slipped
BACK_OFF = 0.15  # m the base backs away after letting go
REACH_REF = np.array([0.0, -1.0, 0.0, 1.6, 0.0, -0.6, 0.0])  # arm bent forward: IK reference


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


def _swing_is_free(world: World, door: Door, stance: tuple[float, float, float], q0: float, q1: float) -> bool:
    """True when the base stays on free floor while it turns about the hinge from q0 to q1."""
    grid = world.nav
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
    world: World, door: Door, art: Any, hold: np.ndarray, q_goal: float, max_steps: int
) -> Generator[np.ndarray, None, Moved]:
    """Turn the base about the hinge as one rigid body with the held leaf until the hinge is at
    `q_goal` and at rest: feed-forward rigid rotation (ramped over SWING_RAMP) plus pose feedback."""
    robot = world.robot
    dt = 1.0 / robot.cfg.control_hz
    hinge = np.asarray(door.hinge)
    x0, y0, yaw0 = robot.base_pose()
    p0 = np.array([x0, y0])
    q_ref = q_cmd = float(art.get_qpos()[0])
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
        q = float(art.get_qpos()[0])
        if q_cmd - q > LOST_GRIP:
            return Moved(False, "lost_handle", steps)
        if q_cmd >= q_goal and q >= door.open_threshold and abs(float(art.get_qvel()[0])) < DOOR_REST_QVEL:
            return Moved(True, "", steps)


def open_door(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """The OpenDoor expert for `call.target` = "door:<i>" (see the module docstring)."""
    skill, target = call.skill, call.target
    robot = world.robot
    max_steps = int(robot.cfg.max_steps["OpenDoor"])
    dt = 1.0 / robot.cfg.control_hz
    i = Target.parse(target).index
    door: Door = world.plan.doors[i]
    art = world.handles.doors[i]
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
        if grasp is not None and pre is not None:
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
    q_near = near_ik(planner, handle, rot, q_grasp)
    q_back = None if q_near is None else near_ik(planner, pre_point, rot, q_near)
    if q_near is None or q_back is None:
        return fail("no_ik")
    q_grasp, q_pre = q_near, q_back
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
