"""The Pick expert: a closed-loop top-down parallel-jaw grasp in end-effector space.

Every command is computed at its control step from the state then (the object's pose, the base
pose, the commanded tool-centre point), through `echo_data.skills.servo`, so a perturbed arm or
base is brought back by the next label and a nudged object is followed. The phases are fixed:

1. base: from wherever Navigate handed over (anywhere in its success region, `navigate_success`)
   to the object's interaction pose (`scene.nav.interaction_pose`), holonomic and straight when
   the line is free on the navigation grid, else along the navigation follower's path first;
2. untuck: torso up while the hand moves out of the tuck to APPROACH_TCP, a fixed point beside the
   head (the TCP of Place's carry pose); object-independent;
3. approach and hover: straight to HOVER above the object, jaws across its narrow side, the TCP
   shifted so the wrist camera (mounted 4.5 cm off the TCP's axis) looks straight at the object;
4. descent: straight to the grasp point (fast, then SLOW over the last PRE_GRASP), re-reading the
   object's pose every step;
5. close (binary), lift LIFT_HEIGHT straight up, then the carry pose (`success.CARRY_TCP`).

Started with the object already in the hand (a state a learner reached, asked by
`echo_data.skills.labeller`), it goes straight to phase 5's lift (what is left of it) and carry;
started with the jaws closed on nothing, the untuck and hover phases re-aim and open the jaws.

No weld, no teleport unless the recipe asks for Habitat's magic grasp (`robot.grasp: magic`,
`echo_data.world`): by default the object stays in the hand by friction alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from typing import TYPE_CHECKING

import numpy as np

from echo_data.records import SkillOutcome
from echo_data.robot.ee_control import base_frame
from echo_data.robot.robot import READY_GROUP, yaw_of
from echo_data.scene.objects import object_size
from echo_data.skill_table import approach_skill
from echo_data.skills import servo as S
from echo_data.skills.budget import Budget, SkillFailed
from echo_data.skills.servo import jaw_yaw, top_down
from echo_data.skills.success import CARRY_TCP, object_bottom, pick_success, receptacle_of

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

HOVER = 0.16  # m: TCP above the grasp point while the wrist camera looks at the object
PRE_GRASP = 0.04  # m above the grasp point: the last stretch at the slow speed
LIFT_HEIGHT = 0.15  # m
MIN_LIFT = 0.01  # m: a lift left shorter than this is skipped (an object already lifted)
# m: pads centred this far below the object's top (the palm's underside is 4.2 cm above the TCP;
# pressing a round top against it makes the furby creep to a tilt instead of swing: worse, see
# docs/manipulation_experts.md) ...
GRASP_BELOW_TOP = 0.03
GRASP_ABOVE_BOTTOM = 0.010  # ... but the TCP at least this high above its bottom (tips clear the table)
CLOSE_STEPS = 8
HOVER_STEPS = 3  # control steps held at the hover (the wrist camera's look), fixed
WRIST_CAMERA_OFFSET = 0.045  # m: the wrist camera sits this far along the TCP's z axis (robot/urdf.py)
TORSO_UP = float(READY_GROUP[0])
TORSO_SPEED = 0.15  # m/s
# Out of the tuck the hand goes to a point high on the robot's right, pointing down: the TCP of
# Place's CARRY_DRIVE_GROUP (whose arm covers 0-7 % of the head view against READY's 74 %,
# tests/test_carry_pose.py). The ee map's IK reaches that TCP with another arm shape (its
# redundant degree of freedom pulled towards READY): the elbow rises into the head view, 30-50 %
# of the head pixels measured (docs/manipulation_experts.md).
APPROACH_TCP = (0.214, -0.138, 1.248)  # m, base frame: the TCP of place.CARRY_DRIVE_GROUP ...
APPROACH_JAW = -2.83  # rad: ... and its jaw yaw in the base frame
# Base approach (holonomic, straight): clipped proportional velocity commands.
BASE_SPEED = 0.3  # m/s
BASE_TURN = 0.8  # rad/s
BASE_GAIN = 1.5  # 1/s
STANCE_TOL = 0.02  # m ...
STANCE_YAW_TOL = math.radians(2.0)  # ... and rad: the base is where Pick needs it
BASE_MAX_STEPS = 120
CARRY_ACCEL = 0.5  # m/s^2: the hand's speed-up and slow-down with an object in it (it swings in the pinch)


def grasp_height(bottom: float, sz: float) -> float:
    """TCP z for a top-down grasp of an object of height sz standing at `bottom`."""
    return max(bottom + GRASP_ABOVE_BOTTOM, bottom + sz - GRASP_BELOW_TOP)


def in_world(world: World, pose_in_base: np.ndarray) -> np.ndarray:
    """A base-frame pose in the world, for the base where it stands now (measured)."""
    return base_frame(*world.robot.base_pose()) @ pose_in_base


def anchored(world: World, pose_in_base: np.ndarray) -> Callable[[], np.ndarray]:
    """Goal callable: a pose fixed in the base frame, in the world where the base stands at each call."""
    return lambda: in_world(world, pose_in_base)


def fixed_in_base(world: World, xyz: tuple[float, float, float], yaw_in_base: float) -> Callable[[], np.ndarray]:
    """Goal callable: a top-down TCP pose at `xyz` in the base frame (see `anchored`)."""
    return anchored(world, top_down(*xyz, yaw_in_base))


def pick(world: World, call: SkillCall, spec: EpisodeSpec) -> Generator[np.ndarray, None, SkillOutcome]:
    """Pick expert (generator of `action.ee`; returns the SkillOutcome)."""
    robot = world.robot
    budget = Budget(int(robot.cfg.max_steps[call.skill]))
    name = call.target
    try:
        yield from budget.run(_pick(world, name))
    except SkillFailed as e:
        return SkillOutcome(call.skill, name, False, str(e), budget.steps)
    ok = pick_success(world, name)
    reason = ""
    if not ok:
        reason = "grasp slipped" if robot.holding != name else "not lifted"
    return SkillOutcome(call.skill, name, ok, reason, budget.steps)


class Grasp:
    """The grasp frame on the object where it is now: re-read at every call."""

    def __init__(self, world: World, name: str) -> None:
        self.world, self.name = world, name
        o = world.plan.object_by_name(name)
        self.height = object_size(o.category, o.scale)[2]
        self.turn = 0.0
        # of the two jaw directions across the object's narrow side, the one the arm reaches
        # (the wrist roll has limits), then the one nearer the arm's joints now
        costs = []
        for t in (0.0, math.pi):
            self.turn = t
            costs.append((reach_cost(world, self.pose()), t))
        self.turn = min(costs)[1]

    def yaw(self, turn: float) -> float:
        """The `top_down` yaw of the jaws for a turn from the object's own yaw."""
        return yaw_of(self.world.object_pose(self.name)) + turn

    def pose(self, above: float = 0.0, camera: bool = False) -> np.ndarray:
        """Top-down TCP pose `above` m over the grasp point; `camera` shifts it so the wrist
        camera's axis (not the TCP's) passes through the object."""
        p = self.world.object_pose(self.name)
        yaw = self.yaw(self.turn)
        z = grasp_height(object_bottom(self.world, self.name), self.height) + above
        x, y = float(p.p[0]), float(p.p[1])
        if camera:
            x -= WRIST_CAMERA_OFFSET * math.cos(yaw)
            y -= WRIST_CAMERA_OFFSET * math.sin(yaw)
        return top_down(x, y, z, yaw)


