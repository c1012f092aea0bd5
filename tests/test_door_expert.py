"""OpenDoor in SAPIEN physics (World, no rendering) on a hand-made two-room plan."""

from __future__ import annotations

import math

import pytest
from support.experts import as_joint, make_spec, rollout, two_room_plan

from echo_data.recipe import Recipe


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
        world.step(as_joint(world, next(gen)))
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
