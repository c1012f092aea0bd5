"""The Pick expert: a physical top-down parallel-jaw grasp, lift, and carry pose.

Starts where Navigate left the base (facing the object at its interaction pose). Steps:
raise the torso while the arm leaves the tuck (a collision-checked joint path, RRTConnect only
if the straight path hits something), stop 0.12 m above the object with the jaws across its
narrow side, descend in a straight line, close, lift 0.15 m straight up, then bring the object
to the carry pose above the front of the base (`success.CARRY_TCP`). Nothing is welded or
teleported: the object stays in the hand by friction alone.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING

import numpy as np

from echo_data.records import SkillOutcome
from echo_data.robot.robot import GRIPPER_OPEN, yaw_of
from echo_data.scene.objects import object_size
from echo_data.skills import arm
from echo_data.skills.budget import Budget, SkillFailed
from echo_data.skills.success import object_bottom, pick_success

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

PRE_GRASP_HEIGHT = 0.12  # m above the grasp point
LIFT_HEIGHT = 0.15  # m
GRASP_BELOW_TOP = 0.03  # m: pads centred this far below the object's top ...
GRASP_ABOVE_BOTTOM = 0.010  # ... but the TCP at least this high above its bottom (tips clear the table)
CLOSE_STEPS = 8


def grasp_height(bottom: float, sz: float) -> float:
    """TCP z for a top-down grasp of an object of height sz standing at `bottom`."""
    return max(bottom + GRASP_ABOVE_BOTTOM, bottom + sz - GRASP_BELOW_TOP)


def pick(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """Pick expert (generator of actions; returns the SkillOutcome)."""
    robot = world.robot
    budget = Budget(int(robot.cfg.max_steps["Pick"]))
    name = call.target
    try:
        yield from budget.run(_pick(world, name, budget))
        yield from budget.run(arm.hold(world, 3))
    except SkillFailed as e:
        return SkillOutcome(call.skill, name, False, str(e), budget.steps)
    ok = pick_success(world, name)
    reason = ""
    if not ok:
        reason = "grasp slipped" if robot.holding != name else "not lifted"
    return SkillOutcome(call.skill, name, ok, reason, budget.steps)


def _pick(world: World, name: str, budget: Budget) -> Generator[np.ndarray, None, None]:
    robot = world.robot
    plan = world.plan
    obj = plan.object_by_name(name)
    sx, sy, sz = object_size(obj.category, obj.scale)
    pose = world.handles.objects[name].pose
    ox, oy = float(pose.p[0]), float(pose.p[1])
    oyaw = yaw_of(pose)
    bottom = object_bottom(world, name)
    gz = grasp_height(bottom, sz)

    best = _grasp_plan(world, name, ox, oy, oyaw, gz)
    if best is None:
        # out of reach from where Navigate stopped: step the base towards the object, retry
        moved = yield from _approach(world, ox, oy)
        if moved:
            best = _grasp_plan(world, name, ox, oy, oyaw, gz)
    if best is None:
        raise SkillFailed("no IK solution")
    planner = arm.arm_planner(world, exclude={name})
    start = arm.commanded_group(robot)
    untuck = arm.untuck_waypoints(start)
    _, pre, descent, yaw = best
    path = arm.plan_through(planner, untuck + [pre], gripper=GRIPPER_OPEN)
    if path is None:
        raise SkillFailed("no motion plan")
    yield from arm.follow_path(world, path, gripper=GRIPPER_OPEN)
    yield from arm.follow_path(world, list(descent), gripper=GRIPPER_OPEN, speed_scale=arm.SLOW)
    yield from arm.set_gripper(world, 0.0, CLOSE_STEPS)
    if robot.holding != name:
        raise SkillFailed("grasp missed")
    here = descent[-1]
    grasp_pose = planner.fk(here)
    lift_to = arm.top_down_pose(float(grasp_pose.p[0]), float(grasp_pose.p[1]), float(grasp_pose.p[2]) + LIFT_HEIGHT, yaw)
    lift = arm.cartesian_path(planner, here, arm.line_poses(grasp_pose, lift_to))
    if lift is None:
        raise SkillFailed("no IK solution")
    yield from arm.follow_path(world, lift, speed_scale=arm.SLOW)
    if robot.holding != name:
        raise SkillFailed("grasp slipped")
    # carry: back to READY with the object attached (as a box) where it hangs now
    tcp_to_obj = robot.ee_pose().inv() * world.handles.objects[name].pose
    planner = arm.arm_planner(world, exclude={name})
    planner.attach_box([sx, sy, sz], tcp_to_obj)
    carry = planner.path(np.asarray(lift[-1]), arm.READY_GROUP.copy())
    planner.detach()
    if carry is None:
        raise SkillFailed("no motion plan")
    yield from arm.follow_path(world, carry, speed_scale=0.6)
    if robot.holding != name:
        raise SkillFailed("grasp slipped")


def _grasp_plan(world: World, name: str, ox: float, oy: float, oyaw: float, gz: float) -> tuple[float, np.ndarray, np.ndarray, float] | None:
    """(cost, pre-grasp q, descent path, jaw yaw) of the cheapest top-down grasp from here."""
    planner = arm.arm_planner(world, exclude={name})
    ready = arm.untuck_waypoints(arm.commanded_group(world.robot))[-1]
    best: tuple[float, np.ndarray, np.ndarray, float] | None = None
    for yaw in (oyaw, oyaw + math.pi):
        above = arm.top_down_pose(ox, oy, gz + PRE_GRASP_HEIGHT, yaw)
        pre = planner.ik(above, ready, tries=16, gripper=GRIPPER_OPEN)
        if pre is None:
            continue
        descent = arm.cartesian_path(planner, pre, arm.line_poses(above, arm.top_down_pose(ox, oy, gz, yaw)))
        if descent is None:
            continue
        cost = float(np.max(np.abs(pre[1:] - ready[1:])))
        if best is None or cost < best[0]:
            best = (cost, pre, np.asarray(descent), yaw)
    return best


APPROACH_DISTANCES = (0.6, 0.65, 0.7, 0.55)  # m, base centre to object for a retry stance
APPROACH_SPEED = 0.25  # m/s
APPROACH_TURN = 0.8  # rad/s


def _approach(world: World, ox: float, oy: float) -> Generator[np.ndarray, None, bool]:
    """Drive the base (holonomic, straight) to a free stance facing the object; False if none."""
    robot = world.robot
    x, y, _ = robot.base_pose()
    d = math.hypot(ox - x, oy - y)
    if d < 1e-6:
        return False
    ux, uy = (ox - x) / d, (oy - y) / d
    grid = world.nav
    goal = None
    for dist in APPROACH_DISTANCES:
        gx, gy = ox - ux * dist, oy - uy * dist
        steps = max(2, int(math.hypot(gx - x, gy - y) / 0.05))
        if all(grid.is_free(x + (gx - x) * t, y + (gy - y) * t) for t in np.linspace(0.0, 1.0, steps)):
            goal = (gx, gy, math.atan2(uy, ux))
            break
    if goal is None or math.hypot(goal[0] - x, goal[1] - y) < 0.02:
        return False
    dt = 1.0 / robot.cfg.control_hz
    for _ in range(int(4.0 / dt)):
        x, y, yaw = robot.base_pose()
        ex, ey = goal[0] - x, goal[1] - y
        eyaw = math.remainder(goal[2] - yaw, 2 * math.pi)
        if math.hypot(ex, ey) < 0.01 and abs(eyaw) < 0.02:
            break
        c, s_ = math.cos(yaw), math.sin(yaw)
        vx, vy = c * ex + s_ * ey, -s_ * ex + c * ey
        scale = min(1.0, APPROACH_SPEED / max(math.hypot(vx, vy) / dt * 0.5, 1e-9))
        a = robot.rest_action()
        a[0], a[1] = vx / dt * 0.5 * scale, vy / dt * 0.5 * scale
        a[2] = float(np.clip(eyaw / dt * 0.5, -APPROACH_TURN, APPROACH_TURN))
        yield a
    yield robot.rest_action()
    return True
