"""The Place expert: carry the held object to another receptacle, set it down, let go, tuck.

A closed-loop controller in end-effector space (`echo_data.skills.servo`), like Pick: every
command comes from the state at its step. `call.target` is "furniture:<i>". Phases:

1. fold: the hand, object in it, to the carry pose beside the head (`pick.APPROACH_TCP`, the TCP of
   CARRY_DRIVE_GROUP; the arm's shape there is the ee map's, see pick.py);
2. drive: the navigation follower (`echo_data.skills.navigate.drive_to`) to the piece's
   interaction pose, its base velocities issued as `action.ee` with the arm held;
3. choose a free spot on the top within reach (`place_spots`, the first the arm's IK reaches);
4. lower: the object above the spot, then down until its bottom is level with the top (the
   goal from the spot and the object's pose in the hand, read above the spot); leaning more
   than UPRIGHT_TOL there (caught mid-swing), it is lifted and lowered again (SET_DOWN_TRIES);
5. open, retreat straight up, tuck (TCP poses along the joint path READY -> raised -> tuck,
   ending in a compact fold; the torso stays up, Navigate does not mind).

Step limits: the fold and drive may use max_steps["Navigate"], the arm work max_steps["Place"];
`SkillOutcome.steps` counts both.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING

import numpy as np

from echo_data.records import SkillOutcome
from echo_data.scene.objects import object_size
from echo_data.skill_table import approach_skill
from echo_data.skills import servo as S
from echo_data.skills.budget import Budget, SkillFailed
from echo_data.skills.pick import (
    APPROACH_JAW,
    APPROACH_TCP,
    CARRY_ACCEL,
    commanded_pose,
    drive_path,
    fixed_in_base,
    in_world_fixed,
    reach_cost,
)
from echo_data.skills.servo import jaw_yaw, top_down
from echo_data.skills.success import object_bottom, place_success
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

ABOVE = 0.08  # m: object bottom above the top before the final descent
# m: object bottom over the top when the fingers open: level with it. A round object swings in the
# pinch (the furby +-40-60 deg about the jaw axis, pads 3 cm above its centre of mass); lowered to
# 1.2 cm above the top, its foot (6 x 5 cm, narrower than its body) caught the top mid-swing and
# wedged it leaning 31-36 deg, and let go there it fell over (7 of 100 episodes). Lowered until
# the foot is level with the top, the top stops the swing with the foot flat (the pendulum's
# lowest pose): 0 falls in the same 100 (docs/manipulation_experts.md).
RELEASE_GAP = 0.0
RETREAT = 0.12  # m straight up after releasing
OPEN_STEPS = 6
EDGE_MARGIN = 0.06  # m: object footprint to the top's edges
CLEARANCE = 0.05  # m: object footprint to other objects
REACH = (0.45, 0.74)  # m: base centre to the placing point
PREFERRED_REACH = 0.6
GRID = 0.03  # m
SPOTS_TRIED = 12
LOWER_STEPS = 40
TOUCH_GAP = 0.015  # m: the object's bottom (as if upright) this near the top ...
STALL_DROP = 0.001  # m: ... and it moved less than this ...
STALL_TURN = math.radians(1.0)  # ... and turned less than this in a control step ...
STALL_STEPS = 3  # ... this many steps running: it rests on the top
STEADY_STEPS = 20  # at most this long held above the spot and before opening: a swinging object comes to rest
UPRIGHT_TOL = math.radians(8.0)  # rad: the held object's axis from the vertical, above which it is not let go
SET_DOWN_TRIES = 3  # lowerings onto the top, each followed by a lift to RETRY_ABOVE if the object leans
RETRY_ABOVE = 0.04  # m: object bottom over the top after a lowering that left it leaning
# The arm configuration whose TCP is the carry pose (pick.APPROACH_TCP, APPROACH_JAW): found once
# (the carry-search study) with hand and object covering 0-7 % of the head view against READY's
# 74 % (tests/test_carry_pose.py measures both), every arm link origin within 0.36 m of the base axis.
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
    """Place expert (generator of `action.ee`; returns the SkillOutcome)."""
    robot = world.robot
    # Place includes a drive across the apartment: the drive gets Navigate's step limit, the
    # arm work Place's own.
    drive_budget = Budget(int(robot.cfg.max_steps[approach_skill().name]))
    budget = Budget(int(robot.cfg.max_steps[call.skill]))
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
        yield from drive_budget.run(_drive(world, goal))
        yield from budget.run(_place(world, name, goal))
    except SkillFailed as e:
        return SkillOutcome(call.skill, call.target, False, str(e), drive_budget.steps + budget.steps)
    ok = place_success(world, name, goal)
    if ok:
        world.receptacles[name] = goal
    reason = "" if ok else ("still held" if robot.holding == name else "not on goal")
    return SkillOutcome(call.skill, call.target, ok, reason, drive_budget.steps + budget.steps)


def _drive(world: World, goal: int) -> Generator[np.ndarray, None, None]:
    from echo_data.scene.nav import interaction_pose
    from echo_data.skills.navigate import current_grid, door_angles

    grid = current_grid(world)
    try:
        pose = interaction_pose(world.plan, str(Target.furniture(goal)), door_angles=door_angles(world) or None, grid=grid)
    except ValueError:
        raise SkillFailed("no_path") from None
    carry = fixed_in_base(world, APPROACH_TCP, APPROACH_JAW)
    yield from S.servo(world, carry, max_steps=40, close=True, accel=CARRY_ACCEL)
    yield from drive_path(world, pose, carry)


class Spot:
    """The TCP pose that puts the held object, as it sits in the hand, over a spot on a top.

    The object's offset in the hand is read by `feel()` (at the start and again once the object
    has settled above the spot), not at every step: an object pivoting in the pinch would
    otherwise make the goal chase its swing (measured on a furby: +-3 cm at 10 Hz, never settling).
    """

    def __init__(self, world: World, name: str, top: float, x: float, y: float, jaw: float) -> None:
        self.world, self.name = world, name
        o = world.plan.object_by_name(name)
        self.half = object_size(o.category, o.scale)[2] / 2.0
        self.top, self.x, self.y, self.jaw = top, x, y, jaw
        self.obj_in_tcp = np.eye(4)
        self.feel()

    def feel(self) -> None:
        """Read the held object's pose in the hand now (measured TCP and object)."""
        w = self.world
        self.obj_in_tcp = np.linalg.inv(S.measured_tcp(w)) @ w.object_pose(self.name).to_transformation_matrix()

    def tcp(self, bottom_above_top: float) -> np.ndarray:
        """TCP pose (world) with the object's bottom `bottom_above_top` over the spot."""
        goal = top_down(self.x, self.y, 0.0, self.jaw)
        goal[:3, 3] = (self.x, self.y, self.top + bottom_above_top + self.half)
        goal[:3, 3] -= goal[:3, :3] @ self.obj_in_tcp[:3, 3]
        return goal


