"""The OpenDoor expert: a closed-loop controller in end-effector space (yields `action.ee`).

Where it may start: anywhere in Navigate's success region for "door:<i>" (on the swing side,
facing the handle; `echo_data.skills.success.navigate_success`), arm tucked or at READY.

Every command is computed from the state the step starts in (docs/SIMULATION_NOTES.md#door-opening):

1. **stance**: where the base stands when it serves (`stance_here`: the leaf far enough ahead for
   the unfolding arm, the base roughly facing it, the swing on free floor, the grasp within the
   arm's reach; true at Navigate's interaction pose); otherwise the base drives (`echo_data.skills.reach_servo.approach`: straight, or first
   along Navigate's grid path, arm held, when a wall corner is in the way) to the grasp stance
   for the door's *current* hinge angle: 0.88 m from the swing-side handle bar along the leaf
   normal, 0.3 m towards the hinge, facing the leaf — the first of `STANCES` whose swing stays on free floor and whose grasp the
   arm reaches (the robot's own IK). A fixed order, so every episode of a door takes the same one.
2. **untuck** on the straight part of that drive and at the stance: a straight Cartesian move
   of the TCP to READY (the carry pose, 0.27 m ahead of the base at 1.15 m; on the way the arm
   reaches ≤ 0.53 m ahead): at a stance the leaf is ≥ 0.75 m from the base centre, so there is room.
3. **pre-grasp**: the TCP goes to `PREGRASP_BACK` in front of the bar (the bar's pose read from
   the hinge angle each step), approach axis into the leaf, fingers along it;
4. **approach**: straight in at `SLOW_SPEED` (a hand stopped short by a jaw on the bar, within
   `JAW_SLACK`, still closes); then the fingers close until both touch the bar (the world then
   holds the leaf in the closed gripper, `echo_data.world`);
5. **swing**: the base turns about the hinge with the leaf: a feed-forward rotation rate about
   the hinge (ramped over `SWING_RAMP`) plus feedback that keeps the base where the grasp put it
   relative to the leaf *at its current angle*; the arm servoes its TCP back to the grasp pose
   in the base frame (a perturbation of the arm is undone). Until the hinge is `OPEN_MARGIN`
   beyond `Door.open_threshold` and at rest. A leaf that stops following (a blocked door, a lost
   grip) ends the skill with "lost_handle". Started with the leaf already held (a state a learner
   reached, asked by `echo_data.skills.labeller`), the expert goes straight on with the swing.
6. **release, retreat, tuck**: the gripper opens (the world lets the leaf go), the base backs
   `BACK_OFF` straight away from the bar, the TCP returns to READY, then folds into the tuck
   (`echo_data.skills.servo.tuck`, as Place ends: a drive after the skill carries the arm
   inside the base's footprint, the one the navigation grid is inflated for).

No random choices and no motion planner: two episodes of the same door from the same start take the same path.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING, Any

import numpy as np

from echo_data.floorplan import Door
from echo_data.records import SkillOutcome
from echo_data.scene.door_handle import door_handle_world
from echo_data.skills.reach_servo import CONTACT, TRANSIT, TUCK_TURN, Pose2, Steps, approach, arm_reaches, retreat, to_ready, wrap
from echo_data.skills.servo import SLOW_SPEED, ee_command, grip, measured_tcp, servo, step_towards, tuck
from echo_data.skills.success import DOOR_REST_QVEL, door_open_success
from echo_data.target import Target

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

# Grasp stances, preferred first: (distance from the bar along the leaf normal, shift along the
# leaf towards its free edge). Standing 0.3 m towards the hinge keeps the swing radius small
# (≈1.2 m) and the arm well inside its limits.
STANCES = ((0.88, -0.3), (0.95, -0.3), (0.88, -0.15), (0.95, -0.15), (0.95, 0.0), (0.8, -0.3))
PREGRASP_BACK = 0.07  # m, pre-grasp in front of the bar (4 cm clear of the open fingers)
GRASP_TORSO = 0.15  # m, torso height for a handle at ≈1 m (the shoulder level with the bar)
PREGRASP_SPEED = 0.25  # m/s of the TCP from READY to the pre-grasp
JAW_SLACK = 0.03  # m, TCP to the bar's centre within which the open jaws (10 cm) still straddle the 2.4 cm bar
CLOSE_STEPS = 8  # control steps the fingers have to close on the bar
SWING_RATE = 0.35  # rad/s hinge rate while the base swings
SWING_RAMP = 1.0  # s, rate ramp at the start of the swing (docs/SIMULATION_NOTES.md#door-opening)
SWING_SLOWDOWN = 0.15  # rad before the goal over which the rate ramps down (no overshoot to pull back)
K_POSE = 2.0  # 1/s, base pose feedback during the swing
OPEN_MARGIN = 0.12  # rad beyond the open threshold before letting go
STALL_STEPS = 15  # the leaf must gain STALL_GAIN within this many swing steps ...
STALL_GAIN = 0.02  # rad ... or the grip is lost / the door blocked
RELEASE_STEPS = 4  # control steps for the fingers to open
BACK_OFF = 0.15  # m the base backs away after letting go
HERE_MIN_DEPTH = 0.75  # m, the leaf ahead of the base centre for a stance taken where the base stands (STANCES: >= 0.8)
HERE_MAX_YAW = math.radians(30.0)  # off facing the leaf, for a stance where the base stands
# Step limits per phase (the skill's own limit, recipe robot.max_steps.OpenDoor, bounds the sum).
DRIVE_STEPS, PREGRASP_STEPS, APPROACH_STEPS = 160, 60, 50


def _swing_frame(door: Door) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of the closed leaf (hinge -> free edge) and of its swing-side normal."""
    u = np.array([math.cos(door.closed_yaw), math.sin(door.closed_yaw)])
    n = door.open_sign * np.array([-u[1], u[0]])
    return u, n


