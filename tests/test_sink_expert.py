"""CloseSink in SAPIEN physics (World, no rendering): the lever is pushed closed, the water stops."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from support.experts import make_spec, rollout, two_room_plan

from echo_data.recipe import Recipe
from echo_data.scene.floorplan import Faucet, FloorPlan, Furniture


def sink_on_north_wall(plan: FloorPlan, angle: float) -> FloorPlan:
    """The same apartment with the sink cabinet against room 1's north wall, facing south."""
    cab = Furniture(0, "sink_cabinet", 1, (6.0, 3.67), (0.9, 0.56, 0.85), -math.pi / 2, "wooden_door", False)
    fc = Faucet(
        index=0, furniture=0, pivot=(6.0, 3.85, 1.0), yaw=-math.pi / 2, lever_length=0.13,
        open_angle=math.pi / 2, closed_tolerance=0.1, angle=angle, spout=(6.0, 3.72, 0.95),
    )
    return dataclasses.replace(plan, furniture=(cab,), faucets=(fc,))


@pytest.fixture(scope="module")
def sink_world_factory():
    from echo_data.scene.nav import interaction_pose
    from echo_data.world import World

    worlds = []

    def make(plan: FloorPlan):
        spec = make_spec(plan, "faucet:0", "CloseSink", interaction_pose(plan, "faucet:0"))
        world = World(spec, Recipe(name="t"), render=False)
        worlds.append(world)
        return world, spec

    yield make
    for w in worlds:
        w.close()


@pytest.mark.parametrize("layout", ["east_wall_running", "north_wall_full_open"])
def test_close_sink_expert_closes_lever_and_stops_water(sink_world_factory, layout: str) -> None:
    from echo_data.skills.close_sink import close_sink, sink_closed_success

    plan = two_room_plan() if layout == "east_wall_running" else sink_on_north_wall(two_room_plan(), math.pi / 2)
    world, spec = sink_world_factory(plan)
    faucet, art, water = plan.faucets[0], world.handles.faucets[0], world.handles.water[0]
    world.step(world.robot.rest_action())
    assert water.flowing and water.radius > 0 and not sink_closed_success(world, 0)
    start_angle = float(art.get_qpos()[0])

    outcome, trace, hits = rollout(world, close_sink, spec, lambda: (float(art.get_qpos()[0]), water.radius))
    angles = [a for a, _ in trace]
    radii = [r for _, r in trace]
    assert outcome.success, outcome.reason
    assert outcome.steps == len(trace) <= world.recipe.robot.max_steps["CloseSink"]
    assert sink_closed_success(world, 0)
    assert angles[-1] <= faucet.closed_tolerance and not water.flowing and radii[-1] == 0.0
    # the lever only ever moves towards closed, and the stream narrows with it
    assert all(b <= a + 0.005 for a, b in zip(angles, angles[1:]))
    assert all(b <= a for a, b in zip(radii, radii[1:]))
    assert angles[0] == pytest.approx(start_angle, abs=0.01)
    assert not hits, f"robot pushed on {hits}"
    # the lever stays closed once the robot has left
    for _ in range(10):
        world.step(world.robot.rest_action())
    assert sink_closed_success(world, 0)


def test_close_sink_expert_is_deterministic(sink_world_factory) -> None:
    """Same episode, fresh worlds: the expert yields the same actions bit for bit (same seeds, same bytes)."""
    from echo_data.skills.close_sink import close_sink

    runs = []
    for _ in range(2):
        world, spec = sink_world_factory(two_room_plan())
        _, trace, _ = rollout(world, close_sink, spec, world.robot.last_action)
        runs.append(np.stack(trace))
    assert runs[0].shape == runs[1].shape and np.array_equal(runs[0], runs[1])