IK_TOL = 0.005  # m (and rad): a pose counts as reachable when the arm's IK gets this close


def reach_cost(world: World, pose_world: np.ndarray) -> float:
    """How well the arm reaches `pose_world` from its commanded joints (torso as commanded):
    the largest joint change if IK arrives within IK_TOL, else 100 + the residual error."""
    robot = world.robot
    ref = robot.applied_action().astype(np.float64)
    ee = robot.ee
    goal_in_base = S.in_base(world, pose_world)
    torso_now = ee.tcp_in_base(float(ref[3]), ref[4:11]) @ np.linalg.inv(ee.tcp_in_torso(ref[4:11]))
    target = np.linalg.inv(torso_now) @ goal_in_base
    q = ref[4:11]
    for _ in range(8):  # damped steps: a few solves to converge from afar
        q = ee.ik(target, q)
    err = float(np.linalg.norm(ee.delta_towards(goal_in_base, arm=q)))
    if err > IK_TOL:
        return 100.0 + err
    return float(np.max(np.abs(q - ref[4:11])))


def _pick(world: World, name: str) -> Generator[np.ndarray, None, None]:
    robot = world.robot
    if robot.holding == name:  # started on a grasp already made (a learner's; the build never starts so)
        yield from lift_and_carry(world, name, LIFT_HEIGHT - lifted(world, name))
        return
    yield from approach_base(world, name)
    # untuck: torso up, hand to the approach point beside the head (object-independent)
    yield from S.servo(world, fixed_in_base(world, APPROACH_TCP, APPROACH_JAW), torso=TORSO_UP, torso_speed=TORSO_SPEED, max_steps=70)
    grasp = Grasp(world, name)
    # approach and hover: the wrist camera centred on the object
    def hover() -> np.ndarray:
        return grasp.pose(HOVER, camera=True)

    if not (yield from S.servo(world, hover, max_steps=60, close=False)):
        # the base was pushed off its stance on the way (the arm touched furniture: measured once in
        # 100 episodes, 6 cm and 8 deg): back to the stance, hand held, and once more
        yield from approach_base(world, name)
        if not (yield from S.servo(world, hover, max_steps=60, close=False)):
            raise SkillFailed("no IK solution")
    yield from S.hold_at(world, hover, HOVER_STEPS, close=False)
    # descent: straight to the grasp point, slow over the last centimetres
    yield from S.servo(world, lambda: grasp.pose(PRE_GRASP), max_steps=30, close=False)
    if not (yield from S.servo(world, grasp.pose, speed=S.SLOW_SPEED, max_steps=30, close=False, settle_tol=0.008)):
        raise SkillFailed("grasp pose not reached")
    yield from S.hold_at(world, grasp.pose(), CLOSE_STEPS, close=True)  # the jaws close where the hand is
    if robot.holding != name:
        raise SkillFailed("grasp missed")
    yield from lift_and_carry(world, name, LIFT_HEIGHT)