def _rotate_about(p: np.ndarray, centre: np.ndarray, ang: float) -> np.ndarray:
    c, s = math.cos(ang), math.sin(ang)
    d = p - centre
    return centre + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])


def _facing(door: Door, q: float) -> float:
    """The yaw that faces the leaf (against its swing-side normal) at hinge angle q."""
    _, n = _swing_frame(door)
    return wrap(math.atan2(-n[1], -n[0]) + door.open_sign * q)


def door_stances(door: Door, q: float = 0.0) -> list[Pose2]:
    """Candidate grasp stances (x, y, yaw) for the door at hinge angle q, preferred first."""
    u, n = _swing_frame(door)
    handle = door_handle_world(door, 0.0, door.open_sign)[:2]
    out = []
    for dist, shift in STANCES:
        p = _rotate_about(handle + dist * n + shift * u, np.asarray(door.hinge), door.open_sign * q)
        out.append((float(p[0]), float(p[1]), _facing(door, q)))
    return out


def _swing_is_free(world: World, door: Door, stance: Pose2, q0: float, q1: float) -> bool:
    """True when the base stays on free floor while it turns about the hinge from q0 to q1."""
    grid = world.nav
    hinge = np.asarray(door.hinge)
    for q in np.linspace(0.0, q1 - q0, 12):
        p = _rotate_about(np.asarray(stance[:2]), hinge, door.open_sign * float(q))
        if not grid.is_free(float(p[0]), float(p[1])):
            return False
    return True


def swing_goal(door: Door) -> float:
    """The hinge angle the swing ends at: `OPEN_MARGIN` past the open threshold, short of the stop."""
    return min(door.open_threshold + OPEN_MARGIN, door.max_angle - 0.02)


def stance_here(world: World, door: Door, pose: Pose2, q0: float, q1: float) -> bool:
    """True when the base may grasp and swing from `pose` as it stands: the leaf at least
    `HERE_MIN_DEPTH` ahead of the base centre (room for the unfolding arm), at most
    `HERE_MAX_YAW` off facing the leaf, the swing on free floor and the grasp within the arm's
    reach. Why: a demonstration whose base drives to one fixed stance teaches a learner one
    base-frame reach, and a learner that stops its base elsewhere then grasps the air beside
    the bar (docs/learners.md, "OpenDoor stands where it is"); from where it stands the arm aims
    at the bar it sees."""
    facing = _facing(door, q0)
    ahead = np.array(pose[:2]) - door_handle_world(door, q0, door.open_sign)[:2]  # from the bar to the base
    if float(ahead @ [-math.cos(facing), -math.sin(facing)]) < HERE_MIN_DEPTH or abs(wrap(pose[2] - facing)) > HERE_MAX_YAW:
        return False
    return _serves(world, door, pose, q0, q1)


