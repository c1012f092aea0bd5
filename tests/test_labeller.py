"""The manipulation experts asked from states a learner reached (`echo_data.skills.labeller`):
a missed grasp is re-aimed and regrasped, a door swing taken over half-open is finished, a lever
half-turned is closed, a carry taken over mid-drive is placed, and asking never changes the world."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

RECIPE = Path(__file__).resolve().parent.parent / "recipes" / "quickstart.yaml"
# train episodes of recipes/quickstart.yaml: 0 is Navigate, Pick, Place; 1 Navigate, CloseSink; 4 Navigate, OpenDoor
PICK_EPISODE, SINK_EPISODE, DOOR_EPISODE = 0, 1, 4


@pytest.fixture()
def env() -> Any:
    from echo_data.envs.env import EchoDataEnv
    from echo_data.recipe import load_recipe

    e = EchoDataEnv(load_recipe(RECIPE), split="train", images=False, audio=False)
    yield e
    e.close()


def _handed_over(env: Any, episode: int, skill: str) -> Any:
    """Reset to train episode `episode` and run the experts up to its first `skill` call; the call."""
    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.runtime import run_episode

    spec = env.sample_spec("train", episode)
    k = next(j for j, c in enumerate(spec.chain) if c.skill == skill)
    obs, info = env.reset(options={"spec": spec})
    run = run_episode(env, obs, info, OraclePlanner(), OracleSkills(), skills=k)
    assert all(o.success for o in run.outcomes) and len(run.outcomes) == k, run
    return spec.chain[k]


def _expert_until(env: Any, call: Any, stop: Callable[[np.ndarray], bool], limit: int = 400) -> None:
    """Step the skill's expert (as the build does) until `stop(its next action.ee)`; that action is not applied."""
    from echo_data.skills import EXPERTS

    world = env.world
    gen = EXPERTS[call.skill](world, call, env.episode)
    try:
        for _ in range(limit):
            a = np.asarray(next(gen), np.float32)
            if stop(a):
                return
            env.step(world.robot.ee.to_joint(a))
    finally:
        gen.close()
    raise AssertionError(f"{call.skill}'s expert never reached the state asked for")


def _label_until(env: Any, call: Any, done: Callable[[], bool], limit: int) -> list[np.ndarray]:
    """Execute the labeller's answers, one per control step, until `done()`; the labels."""
    from echo_data.skills.labeller import ExpertLabeller

    lab = ExpertLabeller(env.world, call, env.episode)
    labels = []
    try:
        for _ in range(limit):
            if done():
                return labels
            a = lab()
            assert a is not None, f"the labeller had nothing to say after {len(labels)} steps"
            labels.append(a)
            env.step(lab.joint(a))
    finally:
        lab.close()
    raise AssertionError(f"not done after {limit} labelled steps")


def _snapshot(world: Any) -> dict[str, Any]:
    robot = world.robot
    art = robot.articulation
    out: dict[str, Any] = {
        "qpos": art.get_qpos().copy(), "qvel": art.get_qvel().copy(), "applied": robot.applied_action().copy(),
        "holding": robot.holding, "door_held": world.holding_door, "steps": world.steps,
        "doors": dict(world.door_angles()), "faucets": dict(world.handles.faucet_angles()),
        "receptacles": dict(world.receptacles),
    }
    for name, e in world.handles.objects.items():
        out[name] = np.concatenate([e.pose.p, e.pose.q])
    return out


def test_missed_grasp_is_reaimed_and_regrasped(env: Any) -> None:
    """A learner closed the jaws beside the object, 10 cm short of it at its height: the
    labeller's answers open them, re-aim, grasp and lift (Pick's success test)."""
    from echo_data.skills import servo as S
    from echo_data.skills.success import pick_success

    call = _handed_over(env, PICK_EPISODE, "Pick")
    world = env.world
    _expert_until(env, call, lambda a: a[10] > 0.5)  # the expert's hand at the grasp point, about to close
    # the learner: the hand up clear of the object, 10 cm back towards the base, down again ...
    for d in [(0.0, 0.0, 0.01)] * 8 + [(-0.01, 0.0, 0.0)] * 10 + [(0.0, 0.0, -0.01)] * 8:
        env.step(world.robot.ee.to_joint(S.ee_command(world, delta=np.array([*d, 0.0, 0.0, 0.0]))))
    for _ in range(10):  # ... and the jaws closed there, on nothing
        env.step(world.robot.ee.to_joint(S.ee_command(world, close=True)))
    assert world.robot.holding is None and S.gripper_closed(world)
    labels = _label_until(env, call, lambda: pick_success(world, call.target), limit=300)
    opened = next(i for i, a in enumerate(labels) if a[10] < 0.5)  # the jaws are opened ...
    assert any(a[10] > 0.5 for a in labels[opened:])  # ... and closed again on the object
    assert world.robot.holding == call.target


