"""Closed-loop motion primitives in end-effector space, shared by the manipulation experts.

Every primitive here yields `action.ee` vectors (`echo_data.records.EE_ACTION_NAMES`) and
recomputes its command at every control step from the state it is in: the goal is read again
(a callable goal re-reads the object, handle or lever pose from the world each step), the error
is taken from the commanded tool-centre-point (TCP) pose, and the step towards the goal is a
clipped proportional command (at most `speed` m/s and `turn` rad/s, the whole remaining error
when it is smaller). So a perturbation of the arm (DART noise on the executed action, a learner
handing over from elsewhere) is corrected by the very next label, and a moved object is
followed. Joint targets come from `echo_data.robot.ee_control` (the one ee <-> joint map).

Typical use in an expert::

    ok = yield from servo(world, lambda: above_object(world, name), max_steps=60)
    if not ok:
        raise SkillFailed("pre-grasp not reached")
    yield from grip(world, close=True, steps=8)

Poses are 4x4 numpy matrices in the world frame unless a name says `_in_base`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.records import EE_ACTION_DIM
from echo_data.robot.ee_control import base_frame, world_to_base
from echo_data.robot.robot import READY_GROUP, TUCK_QPOS

if TYPE_CHECKING:
    from echo_data.world import World

EeActions = Generator[np.ndarray, None, Any]
Goal = np.ndarray | Callable[[], np.ndarray]

SPEED = 0.20  # m/s of the TCP on transit moves (Fetch's arm: ~1 m/s max; slow enough for 10 Hz control)
SLOW_SPEED = 0.06  # m/s on the last centimetres to a grasp, a handle, a lever or a surface
TURN = 0.8  # rad/s of the TCP's orientation
POS_TOL = 0.004  # m: the commanded TCP is at the goal ...
ROT_TOL = 0.02  # rad
SETTLE_TOL = 0.015  # m: ... and the measured TCP has followed to within this
# Arrival after an aimed step (one that commanded the whole remaining error): what is left then is
# not the expert's doing but a perturbation of the executed step (DART, agents/dart.py; ~0.9 cm
# and ~1.7 deg per step at the shipped 0.5 cm / 1 deg). Demanding POS_TOL there would re-aim, and
# be perturbed again, until max_steps; with no perturbation an aimed step leaves ~0 and nothing changes.
AIMED_POS_TOL = 0.015  # m
AIMED_ROT_TOL = 0.05  # rad


def top_down(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    """4x4 TCP pose (world or base frame) pointing straight down with the fingers closing across
    `yaw` + 90 deg (the jaws close along the object's local y when `yaw` is the object's yaw)."""
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, 0] = (0.0, 0.0, -1.0)
    m[:3, 1] = (-s, c, 0.0)
    m[:3, 2] = (c, s, 0.0)
    m[:3, 3] = (x, y, z)
    return m


def jaw_yaw(pose: np.ndarray) -> float:
    """The `yaw` of `top_down` that gives this TCP pose's jaw direction (its inverse)."""
    return math.atan2(-float(pose[0, 1]), float(pose[1, 1]))


def gripper_closed(world: World) -> bool:
    """The gripper's command now (what the drives hold), as the binary `gripper_close`."""
    robot = world.robot
    return bool(robot.applied_action()[11] < robot.ee.gripper_open / 2.0)


def ee_command(
    world: World, base: tuple[float, float, float] = (0.0, 0.0, 0.0), torso: float | None = None,
    delta: np.ndarray | None = None, close: bool | None = None,
) -> np.ndarray:
    """One `action.ee`: base velocity (robot frame), torso target (default: as commanded), TCP
    change (default: none, the arm holds exactly) and gripper (default: as commanded)."""
    robot = world.robot
    a = np.zeros(EE_ACTION_DIM, dtype=np.float32)
    a[:3] = base
    a[3] = float(robot.applied_action()[3]) if torso is None else torso
    if delta is not None:
        a[4:10] = delta
    a[10] = 1.0 if (gripper_closed(world) if close is None else close) else 0.0
    return a


def in_base(world: World, pose_world: np.ndarray) -> np.ndarray:
    """A world pose (4x4) in the frame of the base where it stands now (measured)."""
    return world_to_base(pose_world, world.robot.base_pose())


