"""The OpenDoor expert: grasp the door handle, swing the base about the hinge, let go.

Where it wants to start: on the door's swing side (the side the leaf opens towards), facing
the closed leaf, roughly in front of the handle — `interaction_pose(plan, "door:<i>")` of
`echo_data.scene.nav` (0.8 m from the leaf, facing the swing-side handle) is fine. The
expert first drives the base itself (holonomic, a few decimetres at most) to its grasp
stance: 0.88 m from the swing-side handle bar along the leaf normal and 0.3 m towards the
hinge, facing the leaf (`STANCES`), chosen among a few stances so that the whole swing stays on free floor.

Then (FINDINGS: 19-20/20 this way): reach a pre-grasp 7 cm in front of the bar with a
planned arm motion, move in, close the fingers on the vertical bar; once both fingers touch
the bar the grasp is completed by a stiff drive between gripper and leaf (a heavy door
otherwise slips out of a parallel gripper). The base then turns about the hinge as one rigid
body with the leaf — constant robot-frame velocity for a rigid rotation, ramped over ≈1 s,
with feedback on the pose error — while the arm holds still, until the hinge is
`OPEN_MARGIN` beyond `Door.open_threshold`; the door is let go at rest, the base backs off
and the arm tucks.
"""

from __future__ import annotations

import math
from collections.abc import Generator

import mplib
import numpy as np
import sapien
from transforms3d.quaternions import mat2quat

from echo_data.records import ACTION_DIM, SkillOutcome
from echo_data.robot import urdf as robot_urdf
from echo_data.scene.articulated import door_handle_world
from echo_data.scene.floorplan import Door

# Grasp stances, preferred first: (distance from the bar along the leaf normal, shift along the
# leaf towards its free edge). Standing 0.3 m towards the hinge keeps the swing radius small
# (≈1.2 m) and the arm well inside its limits (a head-on reach at < 0.9 m needs the shoulder
# beyond its lift limit).
STANCES = ((0.88, -0.3), (0.95, -0.3), (0.88, -0.15), (0.95, -0.15), (0.95, 0.0), (0.8, -0.3))
PREGRASP_BACK = 0.07  # m, pre-grasp in front of the bar (4 cm clear of the open fingers)
GRASP_TORSO = 0.15  # m, preferred torso height for a handle at ≈1 m
SWING_RATE = 0.35  # rad/s hinge rate while the base swings
SWING_RAMP = 1.0  # s, velocity ramp at the start of the swing (FINDINGS)
K_POSE = 2.0  # 1/s, base pose feedback during the swing
OPEN_MARGIN = 0.12  # rad beyond the open threshold before letting go
REST_QVEL = 0.05  # rad/s: a door slower than this is at rest
LOST_GRIP = 0.35  # rad between commanded and measured hinge angle: the handle slipped
BACK_OFF = 0.15  # m the base backs away after letting go

# ---------------------------------------------------------------------------------------------
# Arm and base helpers shared with the CloseSink expert (mplib on the fixed-base arm URDF).

ARM_GROUP = ("torso_lift_joint",) + robot_urdf.ARM_JOINTS  # the planner's move group, in order
REACH_REF = np.array([0.0, -1.0, 0.0, 1.6, 0.0, -0.6, 0.0])  # arm bent forward: IK reference
ARM_SPEED = 1.1  # rad/s, fastest joint on a straight joint-space move (URDF limits 1.26-2.27)
# Via poses between the tuck and a reach (arm raised beside the torso), torso up: straight
# joint lines through them are collision free where RRT needs seconds next to a counter.
UNTUCK_VIAS = (np.array([1.32, -0.5, -0.2, 1.72, 0.0, 1.66, 0.0]), np.array([1.32, -0.8, 0.0, 1.5, 0.0, 1.0, 0.0]))
VIA_TORSO = 0.38
APPROACH_SPEED = 0.4  # m/s, final base approach
APPROACH_MIN_SPEED = 0.04  # m/s, so the last centimetres do not crawl
APPROACH_TURN = 0.8  # rad/s
APPROACH_TOL = 0.015  # m
APPROACH_YAW_TOL = math.radians(1.5)
_PLANNER: list[mplib.Planner] = []


def wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def planner() -> mplib.Planner:
    """The process-wide mplib planner of the fixed-base arm (building one costs ≈0.1 s)."""
    if not _PLANNER:
        _PLANNER.append(
            mplib.Planner(
                urdf=str(robot_urdf.ARM_URDF_PATH), srdf=str(robot_urdf.ARM_SRDF_PATH), move_group=robot_urdf.EE_LINK
            )
        )
    return _PLANNER[0]


def _planner_qpos(robot: object) -> np.ndarray:
    """The robot's joint positions in the planner's joint order."""
    q = robot.articulation.get_qpos()  # type: ignore[attr-defined]
    return np.array([q[robot.joint_index[n]] for n in planner().user_joint_names], dtype=np.float64)  # type: ignore[attr-defined]


def _group_slots() -> list[int]:
    names = planner().user_joint_names
    return [names.index(n) for n in ARM_GROUP]


def _set_base(base: tuple[float, float, float]) -> None:
    x, y, yaw = base
    planner().set_base_pose(mplib.Pose([x, y, 0.0], [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)]))


def set_obstacles(world: object, around: tuple[float, float], radius: float = 2.0) -> int:
    """Give the planner the apartment near `around` as boxes: floor, walls, furniture, door leaves.

    Door leaves are placed at their current hinge angle; their handles and faucet levers are
    left out (the gripper must touch them). FINDINGS: plan only against nearby obstacles.
    Returns how many boxes were set.
    """
    from mplib.collision_detection import fcl

    pl = planner()
    for name in pl.planning_world.get_object_names():
        pl.planning_world.remove_object(name)
    plan = world.plan  # type: ignore[attr-defined]
    cx, cy = around
    boxes: list[tuple[tuple[float, float, float], tuple[float, float, float], float]] = []
    boxes.append(((cx, cy, -0.05), (2 * radius, 2 * radius, 0.1), 0.0))  # floor
    for w in plan.walls:
        r = w.footprint
        boxes.append(((*r.center, w.height / 2.0), (*r.size, w.height), 0.0))
    for f in plan.furniture:
        r = f.footprint
        boxes.append(((*r.center, f.size[2] / 2.0), (*r.size, f.size[2]), 0.0))
    angles = world.handles.door_angles() if getattr(world, "handles", None) is not None else {}  # type: ignore[attr-defined]
    for d in plan.doors:
        yaw = d.leaf_yaw(angles.get(d.index, d.angle))
        mid = (d.hinge[0] + d.width / 2.0 * math.cos(yaw), d.hinge[1] + d.width / 2.0 * math.sin(yaw))
        boxes.append(((*mid, d.height / 2.0), (d.width, d.thickness, d.height), yaw))
    n = 0
    for (x, y, z), (sx, sy, sz), yaw in boxes:
        # distance from `around` to the box's footprint (rotation ignored: a conservative cut)
        half = max(sx, sy) / 2.0 if yaw else None
        dx = max(abs(x - cx) - (half if half is not None else sx / 2.0), 0.0)
        dy = max(abs(y - cy) - (half if half is not None else sy / 2.0), 0.0)
        if math.hypot(dx, dy) > radius:
            continue
        pose = mplib.Pose([x, y, z], [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])
        pl.planning_world.add_object(f"obstacle_{n}", fcl.CollisionObject(fcl.Box(sx, sy, sz), pose))
        n += 1
    return n


