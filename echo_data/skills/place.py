"""The Place expert: carry the held object to another receptacle, set it down, let go, tuck.

`call.target` is "furniture:<i>". The base drives to that piece's interaction pose with the
navigation follower (`echo_data.skills.navigate.drive_to`) while the arm holds the object in a
carry pose that keeps the head camera clear (the hand raised beside the head on its right: every
arm link origin within 0.31 m of the base centre, so turning beside a wall does not sweep the elbow
into it the way READY's elbow, 0.47 m out, does; the object hangs higher than READY holds it, above
every receptacle), reached from READY by one straight joint move along which the hand keeps
pointing down (the pinch grasp does not let the object pivot), back to READY on arrival (READY
when the fold is blocked); then a free spot on the top within reach is
chosen, the object is brought above it, lowered until its bottom is RELEASE_GAP above the top,
released, and the arm retreats up and tucks (the torso stays up; Navigate does not mind).
Step limits: the drive may use max_steps["Navigate"], the arm work max_steps["Place"];
`SkillOutcome.steps` counts both.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING

import numpy as np

from echo_data.records import SkillOutcome
from echo_data.robot.robot import GRIPPER_OPEN
from echo_data.scene.objects import object_size
from echo_data.skills import arm
from echo_data.skills.budget import Budget, SkillFailed
from echo_data.skills.success import object_bottom, place_success
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

ABOVE = 0.08  # m: object bottom above the top before the final descent
RELEASE_GAP = 0.012  # m: object bottom above the top when the fingers open (drops the rest)
RETREAT = 0.12  # m straight up after releasing
OPEN_STEPS = 6
EDGE_MARGIN = 0.06  # m: object footprint to the top's edges
CLEARANCE = 0.05  # m: object footprint to other objects
REACH = (0.45, 0.74)  # m: base centre to the placing point
PREFERRED_REACH = 0.6
GRID = 0.03  # m
TUCK_SPEED = 1.4  # speed scale of the empty-handed tuck (1.8 rad/s, within Fetch's joint limits)
# Carry for driving, out of the head camera's view: TCP at (0.21, -0.14, 1.25) in the base frame,
# pointing down (READY holds it at (0.27, 0, 1.15), where hand and object fill 74 % of the head
# view; here 0-7 % depending on the object, benchmarks/carry_view.py). Found once
# (benchmarks/carry_search.py) by growing a tree of hand-down configurations from READY with
# ArmPlanner.ik, keeping moves whose joint-space interpolation tilts the hand < 4 deg and is
# collision-free, and shortcutting to the nearest node covering < 1 % with arm link origins
# within 0.36 m of the base axis: the straight joint segment from READY tilts the hand <= 3 deg.
CARRY_DRIVE_GROUP = np.array([0.386, 0.679, -1.098, -2.373, 1.701, 0.33, 1.781, 1.144])


def held_object(world: World, call: SkillCall, spec: EpisodeSpec) -> str | None:
    """The object to place: what the robot holds, else the event's target object."""
    name = world.robot.holding
    if name is not None:
        return name
    try:
        return spec.events[call.event].target
    except (AttributeError, IndexError):
        return None


def place_spots(world: World, name: str, furniture: int) -> list[tuple[float, float]]:
    """Free points on the top of `furniture` within reach of the base, best first."""
    plan = world.plan
    f = plan.furniture[furniture]
    o = plan.object_by_name(name)
    sx, sy, _ = object_size(o.category, o.scale)
    r = math.hypot(sx, sy) / 2.0
    fp = f.footprint
    bx, by, byaw = world.robot.base_pose()
    others = []
    for other in plan.objects:
        if other.name == name or other.name not in world.handles.objects:
            continue
        p = world.handles.objects[other.name].pose.p
        osx, osy, _ = object_size(other.category, other.scale)
        others.append((float(p[0]), float(p[1]), math.hypot(osx, osy) / 2.0))
    spots = []
    m = EDGE_MARGIN + r
    for x in np.arange(fp.xmin + m, fp.xmax - m + 1e-9, GRID):
        for y in np.arange(fp.ymin + m, fp.ymax - m + 1e-9, GRID):
            d = math.hypot(x - bx, y - by)
            if not REACH[0] <= d <= REACH[1]:
                continue
            if any(math.hypot(x - ox, y - oy) < r + orad + CLEARANCE for ox, oy, orad in others):
                continue
            bearing = abs(math.remainder(math.atan2(y - by, x - bx) - byaw, 2 * math.pi))
            spots.append((abs(d - PREFERRED_REACH) + 0.4 * bearing, float(x), float(y)))
    spots.sort()
    return [(x, y) for _, x, y in spots]