def measured_tcp(world: World) -> np.ndarray:
    """The TCP's measured world pose (4x4)."""
    return world.robot.ee_pose().to_transformation_matrix()


def step_towards(delta: np.ndarray, speed: float, turn: float, dt: float) -> np.ndarray:
    """The clipped proportional command: the whole error when within one step's reach, else the
    error scaled (position and rotation separately) to `speed` and `turn` for one step."""
    d = np.asarray(delta, dtype=np.float64).copy()
    n_p = float(np.linalg.norm(d[:3]))
    n_r = float(np.linalg.norm(d[3:]))
    if n_p > speed * dt:
        d[:3] *= speed * dt / n_p
    if n_r > turn * dt:
        d[3:] *= turn * dt / n_r
    return d


def servo(
    world: World, goal: Goal, *, speed: float = SPEED, turn: float = TURN, max_steps: int = 100,
    close: bool | None = None, torso: float | None = None, pos_tol: float = POS_TOL, rot_tol: float = ROT_TOL,
    settle_tol: float = SETTLE_TOL, orient: bool = True, torso_speed: float | None = None,
    accel: float | None = None,
) -> Generator[np.ndarray, None, bool]:
    """Move the TCP to `goal` (4x4 world pose, or a callable re-read every step); returns True
    once the commanded TCP is within `pos_tol`/`rot_tol` of it and the measured TCP within
    `settle_tol`, False after `max_steps` actions. `orient=False` servos the position only.
    `torso`: a torso target to hold (or move to) meanwhile; the TCP change accounts for it;
    `torso_speed` (m/s): the torso command ramps towards `torso` at most this fast (else it jumps).
    `accel` (m/s^2): the TCP speeds up and slows down at most this fast (a trapezoid instead of a
    jump to `speed`), for an object held by friction that would swing in the pinch."""
    robot = world.robot
    dt = 1.0 / robot.cfg.control_hz
    v_prev = 0.0
    aimed = False  # the last command was the whole remaining error (not clipped)
    for _ in range(max_steps):
        g = goal() if callable(goal) else goal
        t = torso
        if torso is not None and torso_speed is not None:
            now = float(robot.applied_action()[3])
            if abs(torso - now) > torso_speed * dt:
                t = now + math.copysign(torso_speed * dt, torso - now)
        d = robot.ee.delta_towards(in_base(world, g), torso=t)
        if not orient:
            d[3:] = 0.0
        n_p, n_r = float(np.linalg.norm(d[:3])), float(np.linalg.norm(d[3:]))
        strict = n_p <= pos_tol and n_r <= rot_tol
        here = strict or (aimed and n_p <= AIMED_POS_TOL and n_r <= AIMED_ROT_TOL)
        settle = settle_tol if strict else max(settle_tol, AIMED_POS_TOL)
        if here and t == torso and float(np.linalg.norm(measured_tcp(world)[:3, 3] - g[:3, 3])) <= settle:
            return True
        v = speed
        if accel is not None:
            v = min(speed, v_prev + accel * dt, math.sqrt(2.0 * accel * float(np.linalg.norm(d[:3]))))
        step = np.zeros(6) if here else step_towards(d, v, turn, dt)
        if not here:
            aimed = bool(np.allclose(step, d))
        v_prev = float(np.linalg.norm(step[:3])) / dt
        yield ee_command(world, torso=t, delta=step, close=close)
    return False


def steady(
    world: World, name: str, max_steps: int, goal: Goal | None = None, speed: float = 0.02, spin: float = 0.3,
) -> Generator[np.ndarray, None, bool]:
    """Hold the hand (at `goal` if given, see `hold_at`) until object `name` moves slower than
    `speed` (m/s) and turns slower than `spin` (rad/s), at most `max_steps` control steps; True once
    it does (a held object that swings in the pinch comes to rest before it is measured or let go)."""
    import sapien

    body = world.handles.objects[name].find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
    for _ in range(max_steps):
        if float(np.linalg.norm(body.linear_velocity)) < speed and float(np.linalg.norm(body.angular_velocity)) < spin:
            return True
        yield ee_command(world, delta=None if goal is None else delta_to(world, goal))
    return False


