"""A hand-made two-room plan with a door and a sink, and helpers that run one expert in a World
(shared by the OpenDoor and CloseSink expert tests): whole runs, runs with a perturbed executed
end-effector action, and starts off the interaction pose."""

from __future__ import annotations

import math

import numpy as np

from echo_data.episode import EpisodeSpec, SkillCall, SoundEvent
from echo_data.floorplan import Door, Doorway, Faucet, FloorPlan, Furniture, Rect, Room, WallSegment
from echo_data.records import EE_ACTION_DIM

T = 0.1  # wall thickness


def two_room_plan(hinge_low: bool = True, door_angle: float = 0.0) -> FloorPlan:
    """Rooms [0,4]x[0,4] and [4,8]x[0,4]; a doorway at x=4, y in [1.5, 2.5] with a leaf swinging
    west into room 0, hung on the wall face like the generator does; a sink cabinet in room 1."""
    mats = ("linoleum_on_concrete", "plasterboard", "ceiling_plasterboard")
    rooms = (Room(0, "hall", Rect(0, 0, 4, 4), *mats), Room(1, "kitchen", Rect(4, 0, 8, 4), *mats))
    wall = lambda a, b, ext: WallSegment(a, b, T, 2.5, "plasterboard", ext)  # noqa: E731
    walls = (
        wall((-T / 2, 0.0), (8 + T / 2, 0.0), True),
        wall((-T / 2, 4.0), (8 + T / 2, 4.0), True),
        wall((0.0, 0.0), (0.0, 4.0), True),
        wall((8.0, 0.0), (8.0, 4.0), True),
        wall((4.0, 0.0), (4.0, 1.5), False),
        wall((4.0, 2.5), (4.0, 4.0), False),
    )
    doorways = (Doorway(0, (4.0, 2.0), "y", 1.0, 2.1, (0, 1)),)
    hx = 4.0 - (T / 2 + 0.012 + 0.02)  # hinge axis outside the wall face (docs/SIMULATION_NOTES.md#articulations)
    if hinge_low:
        hinge, closed_yaw, sign = (hx, 1.48), math.pi / 2, 1.0
    else:
        hinge, closed_yaw, sign = (hx, 2.52), -math.pi / 2, -1.0
    door = Door(
        index=0, doorway=0, hinge=hinge, closed_yaw=closed_yaw, open_sign=sign, width=1.04, thickness=0.04,
        height=2.08, max_angle=math.radians(105), open_threshold=math.radians(60), angle=door_angle,
        handle_height=1.0, swing_room=0, material="wooden_door", doorbell=(3.94, 2.67, 1.2),
    )
    sink = Furniture(0, "sink_cabinet", 1, (7.67, 1.0), (0.56, 0.9, 0.85), math.pi, "wooden_door", False)
    faucet = Faucet(
        index=0, furniture=0, pivot=(7.85, 1.0, 1.0), yaw=math.pi, lever_length=0.13, open_angle=math.pi / 2,
        closed_tolerance=0.1, angle=1.2, spout=(7.72, 1.0, 0.95),
    )
    return FloorPlan(0, rooms, walls, doorways, (door,), (sink,), (faucet,), ())


def make_spec(plan: FloorPlan, target: str, skill: str, start: tuple[float, float, float]) -> EpisodeSpec:
    category = "doorbell" if target.startswith("door") else "sink"
    event = SoundEvent(category, f"{category}_train_00", target, (0.0, 0.0, 1.0), 0)
    return EpisodeSpec(
        episode_id="test-000000", split="train", index=0, attempt=0, seed=0, setting="state_transition",
        plan=plan, start=start, events=(event,), chain=(SkillCall(skill, target, 0),),
    )


def as_joint(world, action: np.ndarray) -> np.ndarray:
    """An expert's action as the joint action the world steps: an `action.ee` (11) goes through
    the robot's one ee map (as `OracleSkills` does), a joint action (12) passes."""
    action = np.asarray(action)
    if action.shape == (EE_ACTION_DIM,):
        assert action.dtype == np.float32
        return world.robot.ee.to_joint(action)
    return action


def run_expert(world, expert, call, spec) -> tuple[object, list[np.ndarray]]:
    """Drive an expert generator to its end; returns (outcome, joint actions)."""
    gen = expert(world, call, spec)
    actions = []
    try:
        while True:
            action = as_joint(world, next(gen))
            actions.append(action)
            world.step(action)
    except StopIteration as stop:
        return stop.value, actions


