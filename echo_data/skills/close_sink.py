"""The CloseSink expert: push the running faucet's lever back along its arc with closed fingers.

Where it wants to start: in front of the sink cabinet, facing it — `interaction_pose(plan,
"faucet:<i>")` of `echo_data.scene.nav` is fine. The expert drives the last few decimetres
itself to its stance: on the cabinet's front normal through the lever pivot, at least
`PIVOT_DISTANCE` from the pivot and `FRONT_GAP` from the cabinet face, facing the cabinet,
shifted sideways if needed (`sink_stances`).

The lever turns about the vertical axis through `Faucet.pivot` and opens counter-clockwise
(`echo_data.scene.articulated`). With the fingers closed and the gripper pitched down, the
finger block is lowered beside the lever on its opening side (a lead angle ahead of it on
the contact arc, `CONTACT_INSET` inside the lever tip) and then swept clockwise along the arc past angle 0, so
the lever is pushed to its closed limit (docs/SIMULATION_NOTES.md#closing-a-faucet); the water stops. The
arm then lifts and tucks.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING

import numpy as np

from echo_data.records import SkillOutcome
from echo_data.scene.articulated import LEVER_SECTION
from echo_data.scene.floorplan import Faucet, Furniture
from echo_data.skills import arm
from echo_data.skills.reach import (
    approach_base,
    arm_action,
    near_ik,
    planner_at,
    reach_ik,
    tuck_arm,
    untuck_waypoints,
)
from echo_data.skills.success import sink_closed_success
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

BASE_RADIUS = 0.28  # m, the robot's base disc
FRONT_GAP = 0.06  # m between the base disc and the cabinet face, at least
PIVOT_DISTANCE = 0.8  # m from the base centre to the lever pivot, at least (closer needs the shoulder beyond its limit)
BASE_CLEARANCE = 0.02  # m between the base disc and any wall, furniture or door leaf at a stance
LATERAL_SHIFTS = (0.0, -0.1, 0.1, -0.2, 0.2)  # m along the cabinet face, tried in order
PITCH = math.radians(75)  # gripper approach below the horizontal (steep: the wrist stays far from the shoulder)
FINGER_HALF = 0.02  # m, horizontal half-extent of the closed finger block
CONTACT_CLEAR = 0.006  # m between the finger block and the lever before the sweep
CONTACT_INSET = 0.025  # m from the lever tip to the contact point
HOVER = 0.08  # m above the lever before descending
UNTUCK_BACK = (0.35, 0.25, 0.15)  # m back from the stance where the arm unfolds (untuck in open space: docs/SIMULATION_NOTES.md#robot)
SWEEP_RATE = 0.6  # rad/s of the finger along the arc
SWEEP_PAST = 0.2  # rad beyond closed the finger aims at (the joint limit stops the lever at 0)
IK_STEP = 0.15  # rad between IK waypoints along the arc (joint-space lines in between)
SINK_TORSO = 0.38  # m, preferred torso height (the lever is ≈1 m up, beyond a counter)
# IK reference: the arm in its vertical plane, elbow up, lift + elbow + wrist flex = PITCH
# (the planar solution for a lever ≈0.75 m ahead at ≈1 m height with the torso at 0.38 m)
PUSH_REF = np.array([0.0, -0.86, 0.0, 1.29, 0.0, PITCH - 0.43, 0.0])


def _front(cabinet: Furniture) -> tuple[np.ndarray, np.ndarray, float]:
    """Outward unit normal of the cabinet's front face, the lateral axis, and the half depth."""
    n = np.array([round(math.cos(cabinet.yaw)), round(math.sin(cabinet.yaw))], dtype=float)
    lat = np.array([-n[1], n[0]])
    half_depth = (abs(n[0]) * cabinet.size[0] + abs(n[1]) * cabinet.size[1]) / 2.0
    return n, lat, half_depth