def lifted(world: World, name: str) -> float:
    """How far (m) the object's bottom is above the top it stood on."""
    return object_bottom(world, name) - world.plan.furniture[receptacle_of(world, name)].top_z


def lift_and_carry(world: World, name: str, lift_by: float) -> Generator[np.ndarray, None, None]:
    """The held object lifted `lift_by` m straight up (nothing when under MIN_LIFT), then to the carry pose."""
    robot = world.robot
    if lift_by >= MIN_LIFT:
        lift = S.measured_tcp(world)
        lift[2, 3] += lift_by
        yield from S.servo(world, in_world_fixed(world, lift), speed=S.SLOW_SPEED * 2, max_steps=40, close=True, accel=CARRY_ACCEL)
    if robot.holding != name:
        raise SkillFailed("grasp slipped")
    carry = fixed_in_base(world, CARRY_TCP, jaw_yaw(S.in_base(world, S.measured_tcp(world))))
    yield from S.servo(world, carry, max_steps=60, close=True, accel=CARRY_ACCEL)
    yield from S.hold_at(world, carry, 3, close=True)
    if robot.holding != name:
        raise SkillFailed("grasp slipped")


def commanded_pose(world: World) -> Callable[[], np.ndarray]:
    """Goal callable: the TCP pose the arm is commanded to now, fixed in the base frame (to hold the
    arm where it is while the base moves, correcting a perturbed hand)."""
    ref = world.robot.applied_action().astype(np.float64)
    return anchored(world, world.robot.ee.tcp_in_base(float(ref[3]), ref[4:11]))


