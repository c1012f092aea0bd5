"""World: a sampled episode's scene with the robot at its start pose, stepping, nav grid, close."""

from __future__ import annotations

import math

import numpy as np
import pytest

from echo_data.recipe import Recipe
from echo_data.scene.sampling import sample_episode
from echo_data.sounds import SoundLibrary
from echo_data.world import World


@pytest.fixture(scope="module")
def spec_and_recipe():
    recipe = Recipe(name="world-test", robot={"physics_hz": 120, "control_hz": 10})
    spec, _ = sample_episode(recipe, "train", 3, SoundLibrary.from_recipe(recipe))
    return spec, recipe


def test_world_starts_at_the_spec_pose_and_steps(spec_and_recipe) -> None:
    spec, recipe = spec_and_recipe
    world = World(spec, recipe, render=False)
    assert world.substeps == 12
    assert world.scene.timestep == pytest.approx(1.0 / 120.0)
    x, y, yaw = world.robot.base_pose()
    assert (x, y) == pytest.approx(spec.start[:2], abs=1e-5)
    assert math.remainder(yaw - spec.start[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-5)
    # link poses are valid before the first step (not the articulation origin)
    ee = np.asarray(world.robot.ee_pose().p)
    assert math.hypot(ee[0] - x, ee[1] - y) < 0.3 and ee[2] > 0.4
    # every plan object exists as a body resting where the plan put it
    assert set(world.handles.objects) == {o.name for o in spec.plan.objects}
    world.settle(5)
    for o in spec.plan.objects:
        assert np.asarray(world.object_pose(o.name).p) == pytest.approx(o.position, abs=0.005)
    # one control step = 0.1 s of physics: turning in place (a disc never hits anything) at
    # 0.5 rad/s for 5 steps turns the base 0.25 rad and leaves it where it was
    a = world.robot.rest_action()
    a[2] = 0.5
    for _ in range(5):
        world.step(a)
    x2, y2, yaw2 = world.robot.base_pose()
    assert math.remainder(yaw2 - yaw, 2 * math.pi) == pytest.approx(0.25, abs=0.02)
    assert math.hypot(x2 - x, y2 - y) < 0.005
    assert world.steps == 10
    assert world.nav.is_free(*spec.start[:2])
    world.close()
    assert world.closed and not hasattr(world, "scene")  # the scene, robot and handles are released
