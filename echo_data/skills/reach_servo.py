"""Closed-loop base and arm moves that OpenDoor and CloseSink share, in end-effector actions.

Both start wherever Navigate handed over (anywhere in its success region,
`echo_data.skills.success.navigate_success`) and first bring the base where their grasp or push
needs it (`drive`, after `arm_reaches` picked the stance), unfold the arm to READY (`to_ready`),
and after letting go back off while the arm returns to READY (`retreat`). Like
`echo_data.skills.servo`, every command is recomputed from the measured state at each step (a
goal given as a callable is re-read too), so a perturbation is undone by the next label.

The base drive is straight-line and clipped-proportional: it is meant for the last metre or so
in front of a door or a counter, where the interaction pose keeps the way clear; longer trips
are Navigate's job. (The previous experts' joint-space counterpart planned with mplib; no expert
needs a motion planner any more.)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from echo_data.robot.robot import READY_GROUP
from echo_data.skills.servo import ee_command, in_base, servo, step_towards

if TYPE_CHECKING:
    from echo_data.world import World

Pose2 = tuple[float, float, float]

DRIVE_SPEED = 0.4  # m/s, at most (Fetch's base: 1 m/s max; slow where the arm is out)
DRIVE_MIN_SPEED = 0.04  # m/s, so the last centimetres do not crawl
DRIVE_TURN = 0.8  # rad/s, at most
DRIVE_GAIN = 3.0  # 1/s, proportional gain on position and heading (0.3 per 0.1 s step: no overshoot)
DRIVE_TOL = 0.015  # m: the base is at its goal ...
DRIVE_YAW_TOL = math.radians(1.5)  # ... and heads its way
WAYPOINT_TOL = 0.1  # m: a corner of a grid path is passed
WAYPOINT_SPEED = 0.6  # m/s between corners, arm tucked (Navigate's cruise speed)
READY_TORSO = float(READY_GROUP[0])  # m, READY's torso height
UNTUCK_SPEED = 0.2  # m/s of the TCP to and from READY (faster moves out of the tuck measured slower to settle)
UNTUCK_TURN = 1.0  # rad/s (the tuck -> READY turn dominates: 35 steps, joints <= 2.1 rad/s)
STOW_STEPS = 60  # control steps a move to READY may take
# rad/s of the TCP while folding from READY into the tuck at a skill's end (`servo.tuck`): the
# fold is a rotation of the hand more than a move (~1 rad per waypoint); at Place's 0.8 it took
# 75 control steps after OpenDoor, at 1.6 it takes 50 (joints stay below 2.1 rad/s). Followed by
# another skill, CloseSink then takes 176-177 of its 200 steps (75 multi-event test episodes).
TUCK_TURN = 1.6
# Arrival tolerances of the servo moves (commanded TCP position m, rotation rad; measured TCP m).
# Transit moves (to READY, to a pre-grasp or above a lever) end loosely: the next move starts
# from wherever it is, and a per-step perturbation of the executed action (DART, ~1 cm at the
# hand) keeps the commanded pose that far from any goal. Moves onto a handle or beside a lever
# end within CONTACT (the open jaws clear the bar by 3.8 cm, the finger block the lever by 6 mm).


class Tolerances(TypedDict):
    """`servo`'s arrival keywords."""

    pos_tol: float
    rot_tol: float
    settle_tol: float


TRANSIT: Tolerances = {"pos_tol": 0.015, "rot_tol": 0.05, "settle_tol": 0.03}
CONTACT: Tolerances = {"pos_tol": 0.01, "rot_tol": 0.05, "settle_tol": 0.015}


def wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def base_velocity(here: Pose2, goal: Pose2, speed: float = DRIVE_SPEED) -> tuple[float, float, float]:
    """The robot-frame velocity (vx, vy, wz) that drives a base at `here` towards `goal`:
    proportional, clipped to `speed` and DRIVE_TURN, at least DRIVE_MIN_SPEED while moving."""
    x, y, yaw = here
    ex, ey, eyaw = goal[0] - x, goal[1] - y, wrap(goal[2] - yaw)
    c, s = math.cos(yaw), math.sin(yaw)
    v = DRIVE_GAIN * np.array([c * ex + s * ey, -s * ex + c * ey])
    n = float(np.linalg.norm(v))
    if n > speed:
        v *= speed / n
    elif 0.0 < n < DRIVE_MIN_SPEED:
        v *= DRIVE_MIN_SPEED / n
    return (float(v[0]), float(v[1]), float(np.clip(DRIVE_GAIN * eyaw, -DRIVE_TURN, DRIVE_TURN)))


def at_pose(here: Pose2, goal: Pose2, tol: float = DRIVE_TOL, yaw_tol: float = DRIVE_YAW_TOL) -> bool:
    """The base at `here` is within `tol` and `yaw_tol` of `goal`."""
    return math.hypot(goal[0] - here[0], goal[1] - here[1]) < tol and abs(wrap(goal[2] - here[2])) < yaw_tol


def drive(
    world: World, goal: Pose2 | Callable[[], Pose2], *, max_steps: int, speed: float = DRIVE_SPEED,
    arm: Callable[[], np.ndarray] | None = None, torso: float | None = None, close: bool | None = None,
    tol: float = DRIVE_TOL, yaw_tol: float = DRIVE_YAW_TOL, stop: bool = True,
) -> Generator[np.ndarray, None, bool]:
    """Drive the base to `goal` (x, y, yaw in the world, or a callable re-read each step) within
    `tol` and `yaw_tol`; one stop action on arrival unless `stop` is False (a waypoint). `arm`: a
    callable giving this step's TCP change (default: hold). Returns True on arrival, False after
    `max_steps` actions."""
    robot = world.robot
    for _ in range(max_steps):
        g = goal() if callable(goal) else goal
        here = robot.base_pose()
        if at_pose(here, g, tol, yaw_tol) and not stop:
            return True
        delta = None if arm is None else arm()
        if at_pose(here, g, tol, yaw_tol):
            yield ee_command(world, torso=torso, delta=delta, close=close)
            return True
        yield ee_command(world, base=base_velocity(here, g, speed), torso=torso, delta=delta, close=close)
    return False


def approach(
    world: World, target: str, goal: Pose2 | Callable[[], Pose2], *, max_steps: int, close: bool | None = None,
) -> Generator[np.ndarray, None, bool]:
    """Bring the base from anywhere in Navigate's success region for `target` to `goal`,
    unfolding the arm towards READY on the straight part (the way ahead is clear floor and `goal`
    leaves room in front: the unfolding arm reaches at most 0.53 m ahead of the base centre).

    Straight (`drive`) when the way to the target's interaction pose is clear by the robot's
    radius on the navigation grid; otherwise (a hand-over behind a door frame or a wall corner,
    which the success region allows) first through the corners of the grid's shortest path to
    `goal` (`NavGrid.plan_path`, the one Navigate follows; deterministic), arm held, heading
    already turning to the goal's (the base is holonomic), then straight onto it. Returns True
    on arrival (the arm may still be on its way to READY: `to_ready` finishes it).
    """
    from echo_data.scene.nav import interaction_pose
    from echo_data.skills.navigate import START_SNAP, current_grid, door_angles

    steps = Steps()
    x, y, _ = world.robot.base_pose()
    grid = current_grid(world)
    try:
        via = interaction_pose(world.plan, target, door_angles=door_angles(world) or None, grid=grid)
    except ValueError:
        via = None
    if via is not None and grid.segment_clearance((x, y), (via[0], via[1])) < grid.robot_radius:
        g = goal() if callable(goal) else goal
        path = grid.plan_path((x, y), (g[0], g[1]), start_snap=START_SNAP)
        if path is None:
            return False
        for wx, wy in path[1:-1]:
            if not (yield from steps.run(drive(world, (wx, wy, g[2]), max_steps=max(1, max_steps - steps.n), close=close,
                                               speed=WAYPOINT_SPEED, tol=WAYPOINT_TOL, yaw_tol=math.pi, stop=False))):
                return False
    return (yield from drive(world, goal, max_steps=max(1, max_steps - steps.n), arm=lambda: ready_step(world), torso=READY_TORSO, close=close))