def sink_stances(faucet: Faucet, cabinet: Furniture) -> list[tuple[float, float, float]]:
    """Candidate stances (x, y, yaw) in front of the cabinet, facing it, preferred first."""
    n, lat, half_depth = _front(cabinet)
    pivot = np.array(faucet.pivot[:2])
    centre = np.array(cabinet.center)
    depth_in = half_depth - float((pivot - centre) @ n)  # pivot behind the front face
    yaw = math.atan2(-n[1], -n[0])
    out = []
    distance = max(depth_in + BASE_RADIUS + FRONT_GAP, PIVOT_DISTANCE)
    for shift in LATERAL_SHIFTS:
        p = pivot + distance * n + shift * lat
        out.append((float(p[0]), float(p[1]), yaw))
    return out


def _base_fits(world: World, x: float, y: float) -> bool:
    """True when the base disc at (x, y) keeps BASE_CLEARANCE from walls, furniture and door leaves.

    Exact geometry rather than the navigation grid, whose cells and comfort margin reject
    stances the base fits in (a stance is reached by a straight, slow approach).
    """
    plan = world.plan
    need = BASE_RADIUS + BASE_CLEARANCE
    rects = [w.footprint for w in plan.walls] + [f.footprint for f in plan.furniture]
    for r in rects:
        dx = max(r.xmin - x, 0.0, x - r.xmax)
        dy = max(r.ymin - y, 0.0, y - r.ymax)
        if math.hypot(dx, dy) < need:
            return False
    angles = world.handles.door_angles()
    for d in plan.doors:
        a = np.array(d.hinge)
        b = np.array(d.free_edge(angles.get(d.index, d.angle)))
        s = float(np.clip(np.dot([x, y] - a, b - a) / float(np.dot(b - a, b - a)), 0.0, 1.0))
        if float(np.linalg.norm(a + s * (b - a) - [x, y])) < need + d.thickness / 2.0:
            return False
    return True


def _step_back(world: World, pose: tuple[float, float, float]) -> tuple[float, float, float]:
    """The pose the first of UNTUCK_BACK behind `pose` (along its heading) where the base fits."""
    x, y, yaw = pose
    for back in UNTUCK_BACK:
        bx, by = x - back * math.cos(yaw), y - back * math.sin(yaw)
        if _base_fits(world, bx, by):
            return (bx, by, yaw)
    return pose


def _push_rotation(yaw: float) -> np.ndarray:
    """Gripper rotation: approach along the base heading, pitched down; fingers across it, horizontal."""
    h = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    x_axis = math.cos(PITCH) * h + np.array([0.0, 0.0, -math.sin(PITCH)])
    y_axis = np.array([-h[1], h[0], 0.0])
    z_axis = np.cross(x_axis, y_axis)
    return np.stack([x_axis, y_axis, z_axis], axis=1)


def _finger_point(faucet: Faucet, phi: float, z: float) -> np.ndarray:
    """Where the TCP goes for finger angle phi on the contact arc (lever convention)."""
    r = faucet.lever_length - CONTACT_INSET
    yaw = faucet.yaw + phi
    return np.array([faucet.pivot[0] + r * math.cos(yaw), faucet.pivot[1] + r * math.sin(yaw), z])


def _sweep_waypoints(faucet: Faucet, angle: float) -> tuple[list[float], float]:
    """Finger angles from the start (ahead of the lever) to past closed, and the lead angle."""
    r = faucet.lever_length - CONTACT_INSET
    lead = (LEVER_SECTION / 2.0 + FINGER_HALF + CONTACT_CLEAR) / r
    start, end = angle + lead, lead - SWEEP_PAST
    n = max(2, int(math.ceil((start - end) / IK_STEP)) + 1)
    return [float(v) for v in np.linspace(start, end, n)], lead


def _solve_sweep(
    world: World, faucet: Faucet, angle: float, stance: tuple[float, float, float]
) -> tuple[np.ndarray, list[np.ndarray]] | None:
    """IK (torso fixed) for the hover point and every arc waypoint from `stance`, each seeded by the previous."""
    planner = planner_at(world, stance)
    rot = _push_rotation(stance[2])
    phis, _ = _sweep_waypoints(faucet, angle)
    z = faucet.pivot[2]
    first = reach_ik(planner, _finger_point(faucet, phis[0], z), rot, SINK_TORSO, PUSH_REF, fix_torso=True)
    if first is None:
        return None
    hover = near_ik(planner, _finger_point(faucet, phis[0], z + HOVER), rot, first, fix_torso=True)
    if hover is None:
        return None
    sweep = [first]
    for phi in phis[1:]:
        q = near_ik(planner, _finger_point(faucet, phi, z), rot, sweep[-1], fix_torso=True)
        if q is None:  # only another arm branch reaches it: that would swing the arm through the lever
            return None
        sweep.append(q)
    return hover, sweep


