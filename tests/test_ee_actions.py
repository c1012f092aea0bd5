"""The end-effector action space in the environment and the data (docs/action_spaces.md).

Checks: the ee action space's bounds; the env's `action_mode` (from the recipe's
`robot.action_space`) takes 11 floats and refuses 12; the end-effector perturbation is the
drawn noise where its gate allows and nothing elsewhere; an episode whose expert commands in
end-effector form replays bit for bit from `action.executed` in joint mode and from
`action.ee.executed` in ee mode, perturbed; the perturbed expert's next labels undo the
perturbation (they point back to the goal).
"""

from __future__ import annotations

import math
from collections.abc import Generator
from pathlib import Path

import numpy as np
import pytest

from echo_data.agents.dart import QUIET_STEPS, EePerturbation, ee_noise_mask, ee_noise_std
from echo_data.envs import EchoDataEnv
from echo_data.envs.env import EnvInputError, action_space
from echo_data.recipe import Perturbation, load_recipe
from echo_data.records import EE_ACTION_DIM, SkillOutcome
from echo_data.robot.ee_control import MAX_EE_STEP, MAX_EE_TURN, base_frame
from echo_data.robot.robot import READY_GROUP
from echo_data.seeds import EE_PERTURBATION, derived_rng

ROOT = Path(__file__).resolve().parents[1]
SHAKE = Perturbation(position_cm=0.8, rotation_deg=2.0)


def test_ee_action_space_bounds() -> None:
    box = action_space("ee_delta")
    assert box.shape == (EE_ACTION_DIM,)
    assert (box.low[10], box.high[10]) == (0.0, 1.0)  # binary gripper command
    assert np.allclose(box.high[4:7], MAX_EE_STEP) and np.allclose(box.low[4:7], -MAX_EE_STEP)
    assert np.allclose(box.high[7:10], MAX_EE_TURN) and np.allclose(box.low[7:10], -MAX_EE_TURN)
    joint = action_space("joint")
    assert np.array_equal(box.low[:4], joint.low[:4]) and np.array_equal(box.high[:4], joint.high[:4])
    with pytest.raises(EnvInputError, match="action_mode"):
        action_space("cartesian")


def test_env_action_mode_follows_the_recipe_and_checks_the_shape() -> None:
    recipe = load_recipe(ROOT / "recipes" / "quickstart.yaml")
    ee = recipe.model_copy(update={"robot": recipe.robot.model_copy(update={"action_space": "ee_delta"})})
    env = EchoDataEnv(ee, split="test", images=False, audio=False)
    assert env.action_mode == "ee_delta" and env.action_space.shape == (EE_ACTION_DIM,)
    assert EchoDataEnv(recipe, images=False, audio=False).action_mode == "joint"
    assert EchoDataEnv(ee, images=False, audio=False, action_mode="joint").action_space.shape == (12,)
    with pytest.raises(EnvInputError, match="action_mode"):
        EchoDataEnv(recipe, images=False, audio=False, action_mode="ee")
    env.reset(options={"split": "test", "index": 0})
    try:
        with pytest.raises(EnvInputError, match=r"expected shape \(11,\)"):
            env.step(np.zeros(12, np.float32))
        hold = np.zeros(EE_ACTION_DIM, np.float32)
        hold[3] = env.world.robot.applied_action()[3]
        before = env.world.robot.applied_action()
        env.step(hold)  # a zero TCP change holds the arm targets exactly
        assert np.array_equal(env.world.robot.applied_action()[4:11], before[4:11])
    finally:
        env.close()


def test_perturbation_is_the_drawn_noise_where_the_gate_allows() -> None:
    hz, seed = 10, 1234
    noise = EePerturbation(SHAKE, hz, seed)
    rng = derived_rng(EE_PERTURBATION, seed)
    std = ee_noise_std(SHAKE, hz)
    assert math.isclose(std[4], 0.008) and math.isclose(std[7], math.radians(2.0))
    assert math.isclose(std[0], 0.08) and std[3] == 0.0 and std[10] == 0.0  # never torso or gripper
    moving = np.zeros(EE_ACTION_DIM, np.float32)
    moving[4] = 0.01
    driving = np.zeros(EE_ACTION_DIM, np.float32)
    driving[0] = 0.3
    closing = moving.copy()
    closing[10] = 1.0
    labels = [moving] * 5 + [driving] * 3 + [closing] * (QUIET_STEPS + 3)
    for t, label in enumerate(labels):
        got = noise(label)
        draw = rng.standard_normal(EE_ACTION_DIM) * std
        quiet = 8 <= t < 8 + QUIET_STEPS  # from the gripper's change on
        want = np.where(ee_noise_mask(label, quiet), draw, 0.0).astype(np.float32)
        assert np.array_equal(got, want), t
        if label is moving and not quiet:
            assert np.all(got[4:10] != 0) and not got[:4].any() and got[10] == 0
        if label is driving:
            assert np.all(got[:3] != 0) and not got[3:].any()
        if quiet:
            assert not got.any()