def arm_reaches(world: World, stance: Pose2, tcp_world: np.ndarray, torso: float, tol: float = 0.005, rounds: int = 10) -> bool:
    """Whether the arm puts the TCP at `tcp_world` (4x4) from a base at `stance` with the torso at
    `torso`: the robot's own IK (`echo_data.robot.ee_control`) started at READY, within `tol` (m,
    and rad for the rotation). Used to pick a stance before driving there; deterministic."""
    from scipy.spatial.transform import Rotation

    from echo_data.robot.ee_control import world_to_base

    ee = world.robot.ee
    ready = np.asarray(READY_GROUP[1:], dtype=np.float64)
    torso_in_base = ee.tcp_in_base(torso, ready) @ np.linalg.inv(ee.tcp_in_torso(ready))
    goal = np.linalg.inv(torso_in_base) @ world_to_base(tcp_world, stance)
    q = ready
    for _ in range(rounds):
        q = ee.ik(goal, q)
        now = ee.tcp_in_torso(q)
        rot = float(np.linalg.norm(Rotation.from_matrix(goal[:3, :3] @ now[:3, :3].T).as_rotvec()))
        if float(np.linalg.norm(goal[:3, 3] - now[:3, 3])) < tol and rot < tol:
            return True
    return False


class Steps:
    """Counts the actions an expert passes through `run` (its phases' steps add up to its own)."""

    def __init__(self) -> None:
        self.n = 0

    def run(self, gen: Generator[np.ndarray, None, Any]) -> Generator[np.ndarray, None, Any]:
        """Yield `gen`'s actions, counting them; return its value."""
        while True:
            try:
                a = next(gen)
            except StopIteration as stop:
                return stop.value
            self.n += 1
            yield a


def ready_goal(world: World) -> np.ndarray:
    """READY's TCP pose (the carry pose, `echo_data.robot.robot.READY_GROUP`) in the world, for
    the base where it stands now (4x4)."""
    from echo_data.robot.ee_control import base_frame

    tcp = world.robot.ee.tcp_in_base(READY_TORSO, np.asarray(READY_GROUP[1:], dtype=np.float64))
    return base_frame(*world.robot.base_pose()) @ tcp


def ready_step(world: World) -> np.ndarray:
    """This step's TCP change of the straight Cartesian move to READY (for `drive`'s `arm`)."""
    d = world.robot.ee.delta_towards(in_base(world, ready_goal(world)), torso=READY_TORSO)
    return step_towards(d, UNTUCK_SPEED, UNTUCK_TURN, 1.0 / world.robot.cfg.control_hz)


def to_ready(world: World, *, close: bool, max_steps: int = STOW_STEPS) -> Generator[np.ndarray, None, bool]:
    """A straight Cartesian move of the TCP to READY (out of the tuck, or back from a handle or a
    lever), base still; True once there."""
    return (yield from servo(world, lambda: ready_goal(world), speed=UNTUCK_SPEED, turn=UNTUCK_TURN, torso=READY_TORSO, max_steps=max_steps,
                             close=close, **TRANSIT))


def retreat(world: World, goal: Pose2, *, close: bool, max_steps: int = STOW_STEPS) -> Generator[np.ndarray, None, bool]:
    """Back the base to `goal` while the TCP already returns to READY, then finish the move to
    READY; True once both are there (used after letting go of a handle or a lever)."""
    steps = Steps()
    arrived = yield from steps.run(drive(world, goal, max_steps=max_steps, arm=lambda: ready_step(world), torso=READY_TORSO, close=close))
    stowed = yield from to_ready(world, close=close, max_steps=max(1, max_steps - steps.n))
    return bool(arrived and stowed)
