"""The CloseSink expert: a closed-loop controller in end-effector space (yields `action.ee`).

Where it may start: anywhere in Navigate's success region for "faucet:<i>" (in front of the sink
cabinet, facing the lever; `echo_data.skills.success.navigate_success`), arm tucked or at READY.

The lever turns about the vertical axis through `Faucet.pivot` and opens counter-clockwise
(`echo_data.scene.articulated`). Every command is computed from the state the step starts in
(docs/SIMULATION_NOTES.md#closing-a-faucet):

1. **stance**: on the cabinet's front normal through the lever pivot, at least `PIVOT_DISTANCE`
   from the pivot and `FRONT_GAP` from the cabinet face, facing the cabinet, shifted sideways if
   needed — the first of `sink_stances` where the base fits and the arm reaches the push (the
   robot's own IK). The base first drives (`echo_data.skills.reach_servo.approach`: straight,
   or first along Navigate's grid path, arm held, when a wall corner is in the way) to a pose
   `UNTUCK_BACK` behind it, where the arm has room;
2. **untuck** on the straight part of that drive and there: a straight Cartesian move of the
   TCP to READY, fingers closing;
3. **drive in** to the stance with the arm at READY (high above the counter);
4. **hover** above the lever's opening side (the finger block `lead` ahead of the lever on the
   contact arc, `CONTACT_INSET` inside its tip, `HOVER` above it; the lever angle read each step),
   gripper pitched down; **descend** straight to the lever's height at `DESCEND_SPEED`;
5. **push**: each step the finger's goal on the arc is one step (`SWEEP_RATE`) clockwise of the
   nearer of where it is commanded and where the lever now is plus the lead, down to
   `SWEEP_PAST` beyond closed (the joint limit stops the lever at 0, the water stops);
6. **lift** `HOVER`, **back off** to the untuck pose, **stow** at READY, **tuck** (as OpenDoor
   and Place end: `echo_data.skills.servo.tuck`).

No random choices and no motion planner: two episodes of the same sink take the same path.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.floorplan import Faucet, Furniture
from echo_data.records import SkillOutcome
from echo_data.robot.ee_control import base_frame
from echo_data.robot.robot import READY_GROUP
from echo_data.scene.articulated import LEVER_SECTION
from echo_data.skills.reach_servo import CONTACT, TRANSIT, TUCK_TURN, Pose2, Steps, approach, arm_reaches, drive, retreat, to_ready
from echo_data.skills.servo import ee_command, in_base, servo, step_towards, tuck
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
CONTACT_CLEAR = 0.006  # m between the finger block and the lever before the push
CONTACT_INSET = 0.025  # m from the lever tip to the contact point
HOVER = 0.08  # m above the lever before descending
UNTUCK_BACK = (0.35, 0.25, 0.15)  # m back from the stance where the arm unfolds (the first where the base fits)
SWEEP_RATE = 0.6  # rad/s of the finger along the arc
SWEEP_PAST = 0.2  # rad beyond closed the finger aims at (the joint limit stops the lever at 0)
SINK_TORSO = float(READY_GROUP[0])  # m: READY's torso (the lever is ≈1 m up, beyond a counter)
HOVER_SPEED = 0.3  # m/s of the TCP from READY to above the lever
DESCEND_SPEED = 0.1  # m/s straight down beside the lever (the finger block keeps CONTACT_CLEAR from it)
# Step limits per phase (the skill's own limit, recipe robot.max_steps.CloseSink, bounds the sum).
DRIVE_STEPS, HOVER_STEPS, DESCEND_STEPS, PUSH_STEPS, LIFT_STEPS = 90, 50, 30, 60, 20


def _front(cabinet: Furniture) -> tuple[np.ndarray, np.ndarray, float]:
    """Outward unit normal of the cabinet's front face, the lateral axis, and the half depth."""
    n = np.array([round(math.cos(cabinet.yaw)), round(math.sin(cabinet.yaw))], dtype=float)
    lat = np.array([-n[1], n[0]])
    half_depth = (abs(n[0]) * cabinet.size[0] + abs(n[1]) * cabinet.size[1]) / 2.0
    return n, lat, half_depth


def sink_stances(faucet: Faucet, cabinet: Furniture) -> list[Pose2]:
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


def _step_back(world: World, pose: Pose2) -> Pose2:
    """The pose the first of UNTUCK_BACK behind `pose` (along its heading) where the base fits."""
    x, y, yaw = pose
    for back in UNTUCK_BACK:
        bx, by = x - back * math.cos(yaw), y - back * math.sin(yaw)
        if _base_fits(world, bx, by):
            return (bx, by, yaw)
    return pose


def _lead(faucet: Faucet) -> float:
    """Angle on the contact arc between the lever's axis and the finger block's centre, touching."""
    return (LEVER_SECTION / 2.0 + FINGER_HALF + CONTACT_CLEAR) / (faucet.lever_length - CONTACT_INSET)