def solve_ik(
    world: object,
    position: np.ndarray,
    rotation: np.ndarray,
    base: tuple[float, float, float] | None = None,
    torso: float | None = None,
    seed: np.ndarray | None = None,
    restarts: int = 40,
    ref: np.ndarray = REACH_REF,
    lock_torso: bool = False,
) -> np.ndarray | None:
    """Torso + 7 arm joints that put the gripper's TCP at a world pose, or None.

    `base` is where the base will stand (default: where it is). The search starts from
    `seed` (smooth sequences: the first answer near it wins) or from a forward-bent arm
    (`ref`, default `REACH_REF`, with torso `torso`), then from fixed pseudo-random restarts; among the answers
    within joint limits and free of self-collision it returns the one closest to the start.
    `lock_torso` keeps the torso at its start value (CLIK otherwise likes to push it to a limit).
    Deterministic (mplib's own IK draws unseeded restarts).
    """
    robot = world.robot  # type: ignore[attr-defined]
    x, y, yaw = robot.base_pose() if base is None else base
    c, s = math.cos(yaw), math.sin(yaw)
    rz_inv = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    p_base = rz_inv @ (np.asarray(position, dtype=np.float64) - [x, y, 0.0])
    r_base = rz_inv @ np.asarray(rotation, dtype=np.float64)
    goal = mplib.Pose(p_base, mat2quat(r_base))
    pl = planner()
    slots = _group_slots()
    start = _planner_qpos(robot)
    if seed is not None:
        start[slots] = seed
    else:
        start[slots[0]] = robot.torso() if torso is None else torso  # type: ignore[attr-defined]
        start[slots[1:]] = ref
    mask = np.ones(len(start), dtype=bool)
    mask[slots[1 if lock_torso else 0 :]] = False
    _set_base((x, y, yaw))  # collision checks against the obstacles happen in the world frame
    lo, hi = pl.joint_limits[slots, 0], pl.joint_limits[slots, 1]
    rng = np.random.default_rng(0)
    link = pl.link_name_2_idx[pl.move_group]
    best, best_dist = None, math.inf
    for k in range(restarts + 1):
        q0 = start.copy()
        if k > 0:
            q0[slots] = rng.uniform(lo, hi)
            if lock_torso:
                q0[slots[0]] = start[slots[0]]
        q, ok, _ = pl.pinocchio_model.compute_IK_CLIK(link, goal, q0, list(mask))
        q = np.asarray(q, dtype=np.float64)
        if not ok or not pl.wrap_joint_limit(q):
            continue
        pl.planning_world.set_qpos_all(q[pl.move_group_joint_indices])
        if pl.planning_world.check_collision():
            continue
        dist = float(np.linalg.norm(q[slots] - start[slots]))
        if dist < best_dist:
            best, best_dist = q[slots].copy(), dist
        if seed is not None and k == 0:
            break  # converged from the seed: the nearby answer
    return best


def _line_is_free(a: np.ndarray, b: np.ndarray, step: float = 0.05) -> bool:
    """True when the straight joint-space segment a -> b (planner order) is free of collisions."""
    pl = planner()
    n = max(2, int(math.ceil(float(np.abs(b - a).max()) / step)) + 1)
    for s in np.linspace(0.0, 1.0, n):
        q = a + (b - a) * s
        pl.planning_world.set_qpos_all(q[pl.move_group_joint_indices])
        if pl.planning_world.check_collision():
            return False
    return True


