"""OpenDoor in SAPIEN physics (World, no rendering) on a hand-made two-room plan."""

from __future__ import annotations

import math

import numpy as np
import pytest

from echo_data.episode import EpisodeSpec, SkillCall, SoundEvent
from echo_data.recipe import Recipe
from echo_data.scene.floorplan import Door, Doorway, Faucet, FloorPlan, Furniture, Rect, Room, WallSegment

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


def run_expert(world, expert, call, spec) -> tuple[object, list[np.ndarray]]:
    """Drive an expert generator to its end; returns (outcome, actions)."""
    gen = expert(world, call, spec)
    actions = []
    try:
        while True:
            action = next(gen)
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
            action = next(gen)
        except StopIteration as stop:
            return stop.value, values, hits
        assert action.dtype == np.float32 and action.shape == (12,)
        world.step(action)
        values.append(probe())
        hits |= static_hits(world)


@pytest.fixture(scope="module")
def door_world_factory():
    from echo_data.scene.nav import interaction_pose
    from echo_data.world import World

    worlds = []

    def make(hinge_low: bool, builder=None):
        plan = two_room_plan(hinge_low=hinge_low)
        spec = make_spec(plan, "door:0", "OpenDoor", interaction_pose(plan, "door:0"))
        world = World(spec, Recipe(name="t"), render=False, builder=builder)
        worlds.append(world)
        return world, spec

    yield make
    for w in worlds:
        w.close()


@pytest.mark.parametrize("hinge_low", [True, False], ids=["opens_ccw", "opens_cw"])
def test_open_door_expert_opens_and_leaves_door_at_rest(door_world_factory, hinge_low: bool) -> None:
    import sapien

    from echo_data.skills.open_door import open_door
    from echo_data.skills.success import door_open_success

    world, spec = door_world_factory(hinge_low)
    door, art = world.plan.doors[0], world.handles.doors[0]
    assert not door_open_success(world, 0)
    outcome, angles, hits = rollout(world, open_door, spec, lambda: float(art.get_qpos()[0]))
    assert outcome.success, outcome.reason
    assert outcome.steps == len(angles) <= world.recipe.robot.max_steps["OpenDoor"]
    assert door_open_success(world, 0)
    assert angles[-1] >= door.open_threshold and abs(float(art.get_qvel()[0])) < 0.05
    # progress is monotone: the door never swings back by more than a few milliradians
    assert all(b >= a - 0.005 for a, b in zip(angles, angles[1:]))
    assert angles[0] < 0.01 < door.open_threshold <= max(angles)
    assert not hits, f"robot pushed on {hits}"
    # let go: no attachment left, and the door stays where it was left
    assert art.links[1].entity.find_component_by_type(sapien.physx.PhysxDriveComponent) is None
    assert world.robot.gripper_opening() > 0.05
    for _ in range(10):
        world.step(world.robot.rest_action())
    assert float(art.get_qpos()[0]) == pytest.approx(angles[-1], abs=0.01)


def test_open_door_expert_reports_a_blocked_door(door_world_factory) -> None:
    """A post in the leaf's path: the expert must fail with a reason, not claim success."""
    import sapien

    from echo_data.scene.build import build_scene
    from echo_data.skills.open_door import open_door
    from echo_data.skills.success import door_open_success

    def with_post(scene, plan, recipe):
        handles = build_scene(scene, plan, recipe)
        door = plan.doors[0]
        yaw = door.leaf_yaw(0.45)
        x, y = door.hinge[0] + 0.5 * math.cos(yaw), door.hinge[1] + 0.5 * math.sin(yaw)
        b = scene.create_actor_builder()
        b.add_box_collision(half_size=[0.05, 0.05, 1.0])
        post = b.build_static(name="post")
        # centre 0.08 m ahead of the leaf (swing side) at q = 0.45: the leaf stops at ≈0.3 rad
        nx, ny = -door.open_sign * math.sin(yaw), door.open_sign * math.cos(yaw)
        post.set_pose(sapien.Pose([x + 0.08 * nx, y + 0.08 * ny, 1.0]))
        handles.statics.append(post)
        return handles

    world, spec = door_world_factory(True, builder=with_post)
    art = world.handles.doors[0]
    outcome, angles, _ = rollout(world, open_door, spec, lambda: float(art.get_qpos()[0]))
    assert not outcome.success
    assert outcome.reason == "lost_handle", outcome.reason  # it grasped and swung, the door did not follow
    assert 0.1 < max(angles) < world.plan.doors[0].open_threshold
    assert not door_open_success(world, 0)


def test_open_door_expert_stopped_mid_swing_lets_go(door_world_factory) -> None:
    """An expert closed mid-swing leaves the door held only while the gripper stays closed: the
    world holds a door leaf in a closed gripper and lets go as soon as the gripper opens."""
    import sapien

    from echo_data.skills.open_door import open_door

    world, spec = door_world_factory(False)
    leaf_entity = world.handles.doors[0].links[1].entity
    gen = open_door(world, spec.chain[0], spec)
    attached_steps = 0
    for _ in range(world.recipe.robot.max_steps["OpenDoor"]):
        world.step(next(gen))
        if leaf_entity.find_component_by_type(sapien.physx.PhysxDriveComponent) is not None:
            attached_steps += 1
            if attached_steps == 5:
                break
    assert attached_steps == 5 and world.holding_door  # it did grasp and start swinging
    gen.close()
    open_hand = world.robot.rest_action()
    open_hand[11] = 0.1
    world.step(open_hand)
    assert not world.holding_door
    assert leaf_entity.find_component_by_type(sapien.physx.PhysxDriveComponent) is None
