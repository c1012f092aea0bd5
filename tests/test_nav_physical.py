"""Navigate in SAPIEN physics (no rendering): through a doorway, no wall contact, and failures."""

from __future__ import annotations

import dataclasses
import math

from support.nav_plans import two_room_plan

from echo_data.episode import EpisodeSpec, SkillCall
from echo_data.floorplan import FloorPlan, Furniture, Rect
from echo_data.recipe import ExpertsConfig, Recipe, RobotConfig
from echo_data.records import EE_ACTION_DIM
from echo_data.scene.nav import NavGrid, interaction_pose, target_point
from echo_data.skills import navigate as nav_skill

BASE_RADIUS = 0.28  # echo_data.robot.urdf.BASE_RADIUS


def _world(plan: FloorPlan, start: tuple[float, float, float], max_nav_steps: int = 600, handover: float = 0.0,
           chain: tuple[SkillCall, ...] = (), seed: int = 0):
    """A physics-only World for `plan` with the robot at `start`."""
    from echo_data.world import World

    robot = RobotConfig(max_steps={"Navigate": max_nav_steps, "Pick": 250, "Place": 250, "OpenDoor": 300, "CloseSink": 200})
    recipe = Recipe(name="navtest", robot=robot, experts=ExpertsConfig(handover_noise=handover))
    spec = EpisodeSpec(
        episode_id="test-000000", split="test", index=0, attempt=0, seed=seed, setting="object_relocation",
        plan=plan, start=start, events=(), chain=chain,
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
            assert action.shape == (EE_ACTION_DIM,)  # Navigate speaks action.ee
            world.step(world.robot.ee.to_joint(action))
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
            world.step(world.robot.ee.to_joint(next(gen)))
            x, y, yaw = world.robot.base_pose()
            if not pushed and x > 2.0:
                world.robot.set_base_pose(x, y + 0.8 if y < 2.0 else y - 0.8, yaw)
                pushed = True
    except StopIteration as stop:
        result = stop.value
    assert pushed and result.success and result.replans >= 1
    x, y, _ = world.robot.base_pose()
    assert math.hypot(x - goal[0], y - goal[1]) <= 0.15


def test_drive_holds_the_arm_exactly_and_corrects_a_perturbed_arm() -> None:
    """Navigate's actions are action.ee: base velocity, torso and gripper as commanded, a zero TCP
    change (the joint targets stay bit for bit); a perturbed arm gets a label back towards them."""
    import numpy as np

    world = _world(two_room_plan(door_angle=math.radians(90)), (1.0, 1.0, 0.0))
    held = world.robot.applied_action()
    gen = nav_skill.drive_to(world, (3.0, 1.0, 0.0), 100)
    first = next(gen)
    assert first.shape == (EE_ACTION_DIM,) and not np.any(first[4:10])
    assert first[3] == held[3] and first[10] == (1.0 if held[11] < world.robot.ee.gripper_open / 2 else 0.0)
    joint = world.robot.ee.to_joint(first)
    np.testing.assert_array_equal(joint[3:], held[3:])
    pushed = joint.copy()
    pushed[4] += 0.05  # the shoulder target knocked 0.05 rad off
    world.step(pushed)
    label = world.robot.ee.to_joint(next(gen))
    assert not np.array_equal(label[4:11], pushed[4:11])  # a nonzero TCP change ...
    ee = world.robot.ee

    def off(arm: np.ndarray) -> float:  # TCP distance (m) from where the drive holds it
        return float(np.linalg.norm(ee.tcp_in_torso(arm)[:3, 3] - ee.tcp_in_torso(held[4:11])[:3, 3]))

    assert off(label[4:11]) < 0.5 * off(pushed[4:11])  # ... back towards the held TCP
    gen.close()


def test_handover_goals_lie_in_the_next_skills_stance() -> None:
    """experts.handover_noise: stop poses drawn uniformly from a disc of f x (stance distance -
    GOAL_TOL) around the interaction point, on free cells in straight sight of it, heading within
    f x (stance heading - YAW_TOL) of the pose's and facing the target as Navigate's success test
    asks; the margins keep the follower's stop inside the stance (docs/handover.md)."""
    import numpy as np

    from echo_data.skill_table import SKILLS
    from echo_data.skills.success import NAV_SUCCESS_DIST, NAV_SUCCESS_YAW

    stance = SKILLS["CloseSink"].stance
    assert stance is not None and stance.distance < NAV_SUCCESS_DIST and stance.heading < NAV_SUCCESS_YAW
    radius, spread = stance.distance - nav_skill.GOAL_TOL, stance.heading - nav_skill.YAW_TOL
    doors = {0: math.radians(90)}
    plan = two_room_plan(door_angle=math.radians(90))
    grid = NavGrid.from_plan(plan, door_angles=doors)
    exact = interaction_pose(plan, "faucet:0", door_angles=doors, grid=grid)
    tx, ty = target_point(plan, "faucet:0", doors)
    assert nav_skill.handover_goal(plan, "faucet:0", grid, exact, 0.0, np.random.default_rng(0), stance, doors) == exact
    for noise in (0.5, 1.0):
        dists, turns = [], []
        for i in range(100):
            x, y, yaw = nav_skill.handover_goal(plan, "faucet:0", grid, exact, noise, np.random.default_rng(i), stance, doors)
            d = math.hypot(x - exact[0], y - exact[1])
            assert d <= noise * radius + 1e-9 and grid.is_free(x, y)
            assert grid.segment_clearance((x, y), exact[:2]) >= grid.robot_radius
            assert abs(math.remainder(yaw - exact[2], 2 * math.pi)) <= noise * spread + 1e-9
            assert abs(math.remainder(math.atan2(ty - y, tx - x) - yaw, 2 * math.pi)) <= NAV_SUCCESS_YAW - nav_skill.YAW_TOL + 1e-9
            dists.append(d)
            turns.append(abs(math.remainder(yaw - exact[2], 2 * math.pi)))
        # uniform by area over the free part of the disc: the median radius is near R / sqrt(2);
        # the heading uniform: its median offset near half the spread
        assert 0.4 * noise * radius < float(np.median(dists)) < 0.8 * noise * radius
        assert 0.3 * noise * spread < float(np.median(turns)) < 0.7 * noise * spread


def test_navigate_with_handover_noise_stops_off_the_pose_inside_the_region() -> None:
    """The build's Navigate under experts.handover_noise ends where its success test holds and
    inside the next skill's stance, but away from the interaction pose, at a point drawn from the
    episode's own seeded stream; with no skill after it, it drives to the exact pose."""
    from echo_data.skill_table import SKILLS
    from echo_data.skills.success import handed_over

    stance = SKILLS["CloseSink"].stance
    assert stance is not None
    call = SkillCall("Navigate", "faucet:0", 0)
    chain = (call, SkillCall("CloseSink", "faucet:0", 0))
    plan = two_room_plan(door_angle=math.radians(90))
    gx, gy, _ = interaction_pose(plan, "faucet:0", door_angles={0: math.radians(90)})
    ends = []
    for seed, calls in ((1, chain), (1, chain), (2, chain), (2, (call,))):
        world = _world(plan, (1.0, 1.0, 0.0), handover=1.0, chain=calls, seed=seed)
        outcome, _, contact_steps = _run(world, nav_skill.navigate(world, call, world.spec))
        assert outcome.success and contact_steps == 0 and nav_skill.navigate_success(world, "faucet:0")
        assert handed_over(world, "faucet:0", stance.distance, stance.heading)
        x, y, yaw = world.robot.base_pose()
        ends.append((round(x, 3), round(y, 3)))
        world.close()
    assert ends[0] == ends[1] != ends[2]  # the episode's seed decides the point
    assert max(math.hypot(x - gx, y - gy) for x, y in ends[:3]) > 0.03
    assert math.hypot(ends[3][0] - gx, ends[3][1] - gy) < nav_skill.GOAL_TOL + 0.02  # nothing to hand over to: the exact pose