def plan_arm(world: object, goal: np.ndarray) -> list[np.ndarray] | None:
    """A collision-free joint path from the current arm to `goal` (torso + 7), one point per control step.

    Against the obstacles of the last `set_obstacles`. A straight joint-space line is used when
    it is free (deterministic, the common case in open space), else two lines through one of
    `UNTUCK_VIAS`; otherwise mplib's RRTConnect
    (random, so its answer is recorded as actions, never re-planned on replay — FINDINGS).
    """
    robot = world.robot  # type: ignore[attr-defined]
    _set_base(robot.base_pose())
    pl = planner()
    slots = _group_slots()
    start = _planner_qpos(robot)
    target = start.copy()
    target[slots] = goal
    dt = 1.0 / robot.cfg.control_hz
    def timed(a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
        return line(a, b, max(3, int(math.ceil(float(np.abs(b - a).max()) / (ARM_SPEED * dt)))))

    if _line_is_free(start, target):
        return timed(start[slots], goal)
    for arm_via in UNTUCK_VIAS:  # out of (or into) the tuck through a raised side pose
        via = start.copy()
        via[slots] = np.concatenate([[VIA_TORSO], arm_via])
        if _line_is_free(start, via) and _line_is_free(via, target):
            return timed(start[slots], via[slots]) + timed(via[slots], goal)
    for planning_time in (1.0, 2.0, 3.0):
        res = pl.plan_qpos([target], start, time_step=dt, planning_time=planning_time)
        if res.get("status") == "Success":
            return [np.asarray(q, dtype=np.float64) for q in res["position"]]
    return None


def line(q0: np.ndarray, q1: np.ndarray, n: int) -> list[np.ndarray]:
    """n joint targets from q0 (excluded) to q1 (included) on a straight line."""
    return [q0 + (q1 - q0) * (k + 1) / n for k in range(n)]


def arm_action(robot: object, q: np.ndarray, gripper: float, base: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """An action holding torso + arm at `q` (8 values) and the gripper at `gripper` (m)."""
    a = np.zeros(ACTION_DIM, dtype=np.float32)
    a[0:3] = base
    a[3] = q[0]
    a[4:11] = q[1:8]
    a[11] = gripper
    return a


class Moved:
    """How a helper motion ended."""

    def __init__(self, success: bool, reason: str, steps: int) -> None:
        self.success, self.reason, self.steps = success, reason, steps


def approach_base(
    world: object, goal: tuple[float, float, float], hold: np.ndarray, max_steps: int
) -> Generator[np.ndarray, None, Moved]:
    """Drive the (holonomic) base straight to a nearby pose, holding torso/arm/gripper as in `hold`.

    For the last few decimetres in front of a door or counter, where the path is clear by
    construction of the interaction pose; longer trips are Navigate's job.
    """
    robot = world.robot  # type: ignore[attr-defined]
    steps = 0
    while True:
        x, y, yaw = robot.base_pose()
        ex, ey, eyaw = goal[0] - x, goal[1] - y, wrap(goal[2] - yaw)
        if math.hypot(ex, ey) < APPROACH_TOL and abs(eyaw) < APPROACH_YAW_TOL:
            break
        if steps >= max_steps:
            return Moved(False, "timeout", steps)
        c, s = math.cos(yaw), math.sin(yaw)
        v = 2.0 * np.array([c * ex + s * ey, -s * ex + c * ey])
        speed = float(np.linalg.norm(v))
        if speed > APPROACH_SPEED:
            v *= APPROACH_SPEED / speed
        elif 0.0 < speed < APPROACH_MIN_SPEED:
            v *= APPROACH_MIN_SPEED / speed
        action = np.array(hold, dtype=np.float32)
        action[0:3] = (v[0], v[1], float(np.clip(2.0 * eyaw, -APPROACH_TURN, APPROACH_TURN)))
        yield action
        steps += 1
    stop = np.array(hold, dtype=np.float32)
    stop[0:3] = 0.0
    yield stop
    return Moved(True, "", steps + 1)


def tuck_arm(world: object, hold: np.ndarray, max_steps: int) -> Generator[np.ndarray, None, int]:
    """Bring the arm back to the robot's tuck pose (planned; a straight joint line if planning fails)."""
    robot = world.robot  # type: ignore[attr-defined]
    goal = np.concatenate([[robot.torso()], robot.tuck_qpos])  # type: ignore[attr-defined]
    path = plan_arm(world, goal)
    if path is None:
        now = np.concatenate([[robot.torso()], robot.arm_qpos()])  # type: ignore[attr-defined]
        path = line(now, goal, 20)
    steps = 0
    for q in path[:max_steps]:
        yield arm_action(robot, q, gripper=float(hold[11]))
        steps += 1
    return steps


def attach(world: object, ee_link: sapien.physx.PhysxArticulationLinkComponent, body: sapien.physx.PhysxRigidBaseComponent) -> sapien.physx.PhysxDriveComponent:
    """Complete a physical grasp with a stiff drive that holds `body` where it is in the gripper."""
    rel = body.entity_pose.inv() * ee_link.entity_pose
    drive = world.scene.create_drive(ee_link.entity, sapien.Pose(), body.entity, rel)  # type: ignore[attr-defined]
    for set_axis in (drive.set_drive_property_x, drive.set_drive_property_y, drive.set_drive_property_z):
        set_axis(2.0e4, 2.0e2, 1.0e4)
    drive.set_drive_property_slerp(2.0e2, 2.0e1, 1.0e3)
    drive.set_drive_target(sapien.Pose())
    return drive


def detach(drive: sapien.physx.PhysxDriveComponent) -> None:
    """Remove an attachment made by `attach`."""
    entity = drive.entity
    if entity is not None:
        entity.remove_component(drive)


def door_open_success(world: object, i: int) -> bool:
    """OpenDoor succeeded: door i's hinge angle is at least its open threshold and it is at rest."""
    door = world.plan.doors[i]  # type: ignore[attr-defined]
    art = world.handles.doors[i]  # type: ignore[attr-defined]
    return float(art.get_qpos()[0]) >= door.open_threshold and abs(float(art.get_qvel()[0])) < REST_QVEL


def _swing_frame(door: Door) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of the closed leaf (hinge -> free edge) and of its swing-side normal."""
    u = np.array([math.cos(door.closed_yaw), math.sin(door.closed_yaw)])
    n = door.open_sign * np.array([-u[1], u[0]])
    return u, n


def _rotate_about(p: np.ndarray, centre: np.ndarray, ang: float) -> np.ndarray:
    c, s = math.cos(ang), math.sin(ang)
    d = p - centre
    return centre + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])


def door_stances(door: Door, q: float = 0.0) -> list[tuple[float, float, float]]:
    """Candidate grasp stances (x, y, yaw) for the door at hinge angle q, preferred first."""
    u, n = _swing_frame(door)
    handle = door_handle_world(door, 0.0, door.open_sign)[:2]
    yaw = math.atan2(-n[1], -n[0])
    out = []
    for dist, shift in STANCES:
        p = _rotate_about(handle + dist * n + shift * u, np.asarray(door.hinge), door.open_sign * q)
        out.append((float(p[0]), float(p[1]), wrap(yaw + door.open_sign * q)))
    return out


def _swing_is_free(world: object, door: Door, stance: tuple[float, float, float], q0: float, q1: float) -> bool:
    """True when the base stays on free floor while it turns about the hinge from q0 to q1."""
    grid = getattr(world, "nav", None)
    if grid is None:
        return True
    hinge = np.asarray(door.hinge)
    for q in np.linspace(0.0, q1 - q0, 12):
        p = _rotate_about(np.asarray(stance[:2]), hinge, door.open_sign * float(q))
        if not grid.is_free(float(p[0]), float(p[1])):
            return False
    return True


def _grasp_rotation(door: Door, q: float) -> np.ndarray:
    """World rotation of the gripper grasping the swing-side bar: approach into the leaf, fingers along it."""
    yaw = door.leaf_yaw(q)
    u = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    n = door.open_sign * np.array([-u[1], u[0], 0.0])
    x_axis = -n
    y_axis = u
    z_axis = np.cross(x_axis, y_axis)
    if z_axis[2] < 0:
        y_axis, z_axis = -y_axis, -z_axis
    return np.stack([x_axis, y_axis, z_axis], axis=1)


def open_door(world: object, call: object, spec: object) -> Generator[np.ndarray, None, SkillOutcome]:
    """The OpenDoor expert for `call.target` = "door:<i>" (see the module docstring)."""
    skill, target = call.skill, call.target  # type: ignore[attr-defined]
    robot = world.robot  # type: ignore[attr-defined]
    max_steps = int(robot.cfg.max_steps["OpenDoor"])
    dt = 1.0 / robot.cfg.control_hz
    i = int(target.partition(":")[2])
    door: Door = world.plan.doors[i]  # type: ignore[attr-defined]
    art = world.handles.doors[i]  # type: ignore[attr-defined]
    leaf = art.links[1]
    steps = 0

    def fail(reason: str) -> SkillOutcome:
        return SkillOutcome(skill, target, False, reason, steps)

    q_start = float(art.get_qpos()[0])
    q_goal = min(door.open_threshold + OPEN_MARGIN, door.max_angle - 0.02)
    if q_start >= door.open_threshold:
        ok = door_open_success(world, i)
        return SkillOutcome(skill, target, ok, "" if ok else "door_moving", 0)

    # 1. stance and grasp solution: the first stance whose swing is free and whose grasp is reachable
    rot = _grasp_rotation(door, q_start)
    handle = door_handle_world(door, q_start, door.open_sign)
    set_obstacles(world, (float(handle[0]), float(handle[1])))
    approach_dir = rot[:, 0]
    plan_choice = None
    for stance in door_stances(door, q_start):
        if not _swing_is_free(world, door, stance, q_start, q_goal):
            continue
        grasp = solve_ik(world, handle, rot, base=stance, torso=GRASP_TORSO)
        if grasp is None:
            continue
        pre = solve_ik(world, handle - PREGRASP_BACK * approach_dir, rot, base=stance, seed=grasp)
        if pre is None:
            continue
        plan_choice = (stance, grasp, pre)
        break
    if plan_choice is None:
        return fail("no_grasp_stance")
    stance, q_grasp, q_pre = plan_choice

    # 2. drive to the stance (arm tucked)
    hold = robot.rest_action()
    moved = yield from approach_base(world, stance, hold, max_steps - steps)
    steps += moved.steps
    if not moved.success:
        return fail(moved.reason)

    # 3. arm: planned motion to the pre-grasp, straight in, close the fingers
    q_grasp = solve_ik(world, handle, rot, seed=q_grasp)  # from where the base really stands
    q_pre = None if q_grasp is None else solve_ik(world, handle - PREGRASP_BACK * approach_dir, rot, seed=q_grasp)
    if q_grasp is None or q_pre is None:
        return fail("no_ik")
    path = plan_arm(world, q_pre)
    if path is None:
        return fail("arm_plan_failed")
    for q in path + line(q_pre, q_grasp, 8):
        if steps >= max_steps:
            return fail("timeout")
        yield arm_action(robot, q, gripper=0.1)
        steps += 1
    leaf_entity = leaf.entity
    closed = arm_action(robot, q_grasp, gripper=0.0)
    touching = False
    for _ in range(8):
        yield closed
        steps += 1
        left, right = robot.finger_contacts()
        if leaf_entity in left and leaf_entity in right:
            touching = True
            break
    if not touching:
        return fail("grasp_failed")
    drive = attach(world, robot.ee_link, leaf)

    # 4. swing the base about the hinge as one rigid body with the leaf
    hinge = np.asarray(door.hinge)
    x0, y0, yaw0 = robot.base_pose()
    p0 = np.array([x0, y0])
    q_cmd = float(art.get_qpos()[0])
    q_ref = q_cmd
    t = 0.0
    trajectory = [q_cmd]
    while True:
        if steps >= max_steps:
            detach(drive)
            return fail("timeout")
        t += dt
        rate = SWING_RATE * min(1.0, t / SWING_RAMP)
        q_cmd = min(q_cmd + rate * dt, q_goal)
        ang = door.open_sign * (q_cmd - q_ref)
        p_des = _rotate_about(p0, hinge, ang)
        yaw_des = yaw0 + ang
        x, y, yaw = robot.base_pose()
        w_ff = door.open_sign * (rate if q_cmd < q_goal else 0.0)
        rel = np.array([x, y]) - hinge
        v_world = w_ff * np.array([-rel[1], rel[0]]) + K_POSE * (p_des - [x, y])
        wz = w_ff + K_POSE * wrap(yaw_des - yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        action = closed.copy()
        action[0:3] = (c * v_world[0] + s * v_world[1], -s * v_world[0] + c * v_world[1], wz)
        yield action
        steps += 1
        q = float(art.get_qpos()[0])
        trajectory.append(q)
        if q_cmd - q > LOST_GRIP:
            detach(drive)
            return fail("lost_handle")
        if q_cmd >= q_goal and q >= door.open_threshold and abs(float(art.get_qvel()[0])) < REST_QVEL:
            break

    # 5. let go, back off, tuck
    detach(drive)
    released = closed.copy()
    released[11] = 0.1
    for _ in range(4):
        yield released
        steps += 1
    back = released.copy()
    back[0] = -BACK_OFF / 0.8
    for _ in range(int(round(0.8 / dt))):
        yield back
        steps += 1
    tucked = yield from tuck_arm(world, released, max_steps - steps)
    steps += tucked
    ok = door_open_success(world, i)
    return SkillOutcome(skill, target, ok, "" if ok else "not_open", steps)