def push_pose(faucet: Faucet, phi: float, yaw: float, lift: float = 0.0) -> np.ndarray:
    """World TCP pose (4x4) with the finger block at angle phi on the contact arc (lever
    convention), `lift` m above the lever: approach along the base heading `yaw` pitched down
    by PITCH, fingers across it, horizontal, the finger axis to the robot's right as at READY
    (from READY a small pitch, not a half turn whose direction a tiny heading change flips)."""
    h = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    x_axis = math.cos(PITCH) * h + np.array([0.0, 0.0, -math.sin(PITCH)])
    y_axis = np.array([h[1], -h[0], 0.0])
    m = np.eye(4)
    m[:3, :3] = np.stack([x_axis, y_axis, np.cross(x_axis, y_axis)], axis=1)
    r = faucet.lever_length - CONTACT_INSET
    a = faucet.yaw + phi
    m[:3, 3] = (faucet.pivot[0] + r * math.cos(a), faucet.pivot[1] + r * math.sin(a), faucet.pivot[2] + lift)
    return m


def _commanded_phi(world: World, faucet: Faucet) -> float:
    """The arc angle (lever convention) of the commanded TCP about the lever pivot."""
    robot = world.robot
    ref = robot.applied_action().astype(np.float64)
    tcp = base_frame(*robot.base_pose()) @ robot.ee.tcp_in_base(float(ref[3]), ref[4:11])
    a = math.atan2(tcp[1, 3] - faucet.pivot[1], tcp[0, 3] - faucet.pivot[0]) - faucet.yaw
    return math.remainder(a, 2.0 * math.pi)


def _push(world: World, faucet: Faucet, art: Any, max_steps: int) -> Generator[np.ndarray, None, bool]:
    """Sweep the closed finger block clockwise along the arc, pushing the lever to its closed
    limit (phase 5 of the module docstring); True once the finger has reached the end and settled."""
    robot = world.robot
    dt = 1.0 / robot.cfg.control_hz
    lead = _lead(faucet)
    end = lead - SWEEP_PAST
    for _ in range(max_steps):
        lever = float(art.get_qpos()[0])
        phi = max(end, min(_commanded_phi(world, faucet), lever + lead) - SWEEP_RATE * dt)
        goal = push_pose(faucet, phi, robot.base_pose()[2])
        d = robot.ee.delta_towards(in_base(world, goal), torso=SINK_TORSO)
        if phi <= end + 1e-3 and float(np.linalg.norm(d[:3])) < CONTACT["pos_tol"]:
            return True
        yield ee_command(world, torso=SINK_TORSO, delta=step_towards(d, 0.2, 0.8, dt), close=True)
    return False


def close_sink(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """The CloseSink expert for `call.target` = "faucet:<i>" (see the module docstring)."""
    skill, target = call.skill, call.target
    robot = world.robot
    i = Target.parse(target).index
    faucet: Faucet = world.plan.faucets[i]
    cabinet: Furniture = world.plan.furniture[faucet.furniture]
    art = world.handles.faucets[i]
    st = Steps()

    def fail(reason: str) -> SkillOutcome:
        return SkillOutcome(skill, target, False, reason, st.n)

    if sink_closed_success(world, i):
        return SkillOutcome(skill, target, True, "", 0)

    # 1. a stance where the base fits and the arm reaches the start and the end of the push
    lead = _lead(faucet)
    angle = float(art.get_qpos()[0])
    stance = next(
        (s for s in sink_stances(faucet, cabinet) if _base_fits(world, s[0], s[1])
         and arm_reaches(world, s, push_pose(faucet, angle + lead, s[2]), SINK_TORSO)
         and arm_reaches(world, s, push_pose(faucet, lead - SWEEP_PAST, s[2]), SINK_TORSO)),
        None,
    )
    if stance is None:
        return fail("no_push_stance")
    back_pose = _step_back(world, stance)

    # 2.-3. unfold the arm on the way to a step back from the counter (open space), then drive in with it at READY
    if not (yield from st.run(approach(world, target, back_pose, max_steps=DRIVE_STEPS, close=True))):
        return fail("stance_not_reached")
    if not (yield from st.run(to_ready(world, close=True))):
        return fail("untuck_failed")
    if not (yield from st.run(drive(world, stance, max_steps=DRIVE_STEPS, close=True))):
        return fail("stance_not_reached")

    # 4. above the lever's opening side, then straight down beside it
    def start(lift: float) -> np.ndarray:
        return push_pose(faucet, float(art.get_qpos()[0]) + lead, robot.base_pose()[2], lift)

    if not (yield from st.run(servo(world, lambda: start(HOVER), speed=HOVER_SPEED, torso=SINK_TORSO, max_steps=HOVER_STEPS, close=True,
                                     **TRANSIT))):
        return fail("hover_not_reached")
    if not (yield from st.run(servo(world, lambda: start(0.0), speed=DESCEND_SPEED, torso=SINK_TORSO, max_steps=DESCEND_STEPS, close=True,
                                     **CONTACT))):
        return fail("lever_not_reached")

    # 5. push the lever closed along its arc
    pushed = yield from st.run(_push(world, faucet, art, PUSH_STEPS))
    if not pushed:
        return fail("push_timeout")

    # 6. lift clear, back away from the counter, stow at READY, tuck
    phi_end = _commanded_phi(world, faucet)
    yield from st.run(servo(world, lambda: push_pose(faucet, phi_end, robot.base_pose()[2], HOVER), torso=SINK_TORSO, max_steps=LIFT_STEPS, close=True,
                           **TRANSIT))
    if not (yield from st.run(retreat(world, _step_back(world, robot.base_pose()), close=True))):
        return fail("stow_failed")
    if not (yield from st.run(tuck(world, close=True, turn=TUCK_TURN))):
        return fail("tuck_failed")
    ok = sink_closed_success(world, i)
    return SkillOutcome(skill, target, ok, "" if ok else "still_running", st.n)