def test_door_taken_over_half_open_is_opened(env: Any) -> None:
    """The expert's grasp swung the leaf half-way to the open threshold; a fresh labeller takes
    over there and finishes the opening (OpenDoor's success test)."""
    from echo_data.skills.success import door_open_success
    from echo_data.target import Target

    call = _handed_over(env, DOOR_EPISODE, "OpenDoor")
    world = env.world
    i = Target.parse(call.target).index
    door = world.plan.doors[i]
    _expert_until(env, call, lambda a: world.holding_door and world.door_angles()[i] >= door.open_threshold / 2)
    assert not door_open_success(world, i)
    _label_until(env, call, lambda: door_open_success(world, i), limit=250)


def test_lever_taken_over_half_turned_is_closed(env: Any) -> None:
    """The expert's push turned the lever half-way closed; a fresh labeller takes over there and
    closes it (CloseSink's success test)."""
    from echo_data.skills.success import sink_closed_success
    from echo_data.target import Target

    call = _handed_over(env, SINK_EPISODE, "CloseSink")
    i = Target.parse(call.target).index
    lever = env.world.handles.faucets[i]
    start = float(lever.get_qpos()[0])
    _expert_until(env, call, lambda a: float(lever.get_qpos()[0]) < start / 2)
    assert not sink_closed_success(env.world, i)
    _label_until(env, call, lambda: sink_closed_success(env.world, i), limit=200)


def test_carry_taken_over_mid_drive_is_placed(env: Any) -> None:
    """Place's expert drove the held object part of the way; a fresh labeller takes over there,
    drives on, sets it down and lets go (Place's success test)."""
    from echo_data.skills.success import place_success
    from echo_data.target import Target

    call = _handed_over(env, PICK_EPISODE, "Place")
    world = env.world
    name, goal = world.robot.holding, Target.parse(call.target).index
    assert name is not None
    steps = iter(range(60))
    _expert_until(env, call, lambda a: next(steps, None) is None)  # 60 expert steps: folded, on its way
    _label_until(env, call, lambda: world.robot.holding is None and place_success(world, name, goal), limit=400)


def test_asking_leaves_the_world_unchanged(env: Any) -> None:
    """Asked many times (each answer advances the expert a step) and across a restart, the
    labeller changes nothing in the world: robot, objects, doors, faucets, grasp, bookkeeping."""
    from echo_data.skills.labeller import ExpertLabeller

    spec = env.sample_spec("train", 2)  # Navigate, OpenDoor, Navigate, Pick, Place
    env.reset(options={"spec": spec})
    world = env.world
    before = _snapshot(world)
    for call in spec.chain[1:]:
        lab = ExpertLabeller(world, call, spec)
        answers = [lab() for _ in range(5)]
        if call.skill == "Place":  # nothing in the hand: the Place expert has nothing to do
            assert answers == [None] * 5
            continue
        assert all(a is not None for a in answers) and lab.restarts == 0, call
        lab.grasp, lab.closing = ("someone_else", False), True  # a grasp lost against the label: the expert restarts
        assert lab() is not None and lab.restarts == 1
        lab.close()
    after = _snapshot(world)
    assert before.keys() == after.keys()
    for k, v in before.items():
        assert np.array_equal(v, after[k]) if isinstance(v, np.ndarray) else v == after[k], k


@pytest.mark.parametrize("episode, skill", [(SINK_EPISODE, "CloseSink"), (DOOR_EPISODE, "OpenDoor")])
def test_asked_along_the_experts_own_path_the_labels_are_its_actions(env: Any, episode: int, skill: str) -> None:
    """DAgger's labels are the demonstrations' actions where the two meet: asked at each state of
    the expert's own rollout (advanced once per step, as a learner's rollout asks it), the
    labeller answers exactly what the expert commanded there, in every entry of `action.ee`."""
    from echo_data.skills import EXPERTS
    from echo_data.skills.labeller import ExpertLabeller

    call = _handed_over(env, episode, skill)
    gen = EXPERTS[call.skill](env.world, call, env.episode)
    lab = ExpertLabeller(env.world, call, env.episode)
    try:
        for _ in range(40):
            a = np.asarray(next(gen), np.float32)
            y = lab()
            assert y is not None
            np.testing.assert_array_equal(np.asarray(y, np.float32), a)
            env.step(env.world.robot.ee.to_joint(a))
    finally:
        gen.close()
        lab.close()
