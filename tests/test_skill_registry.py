"""Every registered skill keeps its contract in the environment: its expert succeeds within its
step budget, and its success test — as the environment evaluates it once per step — is false
when the skill starts and true when it ends. Parametrised over the registry, so a new skill is
checked the moment its `Skill(...)` line exists (given an episode whose chain uses it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from echo_data.episode import SkillCall
from echo_data.recipe import Recipe
from echo_data.skill_table import SKILLS, default_max_steps, skill
from echo_data.target import Target

RECIPE = Recipe(name="skill-contract", setting="multi_event")
SEARCH = 12  # train indices searched for an episode that uses each skill


def test_registry_matches_the_recipe_and_the_experts() -> None:
    from echo_data.skills import EXPERTS

    assert tuple(RECIPE.robot.max_steps) == tuple(SKILLS)
    assert set(EXPERTS) == set(SKILLS)
    for s in SKILLS.values():
        assert set(s.budget) <= set(RECIPE.robot.max_steps), s.name
        assert s.step_budget(RECIPE) > sum(RECIPE.robot.max_steps[k] for k in s.budget)  # plus the guard
    assert tuple(n for n, s in SKILLS.items() if s.resolves_event) == ("Pick", "OpenDoor", "CloseSink")
    with pytest.raises(KeyError, match="known: Navigate"):
        skill("Fly")


def _holds(world: Any, call: Any, at: Any) -> int:
    return 1  # a success test named by text (lazy_test makes it a bool)


def test_the_registry_is_the_one_skill_vocabulary() -> None:
    """Skill names and default budgets come from the registry (the recipe holds no list of its
    own); chains are built from the declared roles; effects and the carried object from the
    declared fields; and the registry itself reads only the bottom layer at import."""
    import ast
    from types import SimpleNamespace

    from echo_data import skill_table as R

    assert dict(RECIPE.robot.max_steps) == default_max_steps() and tuple(default_max_steps()) == tuple(SKILLS)
    assert [c.skill for c in R.event_chain("phone_0", 0, "furniture:3")] == ["Navigate", "Pick", "Place"]
    assert [str(c.target) for c in R.event_chain("phone_0", 0, "furniture:3")] == ["phone_0", "phone_0", "furniture:3"]
    assert [c.skill for c in R.event_chain("door:1", 2)] == ["Navigate", "OpenDoor"]
    assert [c.skill for c in R.event_chain("faucet:0", 1)] == ["Navigate", "CloseSink"]
    assert all(c.event == 2 for c in R.event_chain("door:1", 2))
    with pytest.raises(ValueError, match="needs a goal"):
        R.event_chain("phone_0", 0)
    with pytest.raises(ValueError, match="resolve a furniture"):
        R.event_chain("furniture:1", 0)
    roles = {n: (s.role, s.effect, s.drives) for n, s in SKILLS.items()}
    assert roles["Navigate"] == ("approach", "", True) and roles["Place"] == ("deliver", "places_object", True)
    assert roles["OpenDoor"] == ("resolve", "opens_door", False) and roles["Pick"][2] is False
    chain = tuple(R.event_chain("phone_0", 0, "furniture:3"))
    spec = SimpleNamespace(chain=chain)
    assert R.carried_object(spec, chain[2]) == "phone_0" and R.carried_object(spec, chain[1]) is None  # type: ignore[arg-type]
    world = SimpleNamespace(receptacles={"phone_0": 1})
    R.apply_effect(world, chain[1], spec)  # type: ignore[arg-type]  # Pick: no bookkeeping
    assert world.receptacles == {"phone_0": 1}
    R.apply_effect(world, chain[2], spec)  # type: ignore[arg-type]
    assert world.receptacles == {"phone_0": 3}
    assert R.lazy_test("test_skill_registry:_holds")(None, None, None) is True  # type: ignore[arg-type]
    tree = ast.parse(Path(R.__file__).read_text())
    top = {n.module for n in tree.body if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("echo_data")}
    assert top == {"echo_data.target"}, top


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
