"""The skill table (`echo_data.skill_table`) is the one place a skill's name means something:
no other module compares, looks up or lists skills by name literal, and a skill added as
docs/adding_a_skill.md says (one module + one table line, `support.toy_skill`) reaches the
planner's prompt, the recipe, the environment's chain and success evaluation, and `evaluate`'s
per-skill records without another edit."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from echo_data import skill_table
from echo_data.recipe import Recipe

PACKAGE = Path(skill_table.__file__).resolve().parent
TABLE = "skill_table.py"
# Pending elsewhere: the paper table's rows (issue 46's studies move takes them out of the package).
PENDING: set[str] = set()


def skill_literals(source: str, names: set[str]) -> list[int]:
    """Lines of `source` holding a string literal that is exactly a skill name (a comparison, a
    lookup `max_steps["Navigate"]`, a copied tuple or dict of skills: each is logic on the name)."""
    return [n.lineno for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Constant) and n.value in names]


def test_the_scan_finds_names_used_as_logic() -> None:
    names = set(skill_table.SKILLS)
    src = 'x = call.skill == "Place"\ny = cfg.max_steps["Navigate"]\nz = ("Pick", "OpenDoor")\nw = f"Place {a}"\n'
    assert skill_literals(src, names) == [1, 2, 3, 3]


def test_skill_names_are_logic_in_the_table_only() -> None:
    names = set(skill_table.SKILLS)
    found = {str(p.relative_to(PACKAGE)): skill_literals(p.read_text(), names) for p in sorted(PACKAGE.rglob("*.py"))}
    outside = {k: v for k, v in found.items() if v and k != TABLE and k not in PENDING}
    assert found[TABLE], "the table names its skills"
    assert not outside, f"skill names used as logic outside {TABLE} (read the table instead): {outside}"


@pytest.fixture
def toy(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The skill table with `support.toy_skill`'s line in place of CloseSink (both resolve a
    running faucet; the table allows one skill per target kind). Yields the toy's call log."""
    from support import toy_skill

    monkeypatch.delitem(skill_table.SKILLS, "CloseSink")  # the one table every reader holds, edited in place
    monkeypatch.setitem(skill_table.SKILLS, toy_skill.TOY.name, toy_skill.TOY)
    toy_skill.CHECKED.clear()
    return toy_skill.CHECKED


def test_a_new_skill_reaches_the_prompt_the_recipe_and_the_chains(toy: list[str]) -> None:
    from echo_data.dataset.planner import prompt
    from echo_data.skills import EXPERTS

    text = prompt(with_image=False)
    assert "- TurnTapOff(target): turn the running tap off with one push" in text and "CloseSink" not in text
    assert Recipe(name="toy").robot.max_steps["TurnTapOff"] == 200
    assert [c.skill for c in skill_table.event_chain("faucet:0", 1)] == ["Navigate", "TurnTapOff"]
    assert EXPERTS["TurnTapOff"].__name__ == "turn_tap_off"


@pytest.mark.slow
def test_a_new_skill_is_run_checked_and_scored_by_evaluate(toy: list[str]) -> None:
    """The oracle answers a running sink with the toy skill; the environment evaluates the toy's
    success test every step; `evaluate` records the skill's outcome under its name, and the
    results table reports it."""
    from echo_data.evaluation.run import evaluate
    from echo_data.evaluation.table import measured

    recipe = Recipe(name="toy", setting="state_transition", events={"categories": {"doorbell": 0.0, "sink": 1.0}})
    doc = evaluate(recipe, None, "test", 1, "oracle", "oracle")
    [episode] = doc["episodes"]
    assert [c["skill"] for c in episode["true_chain"]] == ["Navigate", "TurnTapOff"]
    assert [s["skill"] for s in episode["skills"]] == ["Navigate", "TurnTapOff"]
    assert episode["success"], episode["skills"]
    assert toy and set(toy) == {episode["skills"][1]["target"]}
    assert measured(doc)["skills"]["TurnTapOff"]["k"] == 1 and "CloseSink" not in measured(doc)["skills"]