def in_world_fixed(world: World, pose_world: np.ndarray) -> Callable[[], np.ndarray]:
    """Goal callable of a world pose held fixed relative to the base (the base does not move here)."""
    return anchored(world, S.in_base(world, pose_world))


def approach_base(world: World, name: str) -> Generator[np.ndarray, None, None]:
    """Bring the base from anywhere in Navigate's success region to the object's interaction pose.

    The hand is held where it is commanded (tucked), a perturbed hand brought back. The base stays
    where it is when the object has no free interaction pose. Straight and holonomic when the
    straight line is free on the navigation grid; otherwise the navigation follower drives the
    path first. Closed loop: the stance is re-derived from the object's current position every step.
    """
    from echo_data.scene.nav import interaction_pose
    from echo_data.skills.navigate import current_grid, door_angles

    robot = world.robot
    arm = commanded_pose(world)
    grid = current_grid(world)
    try:
        sx, sy, syaw = interaction_pose(world.plan, name, door_angles=door_angles(world) or None, grid=grid)
    except ValueError:  # no free stance within reach: try from here (the grasp then says whether it reaches)
        return
    p0 = world.object_pose(name).p
    off = (sx - float(p0[0]), sy - float(p0[1]))

    def stance() -> tuple[float, float, float]:
        p = world.object_pose(name).p
        return float(p[0]) + off[0], float(p[1]) + off[1], syaw

    x, y, yaw = robot.base_pose()
    if math.hypot(sx - x, sy - y) <= STANCE_TOL and abs(math.remainder(syaw - yaw, 2 * math.pi)) <= STANCE_YAW_TOL:
        return
    n = max(2, int(math.hypot(sx - x, sy - y) / (grid.resolution / 2)))
    if not all(grid.is_free(x + (sx - x) * t, y + (sy - y) * t) for t in np.linspace(0.0, 1.0, n)):
        yield from drive_path(world, (sx, sy, syaw), arm)
    for _ in range(BASE_MAX_STEPS):
        gx, gy, gyaw = stance()
        x, y, yaw = robot.base_pose()
        ex, ey = gx - x, gy - y
        eyaw = math.remainder(gyaw - yaw, 2 * math.pi)
        if math.hypot(ex, ey) <= STANCE_TOL and abs(eyaw) <= STANCE_YAW_TOL:
            break
        c, s = math.cos(yaw), math.sin(yaw)
        v = np.array([c * ex + s * ey, -s * ex + c * ey]) * BASE_GAIN
        sp = float(np.linalg.norm(v))
        if sp > BASE_SPEED:
            v *= BASE_SPEED / sp
        wz = float(np.clip(BASE_GAIN * eyaw, -BASE_TURN, BASE_TURN))
        yield S.ee_command(world, base=(float(v[0]), float(v[1]), wz), delta=S.delta_to(world, arm))
    yield S.ee_command(world, delta=S.delta_to(world, arm))


def drive_path(world: World, goal: tuple[float, float, float], arm: S.Goal) -> Generator[np.ndarray, None, None]:
    """Drive along the navigation follower's path (`skills.navigate.drive_to`), as `action.ee`:
    its base velocities, the TCP held at `arm` (a goal fixed in the base frame), torso and gripper held."""
    from echo_data.skills.navigate import drive_to

    gen = drive_to(world, goal, int(world.robot.cfg.max_steps[approach_skill().name]))
    try:
        while True:
            a = next(gen)
            yield S.ee_command(world, base=(float(a[0]), float(a[1]), float(a[2])), delta=S.delta_to(world, arm))
    except StopIteration as stop:
        if not stop.value.success:
            raise SkillFailed(stop.value.reason) from None