def place(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """Place expert (generator of actions; returns the SkillOutcome)."""
    robot = world.robot
    # Place includes a drive across the apartment: the drive gets Navigate's step limit, the
    # arm work Place's own.
    drive_budget = Budget(int(robot.cfg.max_steps["Navigate"]))
    budget = Budget(int(robot.cfg.max_steps["Place"]))
    try:
        tgt = Target.parse(call.target)
    except ValueError:
        tgt = Target.object("")
    if tgt.kind != "furniture":
        return SkillOutcome(call.skill, call.target, False, "bad target", 0)
    goal = tgt.index
    name = held_object(world, call, spec)
    if name is None or robot.holding != name:
        return SkillOutcome(call.skill, call.target, False, "not holding", 0)
    try:
        yield from drive_budget.run(_drive(world, goal, drive_budget))
        yield from budget.run(_place(world, name, goal))
        yield from budget.run(arm.hold(world, 3))
    except SkillFailed as e:
        return SkillOutcome(call.skill, call.target, False, str(e), drive_budget.steps + budget.steps)
    ok = place_success(world, name, goal)
    if ok:
        world.receptacles[name] = goal
    reason = "" if ok else ("still held" if robot.holding == name else "not on goal")
    return SkillOutcome(call.skill, call.target, ok, reason, drive_budget.steps + budget.steps)


def _drive(world: World, goal: int, budget: Budget) -> Generator[np.ndarray, None, None]:
    from echo_data.scene.nav import interaction_pose
    from echo_data.skills.navigate import current_grid, door_angles, drive_to

    grid = current_grid(world)
    try:
        pose = interaction_pose(world.plan, str(Target.furniture(goal)), door_angles=door_angles(world) or None, grid=grid)
    except ValueError:
        raise SkillFailed("no_path") from None
    name = world.robot.holding
    folded = name is not None and (yield from _fold(world, name, CARRY_DRIVE_GROUP, straight=True))
    result = yield from drive_to(world, pose, budget.max_steps - budget.steps, grid=grid, hold=world.robot.rest_action())
    if not result.success:
        raise SkillFailed(result.reason)
    if folded and name is not None:
        yield from _fold(world, name, arm.READY_GROUP)


def _fold(world: World, name: str, goal: np.ndarray, straight: bool = False) -> Generator[np.ndarray, None, bool]:
    """Move the arm, object in hand, to `goal` (torso + arm) on a collision-free path; False if none.

    With `straight`, only the straight joint segment is accepted: a detour found by the planner
    may tilt the hand and let the object pivot in the pinch grasp.
    """
    robot = world.robot
    o = world.plan.object_by_name(name)
    tcp_to_obj = robot.ee_pose().inv() * world.handles.objects[name].pose
    planner = arm.arm_planner(world, exclude={name})
    planner.attach_box(list(object_size(o.category, o.scale)), tcp_to_obj)
    start, end = arm.commanded_group(robot), np.asarray(goal, dtype=np.float64)
    if straight:
        path = [start, end] if planner.segment_free(start, end) else None
    else:
        path = planner.path(start, end)
    planner.detach()
    if path is None:
        return False
    yield from arm.follow_path(world, path)
    return True


def _place(world: World, name: str, goal: int) -> Generator[np.ndarray, None, None]:
    robot = world.robot
    plan = world.plan
    top = plan.furniture[goal].top_z
    o = plan.object_by_name(name)
    sx, sy, sz = object_size(o.category, o.scale)
    tcp = robot.ee_pose()
    tcp_above_bottom = float(tcp.p[2]) - object_bottom(world, name)
    tcp_to_obj = tcp.inv() * world.handles.objects[name].pose
    # keep the object's current yaw relative to the jaws: try the current jaw direction first
    jaw = arm.jaw_yaw(tcp)
    planner = arm.arm_planner(world, exclude={name})
    planner.attach_box([sx, sy, sz], tcp_to_obj)
    start = arm.commanded_group(robot)
    chosen = None
    for x, y in place_spots(world, name, goal)[:12]:
        options = []
        for yaw in (jaw, jaw + math.pi, jaw + math.pi / 2, jaw - math.pi / 2):
            above = arm.top_down_pose(x, y, top + ABOVE + tcp_above_bottom, yaw)
            q_above = planner.ik(above, start, tries=8)
            if q_above is None:
                continue
            down = arm.top_down_pose(x, y, top + RELEASE_GAP + tcp_above_bottom, yaw)
            descent = arm.cartesian_path(planner, q_above, arm.line_poses(above, down))
            if descent is not None:
                options.append((float(np.max(np.abs(q_above[1:] - start[1:]))), q_above, descent, down))
        for _, q_above, descent, down in sorted(options, key=lambda t: t[0]):
            path = planner.path(start, q_above)
            if path is not None:
                chosen = (path, descent, down)
                break
        if chosen is not None:
            break
    planner.detach()
    if chosen is None:
        raise SkillFailed("no IK solution")
    path, descent, down = chosen
    yield from arm.follow_path(world, path)
    if robot.holding != name:
        raise SkillFailed("grasp slipped")
    yield from arm.hold(world, 2)  # let a swinging object come to rest before going down
    yield from arm.follow_path(world, descent, speed_scale=arm.SLOW)
    yield from arm.set_gripper(world, GRIPPER_OPEN, OPEN_STEPS)
    up = arm.top_down_pose(float(down.p[0]), float(down.p[1]), float(down.p[2]) + RETREAT, arm.jaw_yaw(down))
    retreat = arm.cartesian_path(planner, descent[-1], arm.line_poses(down, up), gripper=GRIPPER_OPEN)
    if retreat is None:
        raise SkillFailed("no IK solution")
    yield from arm.follow_path(world, retreat, gripper=GRIPPER_OPEN, speed_scale=arm.SLOW)
    planner = arm.arm_planner(world)
    home = arm.plan_through(planner, arm.tuck_waypoints(np.asarray(retreat[-1])), gripper=GRIPPER_OPEN)
    if home is None:
        raise SkillFailed("no motion plan")
    yield from arm.follow_path(world, home, gripper=GRIPPER_OPEN, speed_scale=TUCK_SPEED, settle=False)


__all__ = ["place", "place_spots", "held_object"]