def tilt(world: World, name: str) -> float:
    """The angle (rad) between the object's up axis and the world's vertical."""
    up = world.object_pose(name).to_transformation_matrix()[2, 2]
    return math.acos(max(-1.0, min(1.0, float(up))))


def choose_spot(world: World, name: str, goal: int) -> Spot:
    """The first free spot (best first) whose pose above it the arm reaches, jaws as they are or turned."""
    top = world.plan.furniture[goal].top_z
    jaw = jaw_yaw(S.measured_tcp(world))
    for x, y in place_spots(world, name, goal)[:SPOTS_TRIED]:
        for yaw in (jaw, jaw + math.pi / 2, jaw - math.pi / 2, jaw + math.pi):
            spot = Spot(world, name, top, x, y, yaw)
            if reach_cost(world, spot.tcp(ABOVE)) < 100.0 and reach_cost(world, spot.tcp(RELEASE_GAP)) < 100.0:
                return spot
    raise SkillFailed("no IK solution")


def _lower(world: World, name: str, spot: Spot) -> Generator[np.ndarray, None, None]:
    """Lower the held object towards RELEASE_GAP over the spot; over once the object has stopped
    near the top for STALL_STEPS steps (it rests on it, flat or caught leaning: going on only
    presses it and spends the step limit; measured on a perturbed train episode, three lowerings
    of 40 steps each ended in a Place timeout). Its pose, not its velocity, says so: a body jammed
    between the pads and the top reports ~1 rad/s and ~0.07 m/s while it does not move."""
    def pose() -> tuple[float, float]:
        return float(world.object_pose(name).p[2]), tilt(world, name)

    before, still = pose(), 0
    for action in S.servo(world, lambda: spot.tcp(RELEASE_GAP), speed=S.SLOW_SPEED, max_steps=LOWER_STEPS, close=True, settle_tol=0.008, accel=CARRY_ACCEL):
        now = pose()
        near = object_bottom(world, name) - spot.top < TOUCH_GAP
        still = still + 1 if near and abs(now[0] - before[0]) < STALL_DROP and abs(now[1] - before[1]) < STALL_TURN else 0
        if still >= STALL_STEPS:
            return
        before = now
        yield action


def _place(world: World, name: str, goal: int) -> Generator[np.ndarray, None, None]:
    robot = world.robot
    spot = choose_spot(world, name, goal)
    yield from S.servo(world, lambda: spot.tcp(ABOVE), max_steps=60, close=True, accel=CARRY_ACCEL)
    if robot.holding != name:
        raise SkillFailed("grasp slipped")
    yield from S.steady(world, name, STEADY_STEPS, goal=lambda: spot.tcp(ABOVE))
    spot.feel()
    for attempt in range(SET_DOWN_TRIES):
        # (not reaching the release height within the steps means the object already rests on
        # the top, tilted or pressed)
        yield from _lower(world, name, spot)
        here = commanded_pose(world)
        yield from S.steady(world, name, STEADY_STEPS, goal=here)
        if tilt(world, name) <= UPRIGHT_TOL or attempt == SET_DOWN_TRIES - 1:
            break
        # caught on the top mid-swing, leaning: let go now and it falls over. Lift it clear (it
        # hangs again), and set it down once more
        yield from S.servo(world, lambda: spot.tcp(RETRY_ABOVE), speed=S.SLOW_SPEED, max_steps=20, close=True, accel=CARRY_ACCEL)
    yield from S.hold_at(world, here, OPEN_STEPS, close=False)
    up = S.measured_tcp(world)
    up[2, 3] += RETREAT
    yield from S.servo(world, in_world_fixed(world, up), speed=S.SLOW_SPEED * 2, max_steps=40, close=False)
    yield from S.tuck(world, close=False)


__all__ = ["place", "place_spots", "held_object", "CARRY_DRIVE_GROUP"]