# ---------------------------------------------------------------------- ee-born episodes
def untuck_and_drive(world, call, spec) -> Generator[np.ndarray, None, SkillOutcome]:  # noqa: ANN001
    """A test expert commanding in end-effector form only: a closed-loop Cartesian move of the
    TCP (and torso) from the tuck to READY, the gripper closed, then a short drive and turn."""
    from echo_data.skills.servo import ee_command, grip, servo

    robot = world.robot
    ready = robot.ee.tcp_in_base(float(READY_GROUP[0]), np.asarray(READY_GROUP[1:], np.float64))

    def goal() -> np.ndarray:  # re-read every step from where the base stands
        return base_frame(*robot.base_pose()) @ ready

    ok = yield from servo(world, goal, torso=float(READY_GROUP[0]), max_steps=60)
    yield from grip(world, close=True, steps=3)
    for _ in range(6):
        yield ee_command(world, base=(0.15, 0.0, 0.3))
    return SkillOutcome(call.skill, call.target, bool(ok), "" if ok else "not at READY", 0)


@pytest.fixture(scope="module")
def ee_rollout() -> tuple:
    """One quickstart episode's first skill run by the ee-born test expert, perturbed."""
    from support.recipes import tiny_recipe

    from echo_data import skills
    from echo_data.app.pipeline import simulate

    recipe = tiny_recipe()
    recipe = recipe.model_copy(update={"experts": recipe.experts.model_copy(update={"perturbation": SHAKE})})
    env = EchoDataEnv(recipe, split="test", images=False, audio=False)
    spec = env.sample_spec("test", 0)
    env.close()
    with pytest.MonkeyPatch.context() as mp:  # every skill's expert is the ee-born test expert
        mp.setattr(skills, "EXPERTS", {name: untuck_and_drive for name in skills.EXPERTS})
        ro = simulate(spec, recipe, observe=True)
    return recipe, spec, ro


@pytest.mark.slow
def test_an_ee_born_episode_replays_bit_for_bit_from_either_form(ee_rollout: tuple) -> None:
    recipe, spec, ro = ee_rollout
    steps = ro.steps
    assert len(steps) > 20
    labels_ee = np.stack([s.action_ee for s in steps])
    executed_ee = np.stack([s.action_ee_executed for s in steps])
    assert np.any(labels_ee[:, 4:10] != 0, axis=1).sum() > 10  # the hand moved on many steps
    assert np.any(executed_ee != labels_ee, axis=1).mean() > 0.5  # most of them perturbed
    for mode, actions in (("joint", [s.action_executed for s in steps]), ("ee_delta", list(executed_ee))):
        env = EchoDataEnv(recipe, split="test", audio=False, action_mode=mode)
        obs, _ = env.reset(options={"spec": spec})
        try:
            for t, a in enumerate(actions):
                assert np.array_equal(obs["observation.state"], steps[t].state), f"{mode}: state differs at frame {t}"
                assert np.array_equal(obs["observation.images.head_rgb"], steps[t].head_rgb), f"{mode}: image differs at frame {t}"
                assert np.array_equal(env.world.robot.ee.to_joint(steps[t].action_ee_executed), steps[t].action_executed)
                obs, *_ = env.step(a)
        finally:
            env.close()


@pytest.mark.slow
def test_perturbed_labels_correct_toward_the_goal(ee_rollout: tuple) -> None:
    """After a perturbation knocks the commanded TCP off its way, the expert's next label (from
    the perturbed state) has a component against the knock: it steers back to the goal."""
    _, _, ro = ee_rollout
    steps = ro.steps
    against = total = 0
    for s, nxt in zip(steps, steps[1:]):
        knock = s.action_ee_executed[4:7] - s.action_ee[4:7]
        if not knock.any() or not nxt.action_ee[4:7].any():
            continue
        way = s.action_ee[4:7] / max(float(np.linalg.norm(s.action_ee[4:7])), 1e-9)
        side = knock - float(knock @ way) * way  # the part of the knock that leaves the straight way
        if float(np.linalg.norm(side)) < 1e-3:
            continue
        total += 1
        against += float(nxt.action_ee[4:7] @ side) < 0.0
    assert total >= 5
    assert against / total > 0.8, f"{against}/{total} next labels steer against the knock"


@pytest.mark.parametrize("policy", ["still", "random", "oracle"])
def test_builtin_policies_act_in_the_envs_mode(policy: str) -> None:
    """The runtime tells a policy the env's action form (`info["action_mode"]`): the built-in
    policies then return 11-float `action.ee` vectors to an ee-mode env."""
    from echo_data.agents.builtin import BUILTIN_POLICIES, OraclePlanner
    from echo_data.agents.runtime import run_episode

    recipe = load_recipe(ROOT / "recipes" / "quickstart.yaml")
    env = EchoDataEnv(recipe, split="test", images=False, audio=False, action_mode="ee_delta")
    seen: list[np.ndarray] = []
    try:
        obs, info = env.reset(options={"split": "test", "index": 0})
        run = run_episode(env, obs, info, OraclePlanner(), BUILTIN_POLICIES[policy](), max_steps=4,
                          on_step=lambda e, o, a, k, c, f: seen.append(a))
    finally:
        env.close()
    assert run.truncated_at == 4 and len(seen) == 4
    assert all(a.shape == (EE_ACTION_DIM,) for a in seen)