def static_hits(world) -> set[str]:
    """Walls / furniture (not the floor) that a robot link pushes on after the last physics step."""
    robot_entities = {ln.entity for ln in world.robot.articulation.links}
    statics = {e for e in world.handles.statics if e.name != "floor"}
    hits = set()
    for c in world.scene.get_contacts():
        e0, e1 = c.bodies[0].entity, c.bodies[1].entity
        other = e1 if e0 in robot_entities else e0 if e1 in robot_entities else None
        if other in statics and any(np.linalg.norm(p.impulse) > 1e-6 for p in c.points):
            hits.add(other.name)
    return hits


def rollout(world, expert, spec, probe) -> tuple[object, list[float], set[str]]:
    """Run `expert` on the spec's only call; returns (outcome, probe() after each step, static hits)."""
    gen = expert(world, spec.chain[0], spec)
    values, hits = [], set()
    while True:
        try:
            action = as_joint(world, next(gen))
        except StopIteration as stop:
            return stop.value, values, hits
        assert action.dtype == np.float32 and action.shape == (12,)
        world.step(action)
        values.append(probe())
        hits |= static_hits(world)


def offset_start(plan: FloorPlan, target: str, back: float, side: float) -> tuple[float, float, float]:
    """A start `back` m behind and `side` m left of the target's interaction pose, facing the
    target (as a learned Navigate hands over: short and off-axis, inside its success region)."""
    from echo_data.scene.nav import interaction_pose, target_point

    x, y, yaw = interaction_pose(plan, target)
    c, s = math.cos(yaw), math.sin(yaw)
    sx, sy = x - back * c - side * s, y - back * s + side * c
    tx, ty = target_point(plan, target)
    return (sx, sy, math.atan2(ty - sy, tx - sx))


def rollout_ee(world, expert, spec, perturb=None) -> tuple[object, list[np.ndarray], list[np.ndarray], int | None]:
    """Run an `action.ee` expert on the spec's only call; returns (outcome, its ee labels, the
    commanded arm joints after each step, the step perturbed). `perturb(world)` -> a 6-vector:
    added once (the first time it returns one) to the executed action's TCP change."""
    gen = expert(world, spec.chain[0], spec)
    labels, arms, at = [], [], None
    while True:
        try:
            label = next(gen)
        except StopIteration as stop:
            return stop.value, labels, arms, at
        assert label.dtype == np.float32 and label.shape == (EE_ACTION_DIM,)
        executed = label.copy()
        if perturb is not None and at is None:
            kick = perturb(world)
            if kick is not None:
                executed[4:10] += np.asarray(kick, dtype=np.float32)
                at = len(labels)
        labels.append(label)
        world.step(world.robot.ee.to_joint(executed))
        arms.append(world.robot.applied_action()[4:11].astype(np.float64))



def handover_gap(make, expert, target: str, done, starts) -> float:
    """Run `expert` in a fresh world from each start (`make(start)` -> (world, spec); None: the
    interaction pose), each inside Navigate's success region and ending in success (`done(world)`);
    returns how far the first two arm paths out of the tuck lie apart (`path_gap`, rad)."""
    from echo_data.evaluation.path_spread import path_gap
    from echo_data.skills.success import navigate_success

    runs = []
    for start in starts:
        world, spec = make(start)
        assert navigate_success(world, target)
        outcome, _, arms, _ = rollout_ee(world, expert, spec)
        assert outcome.success, outcome.reason
        assert done(world)
        runs.append(arms)
    return path_gap(runs[0], runs[1])


def assert_folded(world) -> None:
    """The arm folded for a drive: the TCP within 3 cm of the tuck's (READY's torso), and every arm
    link's origin within the base's own disc (0.28 m radius) seen from above, inside the 0.32 m
    the navigation grid is inflated for (`echo_data.scene.nav.NavGrid`). At READY the elbow sits
    0.47 m out. The joints themselves may differ from TUCK_QPOS: the TCP is servoed, and the arm
    is redundant."""
    from echo_data.robot.ee_control import base_frame
    from echo_data.robot.robot import READY_GROUP, TUCK_QPOS
    from echo_data.skills.servo import measured_tcp

    robot = world.robot
    ee = robot.ee
    here = np.linalg.inv(base_frame(*robot.base_pose())) @ measured_tcp(world)
    want = ee.tcp_in_base(float(READY_GROUP[0]), TUCK_QPOS)
    assert np.linalg.norm(here[:3, 3] - want[:3, 3]) < 0.03, (here[:3, 3], want[:3, 3])
    q = ee._full(robot.arm_qpos())
    ee.model.compute_forward_kinematics(q)
    for i, link in enumerate(robot.articulation.get_links()):
        if any(k in link.name for k in ("shoulder", "upperarm", "elbow", "forearm", "wrist", "gripper")):
            p = ee.model.get_link_pose(i).p
            assert math.hypot(p[0], p[1]) < 0.28, f"{link.name} {math.hypot(p[0], p[1]):.3f} m from the base centre"

