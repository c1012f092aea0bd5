"""Every registered skill keeps its contract in the environment: its expert succeeds within its
step budget, and its success test — as the environment evaluates it once per step — is false
when the skill starts and true when it ends. Parametrised over the registry, so a new skill is
checked the moment its `Skill(...)` line exists (given an episode whose chain uses it)."""

from __future__ import annotations

from typing import Any

import pytest

from echo_data.episode import SkillCall
from echo_data.recipe import Recipe
from echo_data.skills.registry import RESOLVING_SKILLS, SKILLS, skill
from echo_data.target import Target

RECIPE = Recipe(name="skill-contract", setting="multi_event")
SEARCH = 12  # train indices searched for an episode that uses each skill


def test_registry_matches_the_recipe_and_the_experts() -> None:
    from echo_data.recipe import SKILLS as RECIPE_SKILLS
    from echo_data.skills import EXPERTS

    assert tuple(SKILLS) == tuple(RECIPE_SKILLS)
    assert set(EXPERTS) == set(SKILLS)
    for s in SKILLS.values():
        assert set(s.budget) <= set(RECIPE.robot.max_steps), s.name
        assert s.step_budget(RECIPE) > sum(RECIPE.robot.max_steps[k] for k in s.budget)  # plus the guard
    assert RESOLVING_SKILLS == ("Pick", "OpenDoor", "CloseSink")
    with pytest.raises(KeyError, match="known: Navigate"):
        skill("Fly")


@pytest.mark.parametrize("text", ["phone_0", "door:1", "faucet:0", "furniture:12"])
def test_target_text_round_trips(text: str) -> None:
    assert str(Target.parse(text)) == text


@pytest.mark.parametrize("text", ["door:", "window:1", "door:x"])
def test_bad_target_text_is_refused(text: str) -> None:
    with pytest.raises(ValueError, match="target"):
        Target.parse(text)


@pytest.fixture(scope="module")
def runs() -> dict[str, dict[str, Any]]:
    """Per skill: its outcome (whose success is the env's flag after the skill's last step), its
    budget and the env's success flag before the skill's first action."""
    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv
    from echo_data.scene.sampling import SamplingError

    env = EchoDataEnv(RECIPE, split="train", images=False, audio=False)
    seen: dict[str, dict[str, Any]] = {}
    try:
        for index in range(SEARCH):
            try:
                spec = env.sample_spec("train", index)
            except SamplingError:
                continue
            if all(c.skill in seen for c in spec.chain):
                continue
            obs, info = env.reset(options={"spec": spec})
            first: dict[int, bool] = {}

            def hook(e: Any, o: Any, a: Any, k: int, call: SkillCall, flags: tuple[bool, ...], first: dict[int, bool] = first) -> None:
                first.setdefault(k, bool(e.success_flags[k]))

            policy = OracleSkills()
            try:
                run = run_episode(env, obs, info, OraclePlanner(), policy, on_step=hook)
            finally:
                policy.close()
            for k, (call, out) in enumerate(zip(spec.chain, run.outcomes)):
                if call.skill not in seen and k in first:
                    seen[call.skill] = {"outcome": out, "first": first[k], "budget": skill(call.skill).step_budget(RECIPE)}
            if set(seen) == set(SKILLS):
                break
    finally:
        env.close()
    return seen


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SKILLS))
def test_skill_contract(name: str, runs: dict[str, dict[str, Any]]) -> None:
    assert name in runs, f"no episode among the first {SEARCH} train indices of a multi_event recipe uses {name}"
    r = runs[name]
    out = r["outcome"]
    assert out.success, f"{name} expert failed: {out.reason}"
    assert 0 < out.steps <= r["budget"]
    assert not r["first"], f"{name}'s success test already held when the skill started"
