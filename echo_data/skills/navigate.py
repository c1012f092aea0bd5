"""The Navigate expert: plan a base path on the occupancy grid and drive it with velocity actions.

`PathFollower` is pure (pose in, robot-frame velocity out) so it can be checked without
physics; `drive_to` runs it in a `World` (replanning when the robot strays or stalls, stopping
on contact with walls or furniture), yielding `action.ee` (base velocities, the arm held by a
zero TCP change), and is reused by the Place expert; `navigate` is the skill (its success test,
`navigate_success`, lives with the others in `echo_data.skills.success`).

Navigate's internals live here and nowhere else: its goal (`goal_pose`), planning and
re-planning (`plan_follower`), the expert's path length that SPL divides by (`path_length`),
its answer from any state a learner reached (`Relabeller`, DAgger's labels), and the hand-over
starts of `experts.handover_noise` (`handover_goal`).
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from echo_data.records import ACTION_DIM, EE_ACTION_DIM, SkillOutcome
from echo_data.scene.nav import NavGrid, interaction_pose, target_point
from echo_data.seeds import HANDOVER, derived_rng
from echo_data.skill_table import HandOver, handover_call
from echo_data.skill_table import skill as skill_of
from echo_data.skills.servo import SPEED, TURN, ee_command, step_towards
from echo_data.skills.success import NAV_SUCCESS_YAW, navigate_success

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.floorplan import FloorPlan
    from echo_data.world import World

# Speed limits and ramps (Fetch's base: ≈1 m/s top speed; slower keeps tracking tight).
MAX_LIN = 0.6  # m/s
MAX_ANG = 1.0  # rad/s
ACC_LIN = 0.8  # m/s^2
ACC_ANG = 2.5  # rad/s^2
LOOKAHEAD = 0.35  # m, carrot distance along the path
TURN_IN_PLACE = math.radians(35)  # heading error beyond which the base stops and turns
K_HEADING = 2.0  # 1/s, heading gain while driving and turning
GOAL_TOL = 0.08  # m, position at which the final turn starts
YAW_TOL = math.radians(3)  # final heading tolerance
# Replanning: off the path by more than this, or no progress for this long.
STRAY_DIST = 0.35
STALL_SECONDS = 3.0
MAX_REPLANS = 4
# A robot that ends a skill inside the inflated zone (beside an opened leaf, close to a
# counter) first steps out to the nearest free cell within this distance (m).
START_SNAP = 0.6
COLLISION_STEPS = 3  # consecutive control steps in contact before the drive gives up
HOLD_TOL = 1e-6  # m / rad: a commanded TCP this close to where the drive holds it gets a zero change


def wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def _ramp(prev: float, want: float, acc: float, dt: float) -> float:
    step = acc * dt
    return prev + max(-step, min(step, want - prev))


@dataclass
class PathFollower:
    """Turn-then-drive tracking of a waypoint path, ending with a turn to `final_yaw`.

    `command(pose)` returns (vx, vy, wz) in the robot frame; vy stays 0 so the same
    commands suit a differential or a holonomic base.
    """

    path: list[tuple[float, float]]
    final_yaw: float | None
    dt: float
    max_lin: float = MAX_LIN
    max_ang: float = MAX_ANG
    seg: int = 0  # index of the segment being tracked (path[seg] -> path[seg+1])
    v: float = 0.0
    w: float = 0.0
    turning: bool = False  # in the final turn
    done: bool = False

    def _project(self, x: float, y: float) -> tuple[float, float]:
        """Advance `seg` past finished segments; return (distance off the path, path length left)."""
        while self.seg < len(self.path) - 2:
            (ax, ay), (bx, by) = self.path[self.seg], self.path[self.seg + 1]
            dx, dy = bx - ax, by - ay
            t = ((x - ax) * dx + (y - ay) * dy) / max(dx * dx + dy * dy, 1e-12)
            if t < 1.0 and math.hypot(bx - x, by - y) > 0.5 * LOOKAHEAD:
                break
            self.seg += 1
        (ax, ay), (bx, by) = self.path[self.seg], self.path[min(self.seg + 1, len(self.path) - 1)]
        dx, dy = bx - ax, by - ay
        t = min(max(((x - ax) * dx + (y - ay) * dy) / max(dx * dx + dy * dy, 1e-12), 0.0), 1.0)
        px, py = ax + t * dx, ay + t * dy
        left = math.hypot(bx - px, by - py) + sum(
            math.dist(self.path[k], self.path[k + 1]) for k in range(self.seg + 1, len(self.path) - 1)
        )
        return math.hypot(x - px, y - py), left

    def _carrot(self, x: float, y: float) -> tuple[float, float]:
        """The point LOOKAHEAD ahead along the path from the robot's projection (or the goal)."""
        (ax, ay), (bx, by) = self.path[self.seg], self.path[min(self.seg + 1, len(self.path) - 1)]
        dx, dy = bx - ax, by - ay
        seg_len = math.hypot(dx, dy)
        t = min(max(((x - ax) * dx + (y - ay) * dy) / max(seg_len * seg_len, 1e-12), 0.0), 1.0)
        remaining = LOOKAHEAD
        px, py = ax + t * dx, ay + t * dy
        k = self.seg + 1
        cx, cy = px, py
        while k < len(self.path):
            nx, ny = self.path[k]
            d = math.hypot(nx - cx, ny - cy)
            if d >= remaining:
                f = remaining / max(d, 1e-12)
                return (cx + f * (nx - cx), cy + f * (ny - cy))
            remaining -= d
            cx, cy = nx, ny
            k += 1
        return self.path[-1]

    def off_path(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the segment being tracked."""
        return self._project(x, y)[0]

    def command(self, pose: tuple[float, float, float]) -> tuple[float, float, float]:
        """Velocity targets for this control step; sets `done` once at the goal and turned."""
        x, y, yaw = pose
        goal = self.path[-1]
        dist_goal = math.hypot(goal[0] - x, goal[1] - y)
        want_v, want_w = 0.0, 0.0
        if not self.turning and dist_goal <= GOAL_TOL:
            self.turning = True
        if self.turning:
            err = 0.0 if self.final_yaw is None else wrap(self.final_yaw - yaw)
            if abs(err) <= YAW_TOL and abs(self.w) <= 0.15:
                self.done = True
            else:
                want_w = K_HEADING * err
        else:
            _, left = self._project(x, y)
            cx, cy = self._carrot(x, y)
            err = wrap(math.atan2(cy - y, cx - x) - yaw)
            want_w = K_HEADING * err
            if abs(err) < TURN_IN_PLACE:
                # Slow down for the goal (v^2 <= 2 a d) and for heading error.
                v_stop = math.sqrt(2.0 * 0.5 * ACC_LIN * max(left, dist_goal))
                want_v = min(self.max_lin, v_stop) * (1.0 - abs(err) / TURN_IN_PLACE)
        want_v = max(0.0, min(self.max_lin, want_v))
        want_w = max(-self.max_ang, min(self.max_ang, want_w))
        if self.done:
            want_v, want_w = 0.0, 0.0
        self.v = _ramp(self.v, want_v, ACC_LIN, self.dt)
        self.w = _ramp(self.w, want_w, ACC_ANG, self.dt)
        # Stop ramps that would overshoot a small heading error within one step.
        if abs(want_w) < abs(self.w) and want_w * self.w >= 0:
            self.w = want_w
        return (self.v, 0.0, self.w)


# ---------------------------------------------------------------------- in a World
@dataclass
class DriveResult:
    """How a drive ended: `reason` is "" on arrival, else "no_path", "timeout" or "collision"."""

    success: bool
    reason: str
    steps: int
    replans: int = 0


def door_angles(world: World) -> dict[int, float]:
    """Current hinge angle of every door in the world (empty when it has none)."""
    return world.handles.door_angles()


def current_grid(world: World) -> NavGrid:
    """The world's occupancy grid with its doors where they stand now (≈2–12 ms to rebuild)."""
    nav = world.nav
    return NavGrid.from_plan(world.plan, robot_radius=nav.robot_radius, resolution=nav.resolution, door_angles=door_angles(world))


def goal_pose(world: World, target: str, grid: NavGrid | None = None) -> tuple[float, float, float]:
    """Navigate's goal for `target`: its interaction pose (x, y, yaw) with the doors where they
    stand now (ValueError when none is free). The one place the expert, the runtime's goal
    observation and SPL's expert path read it from."""
    return interaction_pose(world.plan, target, door_angles=door_angles(world) or None, grid=grid or current_grid(world))


def plan_follower(grid: NavGrid, pose: tuple[float, float, float], goal: tuple[float, float, float], dt: float,
                  v: float = 0.0, w: float = 0.0) -> PathFollower | None:
    """A follower of the grid's path from `pose` to `goal` (None: no path), its speed ramp
    starting at (v, w): how the expert plans at the start and re-plans on the way."""
    path = grid.plan_path((pose[0], pose[1]), (goal[0], goal[1]), start_snap=START_SNAP)
    return None if path is None else PathFollower(path, goal[2], dt, v=v, w=w)


def path_length(grid: NavGrid, pose: tuple[float, float, float], goal: tuple[float, float, float]) -> float:
    """Metres of the expert's planned path from `pose` to `goal` (nan: no path): SPL's reference."""
    path = grid.plan_path((pose[0], pose[1]), (goal[0], goal[1]), start_snap=START_SNAP)
    if not path:
        return math.nan
    pts = [(pose[0], pose[1]), *path]
    return float(sum(math.dist(a, b) for a, b in zip(pts, pts[1:])))


class ArmHold:
    """The arm, torso and gripper held at what was commanded when a drive began, in `action.ee`
    form: a zero TCP change while the commanded TCP is there (the arm, and a carried object,
    hold exactly), else a clipped step back (a perturbed arm is corrected by the next label)."""

    def __init__(self, world: World, hold: np.ndarray | None = None) -> None:
        robot = world.robot
        ref = robot.applied_action()
        self.world = world
        self.arm = ref[4:11].astype(np.float64)
        self.torso = float(ref[3])
        self.close = bool(ref[11] < robot.ee.gripper_open / 2.0)
        if hold is not None:  # a held command: an action.ee (11) or, from joint experts, an action (12)
            h = np.asarray(hold, dtype=np.float64)
            self.torso = float(h[3])
            self.close = bool(h[10] >= 0.5) if h.shape == (EE_ACTION_DIM,) else bool(h[11] < robot.ee.gripper_open / 2.0)
            if h.shape == (ACTION_DIM,):
                self.arm = h[4:11]
        self.home = robot.ee.tcp_in_torso(self.arm)

    def command(self, base: tuple[float, float, float]) -> np.ndarray:
        """One `action.ee`: the base velocity `base` and the arm held (see the class doc)."""
        robot = self.world.robot
        ref = robot.applied_action().astype(np.float64)
        delta = None
        if not np.array_equal(ref[4:11], self.arm):
            now = robot.ee.tcp_in_torso(ref[4:11])
            d = np.zeros(6)
            d[:3] = self.home[:3, 3] - now[:3, 3]
            d[3:] = Rotation.from_matrix(self.home[:3, :3] @ now[:3, :3].T).as_rotvec()
            if np.linalg.norm(d[:3]) > HOLD_TOL or np.linalg.norm(d[3:]) > HOLD_TOL:
                delta = step_towards(d, SPEED, TURN, 1.0 / robot.cfg.control_hz)
        return ee_command(self.world, base=base, torso=self.torso, delta=delta, close=self.close)


def robot_collisions(world: World) -> list[str]:
    """Names of walls, furniture, doors or faucets a robot link touches after the last physics step.

    The floor and dynamic objects (a carried object, clutter) do not count: a collision here
    is the base or arm hitting the apartment.
    """
    robot = world.robot
    robot_entities = {ln.entity for ln in robot.articulation.links}
    handles = world.handles
    solid = {e for e in handles.statics if e.name != "floor"}
    for art in list(handles.doors) + list(handles.faucets):
        solid |= {ln.entity for ln in art.links}
    hits = []
    for c in robot.scene.get_contacts():
        e0, e1 = c.bodies[0].entity, c.bodies[1].entity
        other = e1 if e0 in robot_entities else e0 if e1 in robot_entities else None
        if other is None or other in robot_entities or other not in solid:
            continue
        if any(np.linalg.norm(p.impulse) > 1e-6 for p in c.points):
            hits.append(other.name)
    return hits


def _stalled(history: list[tuple[float, float, float]]) -> bool:
    """True when a window of commanded-motion poses shows (almost) no motion."""
    x0, y0, a0 = history[0]
    x1, y1, a1 = history[-1]
    return math.hypot(x1 - x0, y1 - y0) < 0.05 and abs(wrap(a1 - a0)) < 0.1


def drive_to(
    world: World,
    goal: tuple[float, float, float],
    max_steps: int,
    grid: NavGrid | None = None,
    hold: np.ndarray | None = None,
) -> Generator[np.ndarray, None, DriveResult]:
    """Drive the base to `goal` (x, y, yaw): yields one `action.ee` per control step.

    Torso, arm and gripper hold what is commanded when the drive starts (`ArmHold`: a zero TCP
    change, so a carried object stays in hand exactly); `hold`, when given, names the torso and
    gripper (and, as a 12-float joint action, the arm) to hold instead. Replans from where the
    robot is when it strays from the path or stalls; gives up on MAX_REPLANS failures or
    COLLISION_STEPS steps in contact.
    """
    robot = world.robot
    dt = 1.0 / robot.cfg.control_hz
    arm = ArmHold(world, hold)
    if grid is None:
        grid = current_grid(world)
    follower = plan_follower(grid, robot.base_pose(), goal, dt)
    if follower is None:
        return DriveResult(False, "no_path", 0)
    window = max(int(round(STALL_SECONDS / dt)), 2)
    history: list[tuple[float, float, float]] = []
    steps = replans = touching = 0
    while True:
        pose = robot.base_pose()
        touching = touching + 1 if robot_collisions(world) else 0
        if touching >= COLLISION_STEPS:
            return DriveResult(False, "collision", steps, replans)
        stray = not follower.turning and follower.off_path(pose[0], pose[1]) > STRAY_DIST
        stalled = len(history) >= window and _stalled(history[-window:])
        if stray or stalled:
            replans += 1
            if replans > MAX_REPLANS:
                return DriveResult(False, "collision" if touching else "no_path", steps, replans)
            grid = current_grid(world)
            nxt = plan_follower(grid, pose, goal, dt, v=follower.v, w=follower.w)
            if nxt is None:
                return DriveResult(False, "no_path", steps, replans)
            follower = nxt
            history.clear()
        vx, vy, wz = follower.command(pose)
        if follower.done:
            break
        if steps >= max_steps:
            return DriveResult(False, "timeout", steps, replans)
        if abs(vx) > 0.05 or abs(wz) > 0.1:
            history.append(pose)
        else:
            history.clear()  # standing still on purpose is not a stall
        yield arm.command((vx, vy, wz))
        steps += 1
    if steps < max_steps:  # one explicit stop so the record ends at rest
        yield arm.command((0.0, 0.0, 0.0))
        steps += 1
    return DriveResult(True, "", steps, replans)


class Relabeller:
    """Navigate's expert asked from any state a learner reached (DAgger's labels): the
    expert's path from where the base stands, kept while the base stays within STRAY_DIST of it
    and re-planned otherwise, the follower's speed ramp started from the learner's last command,
    the arm held as `drive_to` holds it. Returns the joint action the build would record."""

    def __init__(self, world: World, target: str, grid: NavGrid) -> None:
        self.world, self.grid = world, grid
        self.goal = goal_pose(world, target, grid)
        self.follower: PathFollower | None = None
        self.arm = ArmHold(world)

    def __call__(self, last_command: np.ndarray) -> np.ndarray | None:
        """Expert action now, given the base velocity the learner commanded last; None: no path."""
        robot = self.world.robot
        pose = robot.base_pose()
        f = self.follower
        if f is None or (not f.turning and f.off_path(pose[0], pose[1]) > STRAY_DIST):
            f = self.follower = plan_follower(self.grid, pose, self.goal, 1.0 / robot.cfg.control_hz)
            if f is None:
                return None
        f.v, f.w = float(last_command[0]), float(last_command[2])  # the ramp starts where the base is
        base = f.command(pose)
        return robot.ee.to_joint(self.arm.command((0.0, 0.0, 0.0) if f.done else base))


# ---------------------------------------------------------------------- hand-over starts
# `experts.handover_noise` = f in (0, 1]: the build's Navigate stops at a random point of the next
# skill's stance (`skill_table.HandOver`, docs/handover.md) instead of its interaction pose,
# so the manipulation demonstrations start from the whole region a learned Navigate is made to
# end in (M3, Gu et al. 2022, "Multi-skill Mobile Manipulation for Object Rearrangement":
# manipulation skills trained from a distribution of base starts around the target, not one pose).
# The point is uniform (by area) in the disc of radius f x (stance distance - GOAL_TOL) about the
# interaction point, on a free cell in straight sight of it along a free line (never behind a wall
# or a closed door), the heading uniform within f x (stance heading - YAW_TOL) of the pose's; a
# draw where Navigate's own success test (facing the target within NAV_SUCCESS_YAW, less YAW_TOL)
# would fail is drawn again. The margins keep the follower's stop inside the stance.
HANDOVER_TRIES = 64  # draws before the interaction pose itself is kept


def handover_goal(plan: FloorPlan, target: str, grid: NavGrid, exact: tuple[float, float, float], noise: float,
                  rng: np.random.Generator, stance: HandOver, doors: dict[int, float] | None = None) -> tuple[float, float, float]:
    """A stop pose drawn from the fraction `noise` of `stance` about `target`'s interaction pose
    `exact` (see the block above), `doors` the hinge angles (default: the plan's); `exact`
    itself when no draw within HANDOVER_TRIES lands on a usable cell."""
    if noise <= 0.0:
        return exact
    tx, ty = target_point(plan, target, doors or None)
    px, py, pyaw = exact
    radius, spread = noise * max(stance.distance - GOAL_TOL, 0.0), noise * max(stance.heading - YAW_TOL, 0.0)
    for _ in range(HANDOVER_TRIES):
        u, phi, s = rng.random(3)
        r = radius * math.sqrt(u)
        x, y = px + r * math.cos(2.0 * math.pi * phi), py + r * math.sin(2.0 * math.pi * phi)
        if not grid.is_free(x, y) or grid.segment_clearance((x, y), (px, py)) < grid.robot_radius:
            continue
        yaw = wrap(pyaw + spread * (2.0 * s - 1.0))
        if abs(wrap(math.atan2(ty - y, tx - x) - yaw)) > NAV_SUCCESS_YAW - YAW_TOL:
            continue
        return (x, y, yaw)
    return exact


def _handover_rng(spec: EpisodeSpec, call: SkillCall) -> np.random.Generator:
    """The episode's own stream for this chain entry's hand-over point (`seeds.HANDOVER`)."""
    k = spec.chain.index(call) if call in spec.chain else 0
    return derived_rng(HANDOVER, spec.seed, k)


def _stop_pose(world: World, call: SkillCall, spec: EpisodeSpec, grid: NavGrid, exact: tuple[float, float, float]) -> tuple[float, float, float]:
    """Where the Navigate expert of `call` stops: a learner's recorded hand-over when the build
    gives one (`World.handover_stops`) and its cell is free (else the entry is set to None and
    the exact pose kept), a draw from the next skill's stance with `experts.handover_noise`, or
    the interaction pose `exact`."""
    k = spec.chain.index(call) if spec is not None and call in spec.chain else None
    stops = world.handover_stops
    if k is not None and k in stops:
        pose = stops[k]
        if pose is not None and grid.is_free(pose[0], pose[1]):
            return pose
        stops[k] = None  # no usable cell (the base would collide there): the exact pose, counted by the build
        return exact
    noise = float(world.recipe.experts.handover_noise)
    to = handover_call(spec.chain, k) if noise > 0.0 and k is not None else None
    stance = skill_of(to.skill).stance if to is not None else None
    if stance is None:
        return exact
    return handover_goal(world.plan, call.target, grid, exact, noise, _handover_rng(spec, call), stance, door_angles(world))


def navigate(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """The Navigate expert: drive to the interaction pose of `call.target` and face it (with
    `experts.handover_noise`, to a point of the next skill's stance drawn per episode instead)."""
    robot = world.robot
    skill, target = call.skill, call.target
    max_steps = int(robot.cfg.max_steps[skill])
    grid = current_grid(world)
    try:
        goal = goal_pose(world, target, grid)
    except ValueError:
        return SkillOutcome(skill, target, False, "no_path", 0)
    goal = _stop_pose(world, call, spec, grid, goal)
    result = yield from drive_to(world, goal, max_steps, grid=grid)
    if not result.success and not (result.reason == "timeout" and navigate_success(world, target)):
        # (out of steps but already within the success region counts: the criterion is the state)
        return SkillOutcome(skill, target, False, result.reason, result.steps)
    ok = navigate_success(world, target)
    return SkillOutcome(skill, target, ok, "" if ok else "not_at_target", result.steps)
