"""Success tests of the skills (Habitat-style criteria, docs/SIMULATION_NOTES.md#success-tests), read from the live world.

Shared file: Pick/Place here; navigation, door and sink owners add theirs below.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.scene.objects import object_size
from echo_data.skill_table import Situation, carried_object, skill
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import SkillCall
    from echo_data.world import World

# ------------------------------------------------------------------ Pick / Place
LIFT_MIN = 0.05  # m: object bottom above its receptacle top for a pick
CARRY_TCP = (0.27, 0.0, 1.15)  # TCP in the base frame (x fwd, y left, z from floor) while carrying
CARRY_TOL = 0.12  # m: "arm back near rest" = TCP this close to CARRY_TCP
PLACE_HEIGHT_TOL = 0.02  # m: object bottom within this of the goal's top
REST_SPEED = 0.05  # m/s: an object slower than this is at rest


def object_bottom(world: World, name: str) -> float:
    """z of the lowest point of the object's collision box (upright objects)."""
    o = world.plan.object_by_name(name)
    p = world.handles.objects[name].pose
    return float(p.p[2]) - object_size(o.category, o.scale)[2] / 2.0


def receptacle_of(world: World, name: str) -> int:
    """Furniture index the object rests on (before a pick): the world's record, else the plan's."""
    return int(world.receptacles.get(name, world.plan.object_by_name(name).receptacle))


def tcp_in_base(world: World) -> np.ndarray:
    """TCP position in the base frame (x forward, y left, z above the floor)."""
    x, y, yaw = world.robot.base_pose()
    p = np.asarray(world.robot.ee_pose().p, dtype=np.float64)
    dx, dy = p[0] - x, p[1] - y
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * dx + s * dy, -s * dx + c * dy, p[2]])


def arm_at_carry(world: World) -> bool:
    return bool(np.linalg.norm(tcp_in_base(world) - np.asarray(CARRY_TCP)) <= CARRY_TOL)


def pick_success(world: World, name: str) -> bool:
    """Held between both fingers, bottom >= LIFT_MIN above its receptacle's top, arm at the carry pose."""
    if world.robot.holding != name:
        return False
    top = world.plan.furniture[receptacle_of(world, name)].top_z
    return object_bottom(world, name) >= top + LIFT_MIN and arm_at_carry(world)


def object_speed(world: World, name: str) -> float:
    import sapien

    body = world.handles.objects[name].find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
    return float(np.linalg.norm(body.linear_velocity))


def place_success(world: World, name: str, goal_furniture: int) -> bool:
    """At rest on the goal receptacle: bottom within PLACE_HEIGHT_TOL of its top, centre inside its footprint, not held."""
    f = world.plan.furniture[goal_furniture]
    p = world.handles.objects[name].pose.p
    on_top = abs(object_bottom(world, name) - f.top_z) <= PLACE_HEIGHT_TOL
    inside = f.footprint.contains(float(p[0]), float(p[1]))
    return bool(on_top and inside and world.robot.holding != name and object_speed(world, name) < REST_SPEED)


# ------------------------------------------------------------------ Navigate
NAV_SUCCESS_DIST = 1.5  # m from the target's interaction point (Habitat's criterion, docs/SIMULATION_NOTES.md#success-tests)
NAV_SUCCESS_YAW = math.radians(15)  # base heading vs the bearing to the target


def _interaction(world: World, target: str, grid: Any, poses: dict[Any, Any] | None) -> tuple[Any, tuple[float, ...] | None]:
    """The navigation grid at the doors' current angles (`grid` when given) and `target`'s
    interaction pose and point (px, py, pyaw, tx, ty) with the doors where they stand, None when
    no free pose exists. `poses`: a dict the caller keeps per episode, in which both are kept per
    (target, door angles, grid) (they are functions of the plan and those alone)."""
    from echo_data.scene.nav import NavGrid, interaction_pose, target_point

    plan = world.plan
    angles = world.handles.door_angles()
    if grid is None:
        grid = NavGrid.from_plan(plan, robot_radius=world.nav.robot_radius, door_angles=angles)
    key = (target, tuple(sorted(angles.items())), id(grid))
    if poses is not None and key in poses:
        return grid, poses[key]
    try:
        stand = interaction_pose(plan, target, door_angles=angles or None, grid=grid)
        hit: tuple[float, ...] | None = (*stand, *target_point(plan, target, angles or None))
    except ValueError:  # no free interaction pose: never a success, never a hand-over
        hit = None
    if poses is not None:
        if len(poses) > 4096:  # a swinging door gives new angles every step
            poses.clear()
        poses[key] = hit
    return grid, hit