def close_sink(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """The CloseSink expert for `call.target` = "faucet:<i>" (see the module docstring)."""
    skill, target = call.skill, call.target
    robot = world.robot
    max_steps = int(robot.cfg.max_steps["CloseSink"])
    i = Target.parse(target).index
    faucet: Faucet = world.plan.faucets[i]
    cabinet: Furniture = world.plan.furniture[faucet.furniture]
    art = world.handles.faucets[i]
    steps = 0

    def fail(reason: str) -> SkillOutcome:
        return SkillOutcome(skill, target, False, reason, steps)

    angle = float(art.get_qpos()[0])
    if sink_closed_success(world, i):
        return SkillOutcome(skill, target, True, "", 0)

    # 1. a stance from which the whole sweep is reachable
    choice = None
    for stance in sink_stances(faucet, cabinet):
        if not _base_fits(world, stance[0], stance[1]):
            continue
        solved = _solve_sweep(world, faucet, angle, stance)
        if solved is not None:
            choice = (stance, solved)
            break
    if choice is None:
        return fail("no_push_stance")
    stance, (q_hover, q_sweep) = choice

    # 2. unfold the arm a step back from the counter (open space), then drive in with it raised
    back_pose = _step_back(world, stance)
    moved = yield from approach_base(world, back_pose, robot.rest_action(), max_steps - steps)
    steps += moved.steps
    if not moved.success:
        return fail(moved.reason)
    planner = planner_at(world)
    path = arm.plan_through(planner, untuck_waypoints(arm.commanded_group(robot), q_hover), gripper=0.0)
    if path is None:
        return fail("arm_plan_failed")
    steps += yield from arm.follow_path(world, path, gripper=0.0)
    moved = yield from approach_base(world, stance, arm_action(robot, q_hover, gripper=0.0), max_steps - steps)
    steps += moved.steps
    if not moved.success:
        return fail(moved.reason)

    # 3. closed fingers down beside the lever, sweep clockwise along the arc (IK from where the base stands)
    solved = _solve_sweep(world, faucet, float(art.get_qpos()[0]), robot.base_pose())
    if solved is None:
        return fail("no_ik")
    q_hover_now, q_sweep = solved
    phis, _ = _sweep_waypoints(faucet, float(art.get_qpos()[0]))
    steps += yield from arm.follow_path(world, [q_hover, q_hover_now, q_sweep[0]], gripper=0.0, speed_scale=0.5)
    # the sweep: joint speed scaled so the finger moves at about SWEEP_RATE along the arc
    widest = max(float(np.max(np.abs(b - a))) for a, b in zip(q_sweep, q_sweep[1:]))
    scale = min(1.0, widest / IK_STEP * SWEEP_RATE / arm.ARM_SPEED)
    steps += yield from arm.follow_path(world, q_sweep, gripper=0.0, speed_scale=scale)
    if steps >= max_steps:
        return fail("timeout")

    # 4. lift clear of the lever, back away from the counter, tuck
    last = q_sweep[-1]
    lift_point = _finger_point(faucet, phis[-1], faucet.pivot[2] + HOVER)
    lift = near_ik(planner_at(world), lift_point, _push_rotation(robot.base_pose()[2]), last, fix_torso=True)
    lift = last if lift is None else lift
    steps += yield from arm.follow_path(world, [last, lift], gripper=0.0, settle=False)
    moved = yield from approach_base(world, _step_back(world, robot.base_pose()), arm_action(robot, lift, gripper=0.0), max(0, max_steps - steps))
    steps += moved.steps
    tucked = yield from tuck_arm(world, gripper=0.0)
    if tucked is None:
        return fail("tuck_failed")
    steps += tucked
    ok = sink_closed_success(world, i)
    return SkillOutcome(skill, target, ok, "" if ok else "still_running", steps)
