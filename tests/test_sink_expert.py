"""CloseSink in SAPIEN physics (World, no rendering): the lever is pushed closed, the water stops;
a perturbed arm is corrected, a start where a learned Navigate hands over succeeds, and the path
out of the tuck is one path."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from support.experts import assert_folded, handover_gap, make_spec, offset_start, rollout, rollout_ee, two_room_plan

from echo_data.floorplan import Faucet, FloorPlan, Furniture
from echo_data.recipe import Recipe


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

    def make(plan: FloorPlan, start=None):
        spec = make_spec(plan, "faucet:0", "CloseSink", start or interaction_pose(plan, "faucet:0"))
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
    # it ends with the arm folded (as Place does): the tuck's TCP, every arm link inside the disc
    # the navigation grid is inflated for, so a drive after it clears what the base clears
    assert_folded(world)
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


def test_close_sink_expert_corrects_an_arm_perturbation_on_the_approach(sink_world_factory) -> None:
    """2 cm sideways on the executed TCP change once, 25 cm from the lever tip: the labels that
    follow steer back (the closed loop), and the lever is still closed."""
    from echo_data.scene.articulated import lever_tip_world
    from echo_data.skills.close_sink import close_sink, sink_closed_success

    def near_lever(world):
        faucet, a = world.plan.faucets[0], float(world.handles.faucets[0].get_qpos()[0])
        if np.linalg.norm(np.asarray(world.robot.ee_pose().p) - lever_tip_world(faucet, a)) < 0.25:
            return (0.0, 0.02, 0.0, 0.0, 0.0, 0.0)
        return None

    world, spec = sink_world_factory(two_room_plan())
    clean, clean_labels, _, _ = rollout_ee(world, close_sink, spec)
    world, spec = sink_world_factory(two_room_plan())
    outcome, labels, _, at = rollout_ee(world, close_sink, spec, perturb=near_lever)
    assert clean.success and outcome.success, outcome.reason
    assert at is not None and np.array_equal(labels[at], clean_labels[at])
    undone = sum(float(b[5]) - float(a[5]) for a, b in zip(labels[at + 1 : at + 16], clean_labels[at + 1 : at + 16]))
    assert labels[at + 1][5] < clean_labels[at + 1][5] and undone > 0.018
    assert sink_closed_success(world, 0)


def test_close_sink_expert_from_a_short_off_axis_handover_takes_the_same_path(sink_world_factory) -> None:
    """A start 0.4 m short of the interaction pose and 0.25 m to the side (inside Navigate's success
    region) succeeds, and its arm path out of the tuck is the one from the interaction pose."""
    from echo_data.skills.close_sink import close_sink, sink_closed_success

    starts = (None, offset_start(two_room_plan(), "faucet:0", back=0.4, side=0.25))
    gap = handover_gap(lambda start: sink_world_factory(two_room_plan(), start=start), close_sink, "faucet:0", lambda w: sink_closed_success(w, 0), starts)
    assert gap < 0.05, f"the two paths out of the tuck lie {gap:.3f} rad apart"