def navigate_success(world: World, target: str, grid: Any = None, poses: dict[Any, Any] | None = None) -> bool:
    """Base within NAV_SUCCESS_DIST of the target's interaction point and facing the target.

    Facing: the base heading points at the target (object centre, swing-side door handle,
    faucet lever, furniture centre) within NAV_SUCCESS_YAW. Doors count where they stand now.
    `grid`: a NavGrid of the doors' current angles to reuse (the test is then cheap per step);
    `poses`: a dict the caller keeps per episode (see `_interaction`).
    """
    _, hit = _interaction(world, target, grid, poses)
    if hit is None:
        return False
    px, py, _, tx, ty = hit
    x, y, yaw = world.robot.base_pose()
    heading_error = abs(math.remainder(math.atan2(ty - y, tx - x) - yaw, 2.0 * math.pi))
    return math.hypot(px - x, py - y) <= NAV_SUCCESS_DIST and heading_error <= NAV_SUCCESS_YAW


def stance_offset(world: World, target: str, grid: Any = None, poses: dict[Any, Any] | None = None) -> tuple[float, float] | None:
    """How far the base stands from `target`'s interaction pose: distance (m) and heading error
    (rad, wrapped to [0, pi]) against the pose's heading; None when the target has no free pose."""
    _, hit = _interaction(world, target, grid, poses)
    if hit is None:
        return None
    return pose_offset(world.robot.base_pose(), hit[:3])


def pose_offset(base: Sequence[float], pose: Sequence[float]) -> tuple[float, float]:
    """A base pose (x, y, yaw) against an interaction pose: distance (m) and heading error (rad,
    wrapped to [0, pi]). The stance test's measure, here and on a dataset's rows (`learn.carry`)."""
    return math.hypot(pose[0] - base[0], pose[1] - base[1]), abs(math.remainder(base[2] - pose[2], 2.0 * math.pi))


def inside(offset: tuple[float, float], distance: float, heading: float) -> bool:
    """An offset (`pose_offset`) inside a stance of `distance` m and `heading` rad."""
    return offset[0] <= distance and offset[1] <= heading


def handed_over(world: World, target: str, distance: float, heading: float, grid: Any = None,
                poses: dict[Any, Any] | None = None) -> bool:
    """The base inside a stance (`skill_table.HandOver`) of `target`: within `distance` m of
    its interaction pose and `heading` rad of that pose's heading."""
    off = stance_offset(world, target, grid, poses)
    return off is not None and inside(off, distance, heading)


def in_stance(world: World, call: SkillCall, at: Situation, fraction: float = 1.0) -> bool:
    """The base inside the stance of `call` (its skill's `stance` about its target's interaction
    pose, doors where they stand now, `skill_table.HandOver`), or inside `fraction` of it (its
    distance and heading both); False for a skill without one."""
    st = skill(call.skill).stance
    return st is not None and handed_over(world, call.target, st.distance * fraction, st.heading * fraction, grid=at.nav_grid(), poses=at.poses)


# ------------------------------------------------------------------ OpenDoor / CloseSink
DOOR_REST_QVEL = 0.05  # rad/s: a door whose hinge turns slower than this is at rest


def door_open_success(world: World, i: int) -> bool:
    """Door i's hinge angle is at least its `open_threshold` and the leaf is at rest (docs/SIMULATION_NOTES.md#success-tests)."""
    door = world.plan.doors[i]
    art = world.handles.doors[i]
    return float(art.get_qpos()[0]) >= door.open_threshold and abs(float(art.get_qvel()[0])) < DOOR_REST_QVEL


def sink_closed_success(world: World, i: int) -> bool:
    """Faucet i's lever is within its `closed_tolerance` of 0 and its water stream is off (docs/SIMULATION_NOTES.md#success-tests)."""
    faucet = world.plan.faucets[i]
    angle = float(world.handles.faucets[i].get_qpos()[0])
    stream = world.handles.water[i]
    stream.update(angle)
    return angle <= faucet.closed_tolerance and not stream.flowing


# ------------------------------------------------------------------ as the skill table calls them
# `echo_data.skill_table` names these "module:function" (it imports nothing above the vocabulary).


def navigated(world: World, call: SkillCall, at: Situation) -> bool:
    return navigate_success(world, call.target, grid=at.nav_grid(), poses=at.poses)


def picked(world: World, call: SkillCall, at: Situation) -> bool:
    return pick_success(world, call.target)


def placed(world: World, call: SkillCall, at: Situation) -> bool:
    name = carried_object(at.spec, call)
    return name is not None and place_success(world, name, Target.parse(call.target).index)


def door_opened(world: World, call: SkillCall, at: Situation) -> bool:
    return door_open_success(world, Target.parse(call.target).index)


def sink_closed(world: World, call: SkillCall, at: Situation) -> bool:
    return sink_closed_success(world, Target.parse(call.target).index)