def _serves(world: World, door: Door, stance: Pose2, q0: float, q1: float) -> bool:
    """True when from `stance` the swing (q0 to q1) stays on free floor and the arm reaches the grasp."""
    return _swing_is_free(world, door, stance, q0, q1) and arm_reaches(world, stance, grasp_pose(door, q0), GRASP_TORSO)


def grasp_pose(door: Door, q: float, back: float = 0.0) -> np.ndarray:
    """World TCP pose (4x4) grasping the swing-side bar at hinge angle q, `back` m in front of it:
    approach axis into the leaf, fingers closing along it, horizontal.

    Of the two such poses (the jaws are symmetric under a half turn about the approach axis)
    the one whose finger axis points to the robot's right, as READY's does: from READY it is a
    quarter turn about one axis. (The other is a half turn away, whose direction a tiny heading
    change flips: one wrist branch or the other, the multimodality this expert is rid of.)"""
    yaw = door.leaf_yaw(q)
    u = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    n = door.open_sign * np.array([-u[1], u[0], 0.0])
    x_axis = -n  # the robot faces -n at its stance
    right = np.array([x_axis[1], -x_axis[0], 0.0])
    y_axis = u if float(u @ right) > 0 else -u
    z_axis = np.cross(x_axis, y_axis)
    m = np.eye(4)
    m[:3, :3] = np.stack([x_axis, y_axis, z_axis], axis=1)
    m[:3, 3] = door_handle_world(door, q, door.open_sign) - back * x_axis
    return m


def _hinge(art: Any) -> float:
    return float(art.get_qpos()[0])


