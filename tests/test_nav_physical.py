"""Navigate in SAPIEN physics (no rendering): through a doorway, no wall contact, and failures."""

from __future__ import annotations

import dataclasses
import math

from support.nav_plans import two_room_plan

from echo_data.episode import EpisodeSpec, SkillCall
from echo_data.recipe import Recipe, RobotConfig
from echo_data.records import ACTION_DIM
from echo_data.scene.floorplan import FloorPlan, Furniture, Rect
from echo_data.scene.nav import NavGrid, interaction_pose, target_point
from echo_data.skills import navigate as nav_skill

BASE_RADIUS = 0.28  # echo_data.robot.urdf.BASE_RADIUS


def _world(plan: FloorPlan, start: tuple[float, float, float], max_nav_steps: int = 600):
    """A physics-only World for `plan` with the robot at `start`."""
    from echo_data.world import World

    robot = RobotConfig(max_steps={"Navigate": max_nav_steps, "Pick": 250, "Place": 250, "OpenDoor": 300, "CloseSink": 200})
    recipe = Recipe(name="navtest", robot=robot)
    spec = EpisodeSpec(
        episode_id="test-000000", split="test", index=0, attempt=0, seed=0, setting="object_relocation",
        plan=plan, start=start, events=(), chain=(),
    )  # fmt: skip
    return World(spec, recipe, render=False)


def _rect_distance(r: Rect, x: float, y: float) -> float:
    dx = max(r.xmin - x, 0.0, x - r.xmax)
    dy = max(r.ymin - y, 0.0, y - r.ymax)
    return math.hypot(dx, dy)


def _run(world, gen):
    """Step `world` with the expert's actions; return (outcome, per-step base poses, contact steps)."""
    poses, contact_steps = [], 0
    try:
        while True:
            action = next(gen)
            assert action.shape == (ACTION_DIM,)
            world.step(action)
            poses.append(world.robot.base_pose())
            contact_steps += bool(nav_skill.robot_collisions(world))
    except StopIteration as stop:
        return stop.value, poses, contact_steps


def test_navigate_through_doorway_to_other_room() -> None:
    plan = two_room_plan(door_angle=math.radians(90))
    world = _world(plan, (1.0, 1.0, 0.0))
    outcome, poses, contact_steps = _run(world, nav_skill.navigate(world, SkillCall("Navigate", "faucet:0", 0), None))
    assert outcome.success and outcome.reason == "" and outcome.steps == len(poses)
    x, y, yaw = world.robot.base_pose()
    gx, gy, _ = interaction_pose(plan, "faucet:0", door_angles={0: math.radians(90)})
    assert math.hypot(x - gx, y - gy) <= 1.5
    tx, ty = target_point(plan, "faucet:0")
    assert abs(math.remainder(math.atan2(ty - y, tx - x) - yaw, 2 * math.pi)) <= math.radians(15)
    assert plan.room_at(x, y) == 1 and plan.room_at(*poses[0][:2]) == 0  # it changed rooms
    assert contact_steps == 0
    # The base disc never overlapped a wall footprint at any step.
    for px, py, _ in poses:
        assert min(_rect_distance(w.footprint, px, py) for w in plan.walls) >= BASE_RADIUS - 1e-3
    assert nav_skill.navigate_success(world, "faucet:0")
    world.robot.set_base_pose(x, y, yaw + math.radians(30))  # turned away: not facing the lever
    assert not nav_skill.navigate_success(world, "faucet:0")
    world.robot.set_base_pose(gx - 1.6, gy, math.atan2(ty - gy, tx - gx + 1.6))  # facing it, 1.6 m off
    assert not nav_skill.navigate_success(world, "faucet:0")


def test_collision_stops_the_drive() -> None:
    """A cabinet the grid does not know about: the drive runs into it and reports a collision."""
    plan = two_room_plan(door_angle=math.radians(90))
    cabinet = Furniture(3, "cabinet", 0, (2.5, 1.0), (0.4, 1.6, 0.8), 0.0, "wooden_door", False)
    world = _world(dataclasses.replace(plan, furniture=plan.furniture + (cabinet,)), (1.0, 1.0, 0.0))
    stale_grid = NavGrid.from_plan(plan)
    result, poses, contact_steps = _run(world, nav_skill.drive_to(world, (3.5, 1.0, 0.0), 200, grid=stale_grid))
    assert not result.success and result.reason == "collision"
    assert contact_steps >= 1 and len(poses) < 60


def test_no_path_when_door_closed_and_timeout() -> None:
    world = _world(two_room_plan(door_angle=0.0), (1.0, 1.0, 0.0), max_nav_steps=5)
    outcome, poses, _ = _run(world, nav_skill.navigate(world, SkillCall("Navigate", "faucet:0", 0), None))
    assert not outcome.success and outcome.reason == "no_path" and not poses
    outcome, poses, _ = _run(world, nav_skill.navigate(world, SkillCall("Navigate", "phone_0", 0), None))
    assert not outcome.success and outcome.reason == "timeout" and len(poses) == 5
    assert not nav_skill.navigate_success(world, "phone_0")


def test_drive_replans_after_being_pushed_off_the_path() -> None:
    """Teleporting the robot 0.8 m off its path mid-drive makes it replan and still arrive."""
    plan = two_room_plan(door_angle=math.radians(90))
    world = _world(plan, (1.0, 1.0, 0.0))
    goal = interaction_pose(plan, "faucet:0", door_angles={0: math.radians(90)})
    gen = nav_skill.drive_to(world, goal, 400)
    pushed = False
    try:
        while True:
            world.step(next(gen))
            x, y, yaw = world.robot.base_pose()
            if not pushed and x > 2.0:
                world.robot.set_base_pose(x, y + 0.8 if y < 2.0 else y - 0.8, yaw)
                pushed = True
    except StopIteration as stop:
        result = stop.value
    assert pushed and result.success and result.replans >= 1
    x, y, _ = world.robot.base_pose()
    assert math.hypot(x - goal[0], y - goal[1]) <= 0.15