HOLD_POS_TOL = 0.001  # m: closer than this (and HOLD_ROT_TOL) a holding command leaves the arm exactly as commanded
HOLD_ROT_TOL = 0.005  # rad


def delta_to(world: World, goal: Goal, speed: float = SLOW_SPEED, turn: float = TURN) -> np.ndarray:
    """One control step's clipped TCP change towards `goal` (4x4 world pose or a callable); zero
    within HOLD_POS_TOL / HOLD_ROT_TOL, so holding a reached goal holds the joint targets exactly."""
    g = goal() if callable(goal) else goal
    d = world.robot.ee.delta_towards(in_base(world, g))
    if float(np.linalg.norm(d[:3])) <= HOLD_POS_TOL and float(np.linalg.norm(d[3:])) <= HOLD_ROT_TOL:
        return np.zeros(6)
    return step_towards(d, speed, turn, 1.0 / world.robot.cfg.control_hz)


def hold_at(world: World, goal: Goal, steps: int, close: bool | None = None, speed: float = SLOW_SPEED) -> EeActions:
    """`steps` control steps holding the TCP at `goal` (base still), gripper as `close` says: a
    perturbed hand is brought back meanwhile (unlike `hold`, which keeps whatever is commanded)."""
    for _ in range(steps):
        yield ee_command(world, delta=delta_to(world, goal, speed), close=close)
    return steps


def grip(world: World, close: bool, steps: int = 8) -> EeActions:
    """Hold the arm and open or close the gripper for `steps` control steps (the jaws move meanwhile)."""
    for _ in range(steps):
        yield ee_command(world, close=close)
    return steps


TUCK_RAISE = -0.5  # shoulder_lift of the tuck path's middle pose (upper arm raised)
TUCK_SAMPLES = 4  # TCP poses per joint segment of the tuck path
TUCK_HOLD = 3  # control steps held in the tuck at the end


def tuck_path(world: World) -> list[Callable[[], np.ndarray]]:
    """Goal callables: TCP poses along the joint path READY -> upper arm raised -> tuck (READY's
    torso), each fixed in the base frame. Why poses along a joint path: a straight Cartesian
    move cannot refold the seven-joint arm into the tuck (its redundancy), while poses close
    together on the joint path lead the ee map's posture-seeded solution along it."""
    ee = world.robot.ee
    torso = float(READY_GROUP[0])
    raised = TUCK_QPOS.copy()
    raised[1] = TUCK_RAISE
    poses = []
    for a, b in ((READY_GROUP[1:], raised), (raised, TUCK_QPOS)):
        for t in np.linspace(0.0, 1.0, TUCK_SAMPLES + 1)[1:]:
            poses.append(ee.tcp_in_base(torso, a + (b - a) * t))

    def fixed_in_base(pose: np.ndarray) -> Callable[[], np.ndarray]:
        return lambda: base_frame(*world.robot.base_pose()) @ pose

    return [fixed_in_base(p) for p in poses]


def tuck(world: World, close: bool, turn: float = TURN) -> Generator[np.ndarray, None, bool]:
    """Fold the arm from READY into the tuck the episode starts in (base still, gripper as
    `close` says), and hold it there TUCK_HOLD steps; True once the tuck is reached. Every skill
    that leaves the hand empty ends so: a drive after it then carries the arm inside the base's
    footprint, the one the navigation grid is inflated for (with the arm at READY the elbow
    reached a wall that the base cleared, test episodes 1 and 20 of the multi-event setting)."""
    path = tuck_path(world)
    ok = False
    for i, pose in enumerate(path):
        last = i == len(path) - 1
        ok = yield from servo(world, pose, max_steps=30, close=close, turn=turn, pos_tol=POS_TOL if last else 0.02,
                              settle_tol=SETTLE_TOL if last else 0.05)
    yield from hold_at(world, path[-1], TUCK_HOLD, close=close)
    return bool(ok)


def hold(world: World, steps: int) -> EeActions:
    """Everything held where it is commanded, base still, for `steps` control steps."""
    for _ in range(steps):
        yield ee_command(world)
    return steps
