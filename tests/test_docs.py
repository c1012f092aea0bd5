"""The README, the docs site and the studies hold their shape: a README read in minutes, a recipes
reference that is the recipe models' rendering, user-facing pages without issue numbers, the
recipes users start from named by the README or the docs, every study folder with its README
(question, command, result, conclusion) whose command's driver parses `--help`, and the
package pointing at neither studies/ nor benchmarks/. The docs build itself (`mkdocs build
--strict`) is .ci/run's."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
STUDIES = sorted(d for d in (ROOT / "studies").iterdir() if d.is_dir() and (d / "README.md").is_file())
USER_PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "studies" / "README.md", *(d / "README.md" for d in STUDIES)]


def _generator():  # scripts/gen_recipe_reference.py, loaded as a module
    spec = importlib.util.spec_from_file_location("gen_recipe_reference", ROOT / "scripts" / "gen_recipe_reference.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_readme_is_read_in_minutes_and_keeps_the_two_commands_ci_runs() -> None:
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    assert "bash scripts/setup.sh && echo-data build recipes/quickstart.yaml" in text and "python -m pytest -q" in text
    for target in re.findall(r"\]\(([^)#]+)\)", text):  # every link and picture of the README exists
        assert (ROOT / target).exists(), target


def test_the_recipes_reference_is_the_models_rendering() -> None:
    gen = _generator()
    assert gen.PAGE.read_text() == gen.render(), "python scripts/gen_recipe_reference.py"
    from echo_data.recipe import Recipe

    page = gen.PAGE.read_text()
    assert all(f"| `{name}` |" in page for name in Recipe.model_fields)  # every top-level key is there
    assert "| `handover_noise` |" in page and "≤ `1.0`" in page  # nested keys and their limits too


def test_user_facing_pages_name_no_issue_numbers() -> None:
    for page in USER_PAGES:
        hits = re.findall(r"\b[Ii]ssues? #?\d+|(?<![\w&/])#\d{1,3}\b(?!\w)", page.read_text())
        hits = [h for h in hits if "#441" not in h]  # pyroomacoustics' issue, an upstream reference
        assert not hits, f"{page.relative_to(ROOT)}: {hits}"


def test_recipes_holds_what_users_start_from_each_named_by_the_readme_or_docs() -> None:
    recipes = sorted((ROOT / "recipes").glob("*"))
    assert len(recipes) <= 10
    text = "".join(p.read_text() for p in USER_PAGES[:1] + sorted((ROOT / "docs").glob("*.md")))
    for r in recipes:
        assert f"recipes/{r.name}" in text or f"`{r.stem}`" in text, f"{r.name}: named by neither README.md nor docs/"


def test_the_package_points_into_neither_studies_nor_benchmarks() -> None:
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in (ROOT / "echo_data").rglob("*.py")
            for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"\b(studies|benchmarks)/", line)]
    assert not hits, hits


def test_every_benchmark_is_named_in_its_readme_and_no_study_is_left_there() -> None:
    readme = (ROOT / "benchmarks" / "README.md").read_text()
    for script in (ROOT / "benchmarks").glob("*.py"):
        assert f"`{script.name}`" in readme, script.name
    assert not (ROOT / "benchmarks" / "recipes").exists() or not any((ROOT / "benchmarks" / "recipes").iterdir())


def test_the_site_lists_every_study() -> None:
    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text().replace("!!python", "#"))["nav"]
    studies = next(entry["Studies"] for entry in nav if "Studies" in entry)
    assert {s for s in studies if isinstance(s, str)} == {f"studies/{d.name}.md" for d in STUDIES}
    listed = (ROOT / "studies" / "README.md").read_text()
    assert all(f"]({d.name}/README.md)" in listed for d in STUDIES)


@pytest.mark.parametrize("study", STUDIES, ids=[d.name for d in STUDIES])
def test_a_study_readme_says_question_command_result_conclusion_and_its_command_parses(study: Path) -> None:
    text = (study / "README.md").read_text()
    assert text.startswith("# ") and "**Question.**" in text and "**Reproduce.**" in text
    assert "**Result" in text and "onclusion.**" in text
    block = re.search(r"\*\*Reproduce\.\*\*.*?```bash\n(.*?)```", text, flags=re.S)
    assert block, f"{study.name}: no command to reproduce it"
    command = block.group(1).split()
    assert command[:1] == ["python"] and command[1].startswith(f"studies/{study.name}/"), command
    driver = ROOT / command[1]
    assert driver.is_file(), driver
    r = subprocess.run([sys.executable, str(driver), "--help"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "usage" in r.stdout.lower(), r.stderr[-2000:]
    for name in re.findall(r"`results/([\w.*-]+)`", text):  # every results file the README names is there
        assert list((study / "results").glob(name)), f"{study.name}: results/{name}"


def test_every_recipe_resolves_as_it_did_before_the_studies_moved() -> None:
    """Recipes moved into studies/<name>/recipes/ with their `extends:` paths rewritten: each still
    resolves to the recipe it was (content hashes taken before the move; a dataset built from it
    is byte for byte the one before)."""
    import json

    from echo_data.recipe import load_recipe

    expected = json.loads((ROOT / "tests" / "data" / "recipe_content_hashes.json").read_text())
    found = sorted(str(p.relative_to(ROOT)) for p in [*(ROOT / "recipes").glob("*.yaml"), *(ROOT / "studies").glob("*/recipes/*.yaml")] if p.name != "base.yaml")
    assert found == sorted(expected)
    assert {path: load_recipe(ROOT / path).content_hash() for path in found} == expected


def test_the_study_readmes_result_tables_are_their_json_rendered() -> None:
    sys.path.insert(0, str(ROOT / "studies"))
    try:
        import results_tables
    finally:
        sys.path.remove(str(ROOT / "studies"))
    assert {study for study, *_ in results_tables.COPIES} >= {"learners", "navigation_ablation", "planner"}
    for study, name, results, render in results_tables.COPIES:
        held, fresh = results_tables.rendered(study, name, results, render)
        assert held == fresh, f"studies/{study}/README.md, {name}: python studies/results_tables.py"