def _swing(world: World, door: Door, art: Any, q_goal: float, max_steps: int) -> Generator[np.ndarray, None, str | None]:
    """Turn the base about the hinge as one rigid body with the held leaf until the hinge is at
    `q_goal` and at rest (see the module docstring, phase 5); None on success, else a reason."""
    robot = world.robot
    dt = 1.0 / robot.cfg.control_hz
    hinge = np.asarray(door.hinge)
    x0, y0, yaw0 = robot.base_pose()
    p0 = np.array([x0, y0])
    q0 = _hinge(art)
    ref = robot.applied_action().astype(np.float64)
    torso = float(ref[3])
    tcp_grasp = robot.ee.tcp_in_base(torso, ref[4:11])  # held fixed in the base frame while swinging
    history = [q0]
    for step in range(max_steps):
        if not world.holding_door:
            return "lost_handle"
        q = _hinge(art)
        moving = q < q_goal
        if moving and len(history) > STALL_STEPS and q - history[-STALL_STEPS - 1] < STALL_GAIN:
            return "lost_handle"
        if not moving and abs(float(art.get_qvel()[0])) < DOOR_REST_QVEL:
            return None
        # ramped up over SWING_RAMP, down over the last SWING_SLOWDOWN before the goal
        ramp = min(1.0, (step + 1) * dt / SWING_RAMP, max(0.2, (q_goal - q) / SWING_SLOWDOWN))
        rate = SWING_RATE * ramp if moving else 0.0
        ang = door.open_sign * (q - q0)  # where the base belongs with the leaf at its angle now
        p_des = _rotate_about(p0, hinge, ang)
        x, y, yaw = robot.base_pose()
        w_ff = door.open_sign * rate
        rel = np.array([x, y]) - hinge
        v_world = w_ff * np.array([-rel[1], rel[0]]) + K_POSE * (p_des - [x, y])
        wz = w_ff + K_POSE * wrap(yaw0 + ang - yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        base = (c * v_world[0] + s * v_world[1], -s * v_world[0] + c * v_world[1], wz)
        arm = step_towards(robot.ee.delta_towards(tcp_grasp, torso=torso), 0.2, 0.8, dt)
        yield ee_command(world, base=base, torso=torso, delta=arm, close=True)
        history.append(_hinge(art))
    return "timeout"


def _close_on_bar(world: World) -> Generator[np.ndarray, None, bool]:
    """Close the fingers, arm held, until the world holds the leaf (both fingers on the bar)."""
    for _ in range(CLOSE_STEPS):
        yield ee_command(world, torso=GRASP_TORSO, close=True)
        if world.holding_door:
            return True
    return False


def _grasp_bar(world: World, door: Door, art: Any, target: str, q_start: float, q_goal: float) -> Generator[np.ndarray, None, str | None]:
    """Phases 1-4 of the module docstring: stance, untuck, pre-grasp, straight in, close on the
    bar; None once the world holds the leaf, else the reason it failed."""
    robot = world.robot
    # 1. the stance: where the base stands when it serves, else the first of STANCES whose swing
    # is free and whose grasp the arm reaches
    if not stance_here(world, door, robot.base_pose(), q_start, q_goal):
        choice = next((k for k, stance in enumerate(door_stances(door, q_start)) if _serves(world, door, stance, q_start, q_goal)), None)
        if choice is None:
            return "no_grasp_stance"
        if not (yield from approach(world, target, lambda: door_stances(door, _hinge(art))[choice], max_steps=DRIVE_STEPS, close=False)):
            return "stance_not_reached"

    # 2.-4. untuck, pre-grasp, straight in, close on the bar
    if not (yield from to_ready(world, close=False)):
        return "untuck_failed"
    if not (yield from servo(world, lambda: grasp_pose(door, _hinge(art), PREGRASP_BACK), speed=PREGRASP_SPEED, torso=GRASP_TORSO, max_steps=PREGRASP_STEPS, close=False,
                                **TRANSIT)):
        return "pregrasp_not_reached"
    at_bar = yield from servo(world, lambda: grasp_pose(door, _hinge(art)), speed=SLOW_SPEED, torso=GRASP_TORSO, max_steps=APPROACH_STEPS,
                              close=False, **CONTACT)
    # a jaw resting on the bar stops the hand short (seen under DART noise: 2 cm): close anyway
    # when the open jaws still straddle it; the grasp test below decides
    if not at_bar and float(np.linalg.norm(measured_tcp(world)[:3, 3] - grasp_pose(door, _hinge(art))[:3, 3])) > JAW_SLACK:
        return "handle_not_reached"
    if not (yield from _close_on_bar(world)):
        return "grasp_failed"
    return None


def open_door(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """The OpenDoor expert for `call.target` = "door:<i>" (see the module docstring)."""
    skill, target = call.skill, call.target
    robot = world.robot
    max_steps = int(robot.cfg.max_steps[skill])
    i = Target.parse(target).index
    door: Door = world.plan.doors[i]
    art = world.handles.doors[i]
    st = Steps()

    def fail(reason: str) -> SkillOutcome:
        return SkillOutcome(skill, target, False, reason, st.n)

    q_start = _hinge(art)
    q_goal = swing_goal(door)
    if q_start >= door.open_threshold and not world.holding_door:
        ok = door_open_success(world, i)
        return SkillOutcome(skill, target, ok, "" if ok else "door_moving", 0)

    # (started on a leaf already in the hand, a state a learner reached, it goes on swinging)
    if not world.holding_door:
        reason = yield from st.run(_grasp_bar(world, door, art, target, q_start, q_goal))
        if reason is not None:
            return fail(reason)

    # 5. swing about the hinge with the leaf
    reason = yield from st.run(_swing(world, door, art, q_goal, max_steps - st.n))
    if reason is not None:
        return fail(reason)

    # 6. let go, back off, stow at READY, tuck
    yield from st.run(grip(world, close=False, steps=RELEASE_STEPS))
    x, y, yaw = robot.base_pose()
    back = (x - BACK_OFF * math.cos(yaw), y - BACK_OFF * math.sin(yaw), yaw)
    if not (yield from st.run(retreat(world, back, close=False))):
        return fail("stow_failed")
    if not (yield from st.run(tuck(world, close=False, turn=TUCK_TURN))):
        return fail("tuck_failed")
    ok = door_open_success(world, i)
    return SkillOutcome(skill, target, ok, "" if ok else "not_open", st.n)
