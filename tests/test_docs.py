"""The README, the docs site and the studies hold their shape: a README read in minutes, a recipes
reference that is the recipe models' rendering, user-facing pages without issue numbers, the
recipes users start from named by the README or the docs, every study folder with its README
(question, command, result, conclusion) whose command's driver parses `--help`, and the
package pointing at neither studies/ nor benchmarks/. The docs build itself (`mkdocs build
--strict`) is .ci/run's."""

from __future__ import annotations

import csv
import importlib.util
import json
import re
import subprocess
import sys
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path
from typing import Any

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



def test_the_recipes_page_counts_the_recipes_episodes() -> None:
    """docs/recipes.md's table of shipped recipes gives each one's train / test episodes: the recipe's own `splits`."""
    from echo_data.recipe import load_recipe

    rows = re.findall(r"^\| `(\w+)` \| (\d+) / (\d+) \|", (ROOT / "docs" / "recipes.md").read_text(), re.M)
    assert len(rows) >= 7
    for name, train, test in rows:
        (path,) = [p for p in [ROOT / "recipes" / f"{name}.yaml", *(ROOT / "studies").glob(f"*/recipes/{name}.yaml")] if p.is_file()]
        assert load_recipe(path).splits == {"train": int(train), "test": int(test)}, f"docs/recipes.md: {name}"

def _episodes(path: str, split: str = "train", setting: str | None = None) -> str:
    """A study recipe's episodes of `split`, in all or in one `setting` of its composition."""
    from echo_data.recipe import load_recipe

    recipe = load_recipe(ROOT / path)
    if setting is None:
        return str(recipe.splits[split])
    assert recipe.composition is not None, path
    return str(recipe.composition[setting][split])


_NAV, _PLANNER, _FRESH = "studies/paper_table/recipes/nav_audio.yaml", "studies/planner/recipes/planner_audio.yaml", "studies/planner/recipes/planner_fresh.yaml"
_PICK, _DOOR = "studies/paper_table/recipes/cameras_pick_place.yaml", "studies/paper_table/recipes/cameras_door_sink.yaml"
_BCNAV = "studies/navigation_ablation/recipes/bc_navigate.yaml"
_USER = "studies/user_check/recipes/user_check.yaml"
_OR, _ST, _ME = "object_relocation", "state_transition", "multi_event"
_Count = list[tuple[str, str, str | None]]  # one figure: (recipe, split, setting or all), every one the same count


def _each(path: str, split: str) -> _Count:
    """One figure that is every setting's count ("480 per setting")."""
    return [(path, split, s) for s in (_OR, _ST, _ME)]


# (study README, quoted text, the episode counts it shows in order: each one the count of every recipe entry given)
RECIPE_COUNTS: list[tuple[str, str, list[_Count]]] = [
    ("navigation_ablation", "`studies/navigation_ablation/recipes/bc_navigate.yaml` (180 train / 54 test episodes",
     [[(_BCNAV, "train", None)], [(_BCNAV, "test", None)]]),
    ("navigation_ablation", "(`recipes/cameras_*.yaml`: 300 state-transition and 150 object-relocation training episodes",
     [[(_DOOR, "train", _ST)], [(_PICK, "train", _OR)]]),
    ("paper_table", "`studies/paper_table/recipes/nav_audio.yaml`: 600 train episodes (300 object relocation, 300 state transition)",
     [[(_NAV, "train", None)], [(_NAV, "train", _OR)], [(_NAV, "train", _ST)]]),
    ("paper_table", "`studies/paper_table/recipes/cameras_pick_place.yaml`: 150 object-relocation episodes", [[(_PICK, "train", _OR)]]),
    ("paper_table", "`studies/planner/recipes/planner_fresh.yaml`: 300 train episodes", [[(_FRESH, "train", None)]]),
    ("paper_table", "(`studies/paper_table/recipes/nav_audio_stop.yaml`: the same 600 training episodes as `nav_audio.yaml`",
     [[("studies/paper_table/recipes/nav_audio_stop.yaml", "train", None), (_NAV, "train", None)]]),
    ("learners", "`studies/paper_table/recipes/cameras_pick_place.yaml`'s 150 training episodes", [[(_PICK, "train", None)]]),
    ("planner", "1440 train episodes (480 per setting) and 280 test episodes with test sounds only (80 object relocation, 80 state transition, 120 multi-event)",
     [[(_PLANNER, "train", None)], _each(_PLANNER, "train"), [(_PLANNER, "test", None)], *([(_PLANNER, "test", s)] for s in (_OR, _ST, _ME))]),
    ("planner", "and 100 train episodes per setting (300, not 1,440", [_each(_FRESH, "train"), [(_FRESH, "train", None)], [(_PLANNER, "train", None)]]),
    ("planner", "(480 train episodes per setting, ~1,440 fresh-voice", [_each(_PLANNER, "train"), [(_PLANNER, "train", None)]]),
    ("user_check", "which no test or study uses, and 60 train, 10 validation and 50 test episodes",
     [[(_USER, "train", None)], [(_USER, "val", None)], [(_USER, "test", None)]]),
]


@pytest.mark.parametrize("study, quote, counts", RECIPE_COUNTS, ids=[f"{s}:{q[:40]}" for s, q, _ in RECIPE_COUNTS])
def test_a_study_readme_counts_its_recipes_episodes(study: str, quote: str, counts: list[_Count]) -> None:
    """A study README's dataset sizes are its recipes' splits and composition, shown in order (1,440 as 1440 too)."""
    text = " ".join((ROOT / "studies" / study / "README.md").read_text().split())
    assert quote in text, f"studies/{study}/README.md: the quote is gone; update RECIPE_COUNTS with the page"
    rest = quote.replace(",", "")
    for count in counts:
        values = {_episodes(*entry) for entry in count}  # "the same 600", "480 per setting": one count
        assert len(values) == 1, f"studies/{study}/README.md: {quote!r}: the recipes disagree ({count}: {values})"
        (n,) = values
        shown = re.search(rf"(?<!\d){n}(?!\d)", rest)
        assert shown, f"studies/{study}/README.md: {quote!r} does not show {n} ({count})"
        rest = rest[shown.end():]


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


# --- measured figures quoted in the docs pages and the studies' prose, checked against the results that hold them
# (page, quoted text, results JSON or folder, the figures the quote must show in order: a function of the JSON).
# The study READMEs render their result tables (studies/results_tables.py); a page's prose quotes, and this
# holds the quote to the JSON. A measured figure no JSON holds is not quoted on a docs page (reworded without
# it); a study README may keep one it declares "not kept" (the last test).

def _pct(v: float) -> str:
    return f"{round(100 * v)} %"


def _cell(doc: dict, metric: str, split: str = "test") -> dict:
    """studies/spatial_cues' table: the row named `metric` on `split` ({room, free}: {value, n})."""
    return next(r for r in doc["table"] if r["metric"] == metric and r["split"] == split)


def _row(doc: dict, metric: str, split: str = "test", env: str = "room") -> float:
    """studies/spatial_cues' table: the `env` value of the row named `metric`."""
    return _cell(doc, metric, split)[env]["value"]


def _kn(c: dict) -> str:
    return f"{c.get('successes', c.get('k'))}/{c.get('attempts', c.get('n'))}"


def _nums(line: str) -> list[str]:
    """The decimals of a benchmark's printed line, as printed."""
    return re.findall(r"\d+\.\d+", line)


def _vec(doc: dict, n: int) -> list[str]:
    """One N of the GPU bench_vec run: async steps/s, share, stragglers' bound; the bare floor's steps/s, share."""
    lines = doc["env"]["bench_vec"]["lines"]
    env = next(ln for ln in lines if re.match(rf"N =\s+{n} async", ln))
    floor = next(ln for ln in lines if re.search(rf"; {n} processes", ln))
    steps, _, share, bound = _nums(env)[:4]
    fsteps, fshare = _nums(floor)[1:3]
    return [steps, share, bound, fsteps, fshare]


def _trial(run: dict, *skills: str) -> list[str]:
    """An `echo-data trial --json` run as a table row: episodes, chains completed, each skill's k/n."""
    done = run.get("successes", round(run["episodes"] * run["success_rate"]))
    return [str(run["episodes"]), str(done), *(_kn(run["skills"][s]) for s in skills)]


def _first(folder: str, name: str, inputs: str) -> str:
    """The navigation ablation's first-Navigate k/n of the row `inputs` in results/`name`."""
    doc = json.loads((ROOT / folder / name).read_text())
    return _kn(next(r for r in doc["navigate"] if r["inputs"] == inputs)["first_navigate"])


def _shortfall(doc: dict, row: str, setting: str, quartiles: bool = False) -> list[str]:
    """The paper table's navigate_shortfall of a chain row: its median (or quartiles) in m and its episodes."""
    short = doc["rows"][row][setting]["metrics"]["navigate_shortfall"]
    shown = short["quartiles_m"][1:2] + (short["quartiles_m"] if quartiles else [])
    return [*(f"{q:.2f}".replace("-", "−") for q in shown), str(short["n"])]


def _gpu_env(doc: dict) -> list[str]:
    """speed.md's H200 env-step cell, from the GPU run's bench_env lines (listening thread on and off)."""
    on, off = doc["env"]["bench_env"]["lines"], doc["env"]["bench_env_listener_off"]["lines"]
    step, step_off = float(_nums(on[3])[0]), float(_nums(off[3])[0])
    return [_nums(on[0])[0], *_nums(on[1])[::2], _nums(on[3])[0], f"{float(_nums(on[4])[3]):.0f}", *_nums(on[3])[1:4:2],
            _nums(on[2])[1], _nums(off[3])[0], *_nums(off[3])[1:4:2], _pct(1 - step / step_off), _nums(on[5])[1]]


def _gpu_vec(doc: dict) -> list[str]:
    """speed.md's H200 vector-env cell, from the GPU run's bench_vec lines (prefetch on and off)."""
    rows = {n: _vec(doc, n) for n in (4, 8, 14)}
    off = next(ln for ln in doc["env"]["bench_vec_prefetch_off"]["lines"] if re.match(r"N = 14 async", ln))
    one = _nums(doc["env"]["bench_vec"]["lines"][1])[0]
    floor_one = _nums(next(ln for ln in doc["env"]["bench_vec"]["lines"] if "; 4 processes" in ln))[0]
    return [one, *(x for n in (4, 8) for x in (f"{float(rows[n][0]):.0f}", rows[n][1])), f"{float(rows[14][0]):.0f}", rows[14][1], rows[14][2],
            f"{float(_nums(off)[0]):.0f}", floor_one, *(f"{float(rows[n][3]):.0f}" for n in (4, 8, 14)), *(rows[n][4] for n in (4, 8, 14)),
            f"{float(rows[14][0]) / float(rows[14][3]):.2f}"]


def _determinism_price(doc: dict) -> list[str]:
    """learners.md's price of deterministic kernels: ACT's strict against default samples/s on the GPU, the
    whole Pick's optimiser steps at the strict pace (minutes), and the whole CPU run (minutes)."""
    t = doc["training"]
    full = {r["id"]: r["result"]["full"] for r in t["runs"]}
    strict, default = full["act_strict"], full["act_default_kernels"]
    gpu_min = t["whole_skill_steps"] * strict["train_seconds"] / strict["steps"] / 60
    cpu_s = float(re.search(r"([\d,]+) s in all", t["cpu_here"]["whole_pick_run"]).group(1).replace(",", ""))
    return [f"{default['samples_per_second'] / strict['samples_per_second']:.0f}", f"{gpu_min:.0f}", f"{cpu_s / 60:.0f}"]


def _beyond_3rc(doc: dict) -> str:
    """The plain ILD's agreement beyond 3 r_c: the 3–5 and 5+ r_c bins of spatial_cues pooled."""
    bins = doc[_DIST]["plain_ild_by_distance"][3:]
    return f"{sum(b['plain_ild_agreement'] * b['n'] for b in bins) / sum(b['n'] for b in bins):.2f}"


def _span(doc: dict, metrics: list[str]) -> list[str]:
    """The lowest and highest room value of spatial_cues' test rows `metrics`."""
    values = [_row(doc, m) for m in metrics]
    return [f"{min(values):.2f}", f"{max(values):.2f}"]


_TILED = [f"{e}, {w}" for e in ("coherence-selected", "onset-weighted") for w in ("100ms", "1s")]
_GAP = "ILD sign = source side, line of sight, source silent in the step's 100 ms (a gap)"
_LR = "left/right classifier on test steps{}, mirror-symmetric (onset3 features, C = 0.01, chosen on train validation)"


def _listener_cues(doc: dict) -> list[str]:
    """environment.md's listener cues on the test episodes: onset-weighted over 1 s (overall and per sound),
    coherence-selected over 1 s, and every tiled estimator over 100 ms."""
    los = "sign = source side, line of sight"
    sounds = ("furby (tonal)", "alarm (tonal)", "doorbell (tonal)", "sink (broadband)", "phone (tonal)")
    per = [f"{_row(doc, f'ILD onset-weighted, 1s: {s}, line of sight'):.2f}" for s in sounds]
    return [f"{_row(doc, f'ILD onset-weighted, 1s: {los}'):.2f}", min(per), max(per), *per,
            f"{_row(doc, f'ITD onset-weighted, 1s: {los}'):.2f}", f"{_row(doc, 'ITD onset-weighted, 1s: alarm (tonal), line of sight'):.2f}",
            f"{_row(doc, 'ITD, alarm (tonal), line of sight', 'train+test', 'free'):.2f}",
            f"{_row(doc, 'ITD onset-weighted, 1s: alarm (tonal), line of sight', env='free'):.2f}",
            *(f"{_row(doc, f'{c} coherence-selected, 1s: {los}'):.2f}" for c in ("ILD", "ITD")),
            *_span(doc, [f"{c} {e}, 100ms: {los}" for c in ("ILD", "ITD") for e in ("coherence-selected", "onset-weighted")])]


def _share(c: dict) -> list[str]:
    """A {correct, n, accuracy, ci95} cell as the pages print it: k/n = share [low, high]."""
    def half_up(x: float) -> str:  # the JSON's 3-decimal bounds as the page rounds them (0.745 → 0.75)
        return str(Decimal(str(x)).quantize(Decimal("0.01"), ROUND_HALF_UP))

    return [f"{c['correct']}/{c['n']}", half_up(c["accuracy"]), *map(half_up, c["ci95"])]


def _door_sink(folder: str) -> list[str]:
    """SIMULATION_NOTES' door and sink experts from the interaction pose and from hand-over starts."""
    start = {s: json.loads((ROOT / folder / f"door_sink_experts_{s}.json").read_text())["skills"] for s in ("interaction", "handover")}
    door, sink = ({s: start[s][k] for s in start} for k in ("OpenDoor", "CloseSink"))
    return [_kn(door["interaction"]), f"{door['interaction']['low']:.3f}", _kn(door["handover"]), str(door["handover"]["steps_max"]),
            _kn(sink["interaction"]), _kn(sink["handover"]), str(max(sink[s]["steps_max"] for s in sink))]



def _dagger(lines: list[str]) -> list[str]:
    """A DAgger run's log (its dagger.csv lines) as the ablation's table cell: rounds, train rollouts,
    rows aggregated, and the learner's successes in each round's rollouts."""
    rounds = list(csv.DictReader(lines))
    n = [len(r["episodes"].split()) for r in rounds]
    return [f"{len(rounds)} round", str(sum(n)), f"{int(rounds[-1]['rows_aggregated']):,}",
            *(f"{round(float(r['learner_success']) * k)}/{k}" for r, k in zip(rounds, n))]


def _dagger_stored(folder: str) -> list[str]:
    """The stored-audio DAgger row, run by hand: its log (dagger.csv) and its evaluation's first Navigate,
    every Navigate and mean SPL, then the log's best validation loss."""
    log = (ROOT / folder / "ablation_dagger-nav-audio-depth-state-dagger1.dagger.csv").read_text().splitlines()
    m = json.loads((ROOT / folder / "ablation_dagger-nav-audio-depth-state-dagger1.json").read_text())["metrics"]["all"]
    first = next(p for p in m["progressive"] if p["through"] == 1)
    return [*_dagger(log), _kn(first), *(f"{b:.2f}" for b in (first["value"], *first["ci95"])), _kn(m["navigate_success"]),
            f"{m['navigate_spl']['value']:.2f}", f"{float(log[-1].split(',')[-1]):.3f}"]


def _dagger_row(doc: dict) -> list[str]:
    """An ablation DAgger JSON's one row from its DAgger cell on: the log, first and all Navigates, SPL, val loss."""
    r = doc["navigate"][0]
    return [*_dagger(r["dagger_log"]), _kn(r["first_navigate"]), _kn(r["all_navigate"]), f"{r['spl_mean']:.2f}", f"{r['best_val_loss']:.3f}"]


def _ablation(doc: dict, run: str, n: int) -> list[str]:
    """A camera_ablations.json run as the learners study's row: validation at the last epoch (k of the `n`
    validation episodes), alone, after a hand-over."""
    r = doc["runs"][run]
    ((skill, det),) = r["details"].items()
    (training,) = det["training"].values()
    return [f"{round(training['validation']['val_success'] * n)}/{n}", _kn(r["skills"][skill]), _kn(r["skills_handover"][skill])]


def _nine(folder: str) -> list[str]:
    """The learners study's validation on nine episodes: none's best 6/9 and the shipped learner's 3/9 with their Wilson bounds."""
    from echo_data.evaluation.metrics import wilson

    none = json.loads((ROOT / folder / "learners/results/camera_ablations.json").read_text())["runs"]["perturbation_none"]
    shipped = json.loads((ROOT / folder / "paper_table/results/paper_table.json").read_text())["training"]["CloseSink"]["last"]
    ks = [round(none["details"]["CloseSink"]["training"]["action.ee-act"]["best_val_success"] * 9), round(shipped["val_success"] * 9)]
    return [*(f"{k}/9" for k in ks), *(f"{b:.2f}" for k in ks for b in wilson(k, 9))]


def _pooled(doc: dict, level: str, column: str) -> str:
    """camera_ablations.json's two CloseSink trainings of one perturbation level, pooled: alone
    (`skills`) or after a hand-over (`skills_handover`). The shipped level's first training is the
    reference block's (its weights are gone)."""
    runs = doc["runs"]
    if level == "shipped":
        first = doc["reference"]["CloseSink"]["alone" if column == "skills" else "after_handover"]
        cells = [dict(zip(("successes", "n"), map(int, first.split("/")))), runs["perturbation_shipped"][column]["CloseSink"]]
    else:
        cells = [runs[f"perturbation_{level}{seed}"][column]["CloseSink"] for seed in ("", "_seed1")]
    return f"{sum(c['successes'] for c in cells)}/{sum(c['n'] for c in cells)}"


def _pooled_cells(doc: dict, column: str) -> list[str]:
    """The pooled perturbation levels none / shipped / twice as the learners study prints them: k/n [low, high]."""
    from echo_data.evaluation.metrics import wilson

    cells = [_pooled(doc, level, column) for level in ("none", "shipped", "twice")]
    return [x for c in cells for x in (c, *(f"{b:.2f}" for b in wilson(*map(int, c.split("/")))))]


_CUES, _DIST = "studies/spatial_cues/results/spatial_cues.json", "distances"
_ABL = "studies/navigation_ablation/results"  # a folder: its entries read the files they name
_GPU = "benchmarks/results/gpu_figures.json"
_ABLATIONS = "studies/learners/results/camera_ablations.json"
_PAPER = "studies/paper_table/results/paper_table.json"
_EXPERTS, _NOISE = "studies/experts/results/pick_place_experts.json", "studies/experts/results/expert_noise.json"
# docs/environment.md's two spatial-cue tables: (the row as the page prints it, the JSON's metric, its split)
_CUE_ROWS: list[tuple[str, str, str]] = [
    ('| ILD sign = source side, line of sight | 0.65 (n=1405) | 0.89 (n=1405) | ≥ 0.85 |',
     'ILD sign = source side, line of sight', 'train+test'),
    ('| … within the critical distance r_c | 0.69 (n=71) | 0.80 (n=71) | |',
     'ILD sign = source side, line of sight, within the critical distance', 'train+test'),
    ('| … beyond r_c | 0.65 (n=1334) | 0.89 (n=1334) | |',
     'ILD sign = source side, line of sight, beyond the critical distance', 'train+test'),
    ("| … source audible in the step's 100 ms | 0.69 (n=1080) | 1.00 (n=1080) | |",
     "ILD sign = source side, line of sight, source audible in the step's 100 ms", 'train+test'),
    ("| … source silent in the step's 100 ms (a gap in the sound) | 0.51 (n=325) | 0.52 (n=325) | |",
     "ILD sign = source side, line of sight, source silent in the step's 100 ms (a gap)", 'train+test'),
    ('| ILD sign = doorway side, behind a wall | 0.65 (n=99) | 0.93 (n=99) | ≥ 0.75 |',
     'ILD sign = doorway side, behind a wall', 'train+test'),
    ('| ITD sign = source side, line of sight | 0.67 (n=802) | 0.89 (n=813) | ≥ 0.85 |',
     'ITD sign = source side, line of sight', 'train+test'),
    ("| … source audible in the step's 100 ms | 0.68 (n=706) | 0.91 (n=771) | |",
     "ITD sign = source side, line of sight, source audible in the step's 100 ms", 'train+test'),
    ('| ITD sign = doorway side, behind a wall | 0.52 (n=66) | 0.95 (n=64) | ≥ 0.75 |',
     'ITD sign = doorway side, behind a wall', 'train+test'),
    ('| median level rise over Navigate (dB) | 7.85 (n=40) | 13.32 (n=40) | ≥ 8 |',
     'median level rise over Navigate (dB)', 'train+test'),
    ('| left/right classifier (spectrogram L−R, as before), test steps | 0.71 (n=873) | 0.97 (n=873) | ≥ 0.85 |',
     'left/right classifier on test spectrograms (spectrogram L−R, C = 0.05, as before)', 'test'),
    ('| ILD plain 100 ms, line of sight | 0.70 (n=558) | 0.90 (n=558) | ≥ 0.85 |',
     'ILD plain 100 ms: sign = source side, line of sight', 'test'),
    ('| ILD coherence-selected (c0 0.98, 1.5–8 kHz), 1 s, line of sight | 0.71 (n=558) | 0.97 (n=558) | ≥ 0.85 |',
     'ILD coherence-selected, 1s: sign = source side, line of sight', 'test'),
    ('| **ILD onset-weighted (rise > 6 dB), 1 s, line of sight** | **0.93 (n=558)** | 0.99 (n=558) | ≥ 0.85 |',
     'ILD onset-weighted, 1s: sign = source side, line of sight', 'test'),
    ('| ITD plain 100 ms, line of sight | 0.67 (n=362) | 0.90 (n=374) | ≥ 0.85 |',
     'ITD plain 100 ms: sign = source side, line of sight', 'test'),
    ('| ITD coherence-selected (c0 0.99, 0.3–1.5 kHz), 1 s, line of sight | 0.77 (n=558) | 0.86 (n=558) | ≥ 0.85 |',
     'ITD coherence-selected, 1s: sign = source side, line of sight', 'test'),
    ('| ITD onset-weighted (rise > 1 dB), 1 s, line of sight | 0.80 (n=558) | 0.93 (n=558) | ≥ 0.85 |',
     'ITD onset-weighted, 1s: sign = source side, line of sight', 'test'),
    ('| ILD plain 100 ms, doorway side behind a wall | 0.75 (n=60) | 0.92 (n=60) | ≥ 0.75 |',
     'ILD plain 100 ms: sign = doorway side, behind a wall', 'test'),
    ('| ILD onset-weighted, 1 s, doorway side behind a wall | 0.72 (n=60) | 0.95 (n=60) | ≥ 0.75 |',
     'ILD onset-weighted, 1s: sign = doorway side, behind a wall', 'test'),
    ('| ITD onset-weighted, 1 s, doorway side behind a wall | 0.45 (n=60) | 0.93 (n=60) | ≥ 0.75 |',
     'ITD onset-weighted, 1s: sign = doorway side, behind a wall', 'test'),
    ('| left/right classifier, mirror-symmetric, onset-weighted log-mel ILDs (C 0.01), all test steps | 0.75 (n=873) | 0.97 (n=873) | ≥ 0.85 |',
     'left/right classifier on test steps, mirror-symmetric (onset3 features, C = 0.01, chosen on train validation)', 'test'),
    ('| … line-of-sight test steps | **0.89 (n=558)** | 0.96 (n=558) | |',
     'left/right classifier on test steps, line of sight, mirror-symmetric (onset3 features, C = 0.01, chosen on train validation)', 'test'),
    ('| … behind a wall, against the doorway side | **0.88 (n=60)** | 0.95 (n=60) | ≥ 0.75 |',
     'left/right classifier on test steps behind a wall = doorway side, mirror-symmetric (onset3 features, C = 0.01)', 'test'),
    ('| … behind a wall, against the source side | 0.50 (n=315) | 0.98 (n=315) | |',
     'left/right classifier on test steps, behind a wall, mirror-symmetric (onset3 features, C = 0.01, chosen on train validation)', 'test'),
]


FIGURES: list[tuple[str, str, str, Any]] = [
    ("docs/acoustics.md", "95 % of the benchmark's line-of-sight steps lie beyond r_c", _CUES,
     lambda d: [_pct(d[_DIST]["share_beyond_critical_distance"])]),
    ("docs/acoustics.md", "distance 1.62 m, median r_c 0.66 m, median direct-to-reverberant ratio −8.7 dB", _CUES,
     lambda d: [f"{d[_DIST]['median_distance_m']:.2f}", f"{d[_DIST]['median_critical_distance_m']:.2f}",
                f"{d[_DIST]['median_direct_to_reverberant_db']:.1f}".replace("-", "−")]),
    ("docs/acoustics.md", "agrees with the source's side 0.73 at 1–2 r_c, 0.70 at 2–3 r_c, 0.58 beyond 3 r_c", _CUES,
     lambda d: [*(f"{b['plain_ild_agreement']:.2f}" for b in d[_DIST]["plain_ild_by_distance"][1:3]), _beyond_3rc(d)]),
    ("docs/acoustics.md", "spread of 3.3 dB measured beyond 3 r_c) predicts 0.65, 0.56 and 0.51–0.53", _CUES,
     lambda d: [f"{d[_DIST]['diffuse_model_ild_agreement']['reverberant_ild_spread_db']:.1f}",
                *(f"{b['diffuse_model']:.2f}" for b in (d[_DIST]["plain_ild_by_distance"][i] for i in (1, 2, 4, 3)))]),
    ("docs/acoustics.md", "at 1405 line-of-sight steps", _CUES, lambda d: [str(d[_DIST]["los_steps"])]),
    ("docs/acoustics.md", "23 % of those steps fall into a gap of the sound", _CUES, lambda d: [_pct(d[_DIST]["share_los_steps_source_silent"])]),
    ("docs/acoustics.md", "the ILD agrees at 0.51 in the rooms and 0.52 in the free field; where the source is audible "
     "the free field agrees at 1.00 and the rooms at 0.69", _CUES,
     lambda d: [f"{_row(d, m, 'train+test', e):.2f}" for m, e in (
         ("ILD sign = source side, line of sight, source silent in the step's 100 ms (a gap)", "room"),
         ("ILD sign = source side, line of sight, source silent in the step's 100 ms (a gap)", "free"),
         ("ILD sign = source side, line of sight, source audible in the step's 100 ms", "free"),
         ("ILD sign = source side, line of sight, source audible in the step's 100 ms", "room"))]),
    ("docs/acoustics.md", "onset-weighted ILD agrees with the source's side at 0.93 of line-of-sight steps, the ITD at 0.80; "
     "the coherence-selected ones at 0.71 and 0.77", _CUES,
     lambda d: [f"{_row(d, f'{c} {w}, 1s: sign = source side, line of sight'):.2f}"
                for w in ("onset-weighted", "coherence-selected") for c in ("ILD", "ITD")]),
    ("docs/acoustics.md", "tells left from right at 0.89 of line-of-sight test steps", _CUES,
     lambda d: [f"{_row(d, 'left/right classifier on test steps, line of sight, mirror-symmetric (onset3 features, C = 0.01, chosen on train validation)'):.2f}"]),
    *(("docs/manipulation_experts.md", q, _EXPERTS, lambda d, i=i, sk=sk: _trial(d["chains_noise_off"][i], *sk)) for q, i, sk in (
        ("| experts_object_relocation | off | 100 | 99 | Pick 100/100, Place 99/100", 0, ("Pick", "Place")),
        ("| experts_state_transition | off | 50 | 50 | OpenDoor 21/21, CloseSink 29/29", 1, ("OpenDoor", "CloseSink")),
        ("| experts_multi_event | off | 30 | 30 | Pick 30/30, Place 30/30, OpenDoor 14/14, CloseSink 16/16", 2, ("Pick", "Place", "OpenDoor", "CloseSink")))),
    ("docs/manipulation_experts.md", "`door_sink_experts_200.json`) | off | 200 | 200 | OpenDoor 98/98, CloseSink 102/102",
     "studies/experts/results/door_sink_experts_200.json", lambda d: _trial(d["trial"], "OpenDoor", "CloseSink")),
    *(("docs/manipulation_experts.md", q, _NOISE, lambda d, i=i, sk=sk: _trial(d["perturbation"]["runs"][i], *sk)) for q, i, sk in (
        ("| experts_object_relocation_perturbed | 0.5 cm / 1° | 60 | 58 | Pick 59/60, Place 58/59", 0, ("Pick", "Place")),
        ("| experts_state_transition_perturbed | 0.5 cm / 1° | 60 | 60 | OpenDoor 28/28, CloseSink 32/32", 1, ("OpenDoor", "CloseSink")),
        ("| experts_multi_event_perturbed | 0.5 cm / 1° | 30 | 30 | Pick 30/30, Place 30/30, OpenDoor 14/14, CloseSink 16/16", 2,
         ("Pick", "Place", "OpenDoor", "CloseSink")),
        ("| recipes/sanity_pick_place (handover 1.0) | 0.5 cm / 1° | 40 | 37 | Pick 39/40, Place 37/39", 3, ("Pick", "Place")),
        ("| recipes/sanity_door_sink (handover 1.0) | 0.5 cm / 1° | 40 | 40 | OpenDoor 20/20, CloseSink 20/20", 4, ("OpenDoor", "CloseSink")))),
    ("docs/manipulation_experts.md", "Before: Pick 3 of 10 at 0.5 cm / 1°", _NOISE,
     lambda d: [f"{d['perturbation']['before']['Pick']['successes']} of {d['perturbation']['before']['Pick']['attempts']}"]),
    ("docs/manipulation_experts.md", "Navigate 100/100, Pick 100/100, Place 92/100 (seven furbies fell over, one elbow touched a wall in a turn)", _EXPERTS,
     lambda d: [*(_kn(d["trial_before_release_fix"]["skills"][s]) for s in ("Navigate", "Pick", "Place")),
                *({1: "one", 7: "seven"}.get(d["trial_before_release_fix"]["failures"][f], "?") for f in ("Place: not on goal", "Place: collision"))]),
    ("docs/manipulation_experts.md", "Pick 30/30, Place after it 28/30 (two furbies fell over)", _EXPERTS,
     lambda d: [*(_kn(d["handover"][s]) for s in ("Pick", "Place")), {2: "two"}.get(d["handover"]["Place"]["n"] - d["handover"]["Place"]["successes"], "?")]),
    ("docs/manipulation_experts.md", "Place 99/100 (1 collision: an elbow touched a wall in a turn)", _EXPERTS,
     lambda d: [_kn(d["chains_noise_off"][0]["skills"]["Place"]), str(d["chains_noise_off"][0]["failures"]["Place: collision"])]),
    ("docs/manipulation_experts.md", "Place 58/59 (1 timeout)", _NOISE,
     lambda d: [_kn(d["perturbation"]["runs"][0]["skills"]["Place"]), str(d["perturbation"]["runs"][0]["failures"]["Place: timeout"])]),
    ("docs/manipulation_experts.md", "Rows per Pick segment (10 episodes): 143 on average, of which 5 base, 27 untuck (the only "
     "object-independent phase, 19 %) and 110 after it (77 %)", _EXPERTS,
     lambda d: [str(d["figures"]["episodes"]), *(f"{d['figures']['pick_rows_per_segment'][k]:.0f}" for k in ("rows", "base", "untuck")),
                _pct(d["figures"]["pick_rows_per_segment"]["untuck"] / d["figures"]["pick_rows_per_segment"]["rows"]),
                f"{d['figures']['pick_rows_per_segment']['object']:.0f}", _pct(d["figures"]["pick_object_share"])]),
    ("docs/manipulation_experts.md", "The object in some camera: 90 % of Pick rows (head 86 %, wrist 60 %); 100 % once the jaws have "
     "closed and in every Place row (wrist 100 %). The rows without it are contiguous, 49-69 rows", _EXPERTS,
     lambda d: [*(_pct(d["figures"]["visible_pick"][k]) for k in ("some_camera", "head", "wrist")),
                _pct(d["figures"]["visible_pick_object_phase_closed"]["some_camera"]), _pct(d["figures"]["visible_place"]["wrist"]),
                f"{min(map(int, d['figures']['unseen_rows_before_close']))}-{max(map(int, d['figures']['unseen_rows_before_close']))}"]),
    ("docs/manipulation_experts.md", "0.00 rad at the end of the untuck, 0.55 rad at the hover, 0.54 rad at the grasp", _EXPERTS,
     lambda d: [f"{d['figures']['joint_spread_rad'][k]:.2f}" for k in ("untuck_end", "hover", "grasp")]),
    *(("docs/environment.md", row, _CUES, lambda d, m=m, sp=sp: [x for env in ("room", "free") for x in (
        f"{_cell(d, m, sp)[env]['value']:.2f}", str(_cell(d, m, sp)[env]["n"]))]) for row, m, sp in _CUE_ROWS),
    ("docs/environment.md", "**Plain 100 ms ILD/ITD ≥ 0.85 in line of sight: not met (0.65 / 0.67), and physics says they cannot be.** "
     "The furnished rooms' critical distance is 0.66 m", _CUES,
     lambda d: [f"{_row(d, f'{c} sign = source side, line of sight', 'train+test'):.2f}" for c in ("ILD", "ITD")]
     + [f"{d[_DIST]['median_critical_distance_m']:.2f}"]),
    ("docs/environment.md", "and 95 % of those steps lie beyond it (median 1.62 m, median direct-to-reverberant ratio −8.7 dB). "
     "The plain ILD agrees 0.73 at 1–2 r_c (n=439), 0.70 at 2–3 r_c (n=238) and 0.58 beyond 3 r_c (n=657)", _CUES,
     lambda d: [_pct(d[_DIST]["share_beyond_critical_distance"]), f"{d[_DIST]['median_distance_m']:.2f}",
                f"{d[_DIST]['median_direct_to_reverberant_db']:.1f}".replace("-", "−"),
                *(x for b in d[_DIST]["plain_ild_by_distance"][1:3] for x in (f"{b['plain_ild_agreement']:.2f}", str(b["n"]))),
                _beyond_3rc(d),
                str(d[_DIST]["diffuse_model_ild_agreement"]["n_steps_beyond_3rc"])]),
    ("docs/environment.md", "spread of 3.3 dB measured beyond 3 r_c — predicts 0.65, 0.56 and 0.51–0.53 for the same bins "
     "(0.57 beyond r_c against 0.65 measured)", _CUES,
     lambda d: [f"{d[_DIST]['diffuse_model_ild_agreement']['reverberant_ild_spread_db']:.1f}",
                *(f"{d[_DIST]['plain_ild_by_distance'][i]['diffuse_model']:.2f}" for i in (1, 2, 4, 3)),
                f"{d[_DIST]['diffuse_model_ild_agreement']['beyond_rc']:.2f}",
                f"{_row(d, 'ILD sign = source side, line of sight, beyond the critical distance', 'train+test'):.2f}"]),
    ("docs/environment.md", "The free field itself reaches only 0.89 because 23 % of these steps fall into a gap", _CUES,
     lambda d: [f"{_row(d, 'ILD sign = source side, line of sight', 'train+test', 'free'):.2f}", _pct(d[_DIST]["share_los_steps_source_silent"])]),
    ("docs/environment.md", "where any head guesses (0.51–0.52); where the source is audible the free-field ILD agrees at 1.00 and the rooms' at 0.69", _CUES,
     lambda d: [f"{_row(d, _GAP, 'train+test', e):.2f}" for e in ("room", "free")]
     + [f"{_row(d, _GAP.replace('silent', 'audible').replace(' (a gap)', ''), 'train+test', e):.2f}" for e in ("free", "room")]),
    ("docs/environment.md", "Weighting the tiles of the last second by their onsets gives 0.93 for the ILD (per sound 0.87–0.98: furby 0.87, "
     "alarm 0.91, doorbell 0.91, sink 0.95, phone 0.98) and 0.80 for the ITD (alarm 0.63, whose ITD is weak in the free field too: "
     "plain 0.61, onset-weighted 0.84). Coherence selection gives 0.71 (ILD) and 0.77 (ITD). Over a step's 100 ms every tiled "
     "estimator stays at 0.68–0.74", _CUES, _listener_cues),
    ("docs/environment.md", "met by the plain ILD on the test episodes (0.75, n=60; 0.65 on all 30 episodes, n=99) and by the classifier (0.88), "
     "not by the plain ITD (0.52) or the tiled ITD (0.45–0.60)", _CUES,
     lambda d: [f"{_row(d, 'ILD plain 100 ms: sign = doorway side, behind a wall'):.2f}", "60",
                f"{_row(d, 'ILD sign = doorway side, behind a wall', 'train+test'):.2f}", "99",
                f"{_row(d, 'left/right classifier on test steps behind a wall = doorway side, mirror-symmetric (onset3 features, C = 0.01)'):.2f}",
                f"{_row(d, 'ITD sign = doorway side, behind a wall', 'train+test'):.2f}",
                *_span(d, [f"ITD {w}: sign = doorway side, behind a wall" for w in _TILED])]),
    ("docs/environment.md", "**Median level rise ≥ 8 dB: not met (7.85 dB, n=40 Navigate runs; free field 13.3 dB).**", _CUES,
     lambda d: [f"{_row(d, 'median level rise over Navigate (dB)', 'train+test'):.2f}", "40",
                f"{_row(d, 'median level rise over Navigate (dB)', 'train+test', 'free'):.1f}"]),
    ("docs/environment.md", "met on line-of-sight steps (0.89) and against the doorway side behind a wall (0.88), not on all test steps (0.75)**, "
     "because behind a wall (315 of 873 test steps) the source's own side is not what reaches the ears (0.50 there; the free field has no "
     "walls: 0.98). The gain over the plain classifier (0.71 → 0.75 overall)", _CUES,
     lambda d: [f"{_row(d, _LR.format(', line of sight')):.2f}",
                f"{_row(d, 'left/right classifier on test steps behind a wall = doorway side, mirror-symmetric (onset3 features, C = 0.01)'):.2f}",
                f"{_row(d, _LR.format('')):.2f}", str(_cell(d, _LR.format(', behind a wall'))["room"]["n"]), str(_cell(d, _LR.format(''))["room"]["n"]),
                f"{_row(d, _LR.format(', behind a wall')):.2f}", f"{_row(d, _LR.format(', behind a wall'), env='free'):.2f}",
                f"{_row(d, 'left/right classifier on test spectrograms (spectrogram L−R, C = 0.05, as before)'):.2f}", f"{_row(d, _LR.format('')):.2f}"]),
    ("docs/recipes.md", "single event 130/160 = 0.81 [0.75, 0.87], multi-event 63/120 = 0.53 [0.44, 0.61]", "studies/planner/results/planner_audio.json",
     lambda d: [x for g in ("single_event", "multi_event") for x in _share(d["rows"][0]["test"][g]["events_in_order"])]),
    *(("docs/recipes.md", f"| {setting} | " + " | ".join(cells), _NOISE, lambda d, setting=setting: [
        f"{r['successes']}/{r['episodes']}" for r in d["runs"] if r["recipe"] == f"recipes/{setting}.yaml"]) for setting, cells in (
        ("object_relocation", ("10/10", "9/10 (Place: not on goal 1)", "9/10 (Place: not on goal 1)", "4/10 (Place: not on goal 3, collision 2, no IK 1)")),
        ("multi_event", ("10/10", "8/10 (Pick: no IK 1, Place: not on goal 1)", "7/10 (Pick: no IK 1, Place: not on goal 2)",
                         "6/10 (Place: not on goal 3, Pick: slipped 1)")))),
    ("docs/recipes.md", "Up to 1.0 the experts still succeed on 9/10 and 7/10", _NOISE,
     lambda d: [f"{r['successes']}/{r['episodes']}" for r in d["runs"] if r["action_noise"] == 1.0]),
    ("docs/SIMULATION_NOTES.md", "OpenDoor 149/149 = 1.00 [0.975, 1.00] from the interaction pose and 149/149 from hand-over starts drawn anywhere "
     "in Navigate's success region (at most 247 of its 300 steps, for a start close to the door in a straight line but far from it "
     "round a wall); CloseSink 151/151 and 151/151 (at most 144 of 200 steps)", "studies/experts/results", _door_sink),
    ("docs/SIMULATION_NOTES.md", "the planner-based expert's lay far apart (24 episodes, `--expert` with the previous version)",
     "studies/experts/results/door_sink_experts_baseline_planner.json", lambda d: [re.search(r" -n (\d+) ", d["command"]).group(1)]),
    ("docs/SIMULATION_NOTES.md", "on the right take mirrored paths (1.2 rad apart)", "studies/experts/results/door_sink_experts_interaction.json",
     lambda d: [f"{d['skills']['OpenDoor']['spread']['path_gap_median']:.1f}"]),
    ("docs/manipulation_experts.md", "(all seven \"not on goal\" failures of the 100-episode trial)", _EXPERTS,
     lambda d: [{7: "seven"}.get(d["trial_before_release_fix"]["failures"]["Place: not on goal"], "?"), str(d["trial_before_release_fix"]["episodes"])]),
    ("docs/manipulation_experts.md", "the seven episodes placed, and 0 falls in 100", _EXPERTS,
     lambda d: [str(d["chains_noise_off"][0]["failures"].get("Place: not on goal", 0)), str(d["chains_noise_off"][0]["episodes"])]),
    ("docs/learners.md", "deterministic kernel is 5× slower than torch's default (`benchmarks/results/gpu_figures.json`); the whole Pick "
     "optimisation still takes about 3 minutes there against 25 on one CPU core", _GPU, _determinism_price),
    ("docs/learners.md", "CloseSink 20/20 against 12/20 with 31 demonstrations, OpenDoor 1/10 against 3/10", "studies/learners/results/door_sink_val.json",
     lambda d: [_kn(d["runs"][r][s]) for s in ("CloseSink", "OpenDoor") for r in ("300 episodes", "60 episodes")]),
    ("docs/learners.md", "delta + DART 3/20, absolute + DART 1/20, delta without noise 0/20, delta + GRU 0/20, delta + head RGB 0/20",
     "studies/learners/results/pick_val.json", lambda d: [_kn(r["pick_success_val"]) for r in d["runs"]]),
    ("docs/learners.md", "audio, state 18/54 stored → 29/54 level + ILD; audio, depth, state 32/54 → 39/54", _ABL,
     lambda d: [_first(d, "ablation.json", "audio,state"), _first(d, "ablation_ild.json", "audio,state"),
                _first(d, "ablation.json", "audio,depth,state"), _first(d, "ablation_ild.json", "audio,depth,state")]),
    ("docs/learners.md", "(audio, state: first Navigate 29/54 with level + ILD audio, 18/54 with the stored spectrogram, "
     "against 5/54 without audio; audio, depth, state 39/54", _ABL,
     lambda d: [_first(d, "ablation_ild.json", "audio,state"), _first(d, "ablation.json", "audio,state"),
                _first(d, "ablation.json", "state"), _first(d, "ablation_ild.json", "audio,depth,state")]),
    ("docs/learners.md", "DAgger on `state, target` took Navigate from 6/16 to 13/16", _ABL,
     lambda d: [_first(d, "ablation_small.json", "state,target"), _first(d, "ablation_small_dagger.json", "state,target")]),
    ("docs/learners.md", "object relocation, the experts 0.03 m (50 episodes), the learned Navigate given the target position "
     "(`oracle planner + learned skills*`) 1.31 m short (quartiles −0.06, 1.31, 1.44 m; 37 episodes), the learned Navigate from "
     "sound (`oracle planner + learned skills`) 0.28 m short (27 episodes), ending anywhere in the region. State transition: "
     "experts 0.03 m, Navigate* 1.42 m short (45), from sound 0.72 m short (38)", _PAPER,
     lambda d: [*_shortfall(d, "oracle planner + scripted experts", "object_relocation"),
                *_shortfall(d, "oracle planner + learned skills*", "object_relocation", quartiles=True),
                *_shortfall(d, "oracle planner + learned skills", "object_relocation"),
                _shortfall(d, "oracle planner + scripted experts", "state_transition")[0],
                *_shortfall(d, "oracle planner + learned skills*", "state_transition"),
                *_shortfall(d, "oracle planner + learned skills", "state_transition")]),
    ("docs/learners.md", "succeeds in 0 of 27 handovers from the learned Navigate and 0 of 37 from Navigate*", _PAPER,
     lambda d: [_kn(d["rows"][r]["object_relocation"]["skills"]["Pick"]).replace("/", " of ")
                for r in ("oracle planner + learned skills", "oracle planner + learned skills*")]),
    ("docs/speed.md", "H200: start-pose floor 3.68 ms, path floor 5.86 ms wall / 4.62 ms CPU; step 9.90 ms = **101 steps/s = 1.69× the "
     "path floor wall, 2.00× CPU** (goal ≤ 1.3×: not met), 2.69× the start-pose floor; with `ECHO_DATA_LISTENER=0` 11.09 ms "
     "(1.83× / 2.10×): the listening thread saves 11 % there; async vector env of 2: 1.47× one process", _GPU, _gpu_env),
    ("docs/speed.md", "H200: one process 106.9 steps/s; N = 4: 233 steps/s in all (0.55 of N × one), N = 8: 297 (0.35), **N = 14: 312 "
     "(0.21**, stragglers' bound 0.45; 286 without prefetch). The bare floor in N processes scales no better: 385.6 steps/s in one, "
     "567 / 559 / 506 in all at N = 4 / 8 / 14 (0.37 / 0.18 / **0.09** of linear): separate processes' render contexts contend for "
     "one GPU, so at N = 14 the envs reach 0.62 of what the floor itself reaches in 14 processes", _GPU, _gpu_vec),
    ("docs/speed.md", "On an H200 (4e7981a): flat 128² 4.7 ms, textured 128² 5.1 ms (1.08×), 224² 8.3 ms (1.78×), 256² 9.6 ms (2.05×)", _GPU,
     lambda d: [_nums(d["env"]["bench_render"]["lines"][0])[0],
                *(x for ln in d["env"]["bench_render"]["lines"][3:6] for x in _nums(ln)[:2])]),
    ("docs/speed.md", "128,625 steps in 150.9 s with 14 workers = 852 steps/s", "studies/learners/results/sanity_builds_gpu.json",
     lambda d: [f"{sum(b['steps'] for b in d['builds'].values()):,}", f"{sum(b['seconds'] for b in d['builds'].values()):.1f}",
                f"{sum(b['steps'] for b in d['builds'].values()) / sum(b['seconds'] for b in d['builds'].values()):.0f}"]),
    *(("docs/vector_envs.md", q, "benchmarks/results/gpu_figures.json", lambda d, n=n: _vec(d, n))
      for n, q in ((1, "| 1 | 89.8 | 0.84 | 1.00 | 400.6 | 1.04 |"), (4, "| 4 | 233.1 | 0.55 | 0.67 | 567.4 | 0.37 |"),
                   (8, "| 8 | 297.2 | 0.35 | 0.54 | 558.9 | 0.18 |"), (14, "| 14 | 312.3 (285.5 with `ECHO_DATA_PREFETCH=0`) | 0.21 | 0.45 | 505.8 | **0.09** |"))),
    ("docs/vector_envs.md", "the envs at N = 14 reach 0.62 of what the floor reaches in 14 processes", _GPU, lambda d: _gpu_vec(d)[-1:]),
    ("docs/vector_envs.md", "The idle-time prefetch still pays at N = 14 (+9 %)", _GPU,
     lambda d: [_pct(float(_vec(d, 14)[0]) / float(_nums(next(ln for ln in d["env"]["bench_vec_prefetch_off"]["lines"] if "N = 14" in ln))[0]) - 1)]),
    ("docs/vector_envs.md", "H200 at 4e7981a: 4: 233, 8: 297, 14: 312 steps/s", _GPU, lambda d: [f"{float(_vec(d, n)[0]):.0f}" for n in (4, 8, 14)]),
    ("docs/vector_envs.md", "the bare floor alone reaches 0.09 of linear at N = 14 (H200, below)", _GPU, lambda d: [_vec(d, 14)[4]]),
    ("docs/vector_envs.md", "GPU machine too: 5.86 against 3.68 ms a step", _GPU, lambda d: [_nums(d["env"]["bench_env"]["lines"][i])[0] for i in (1, 0)]),
    ("docs/vector_envs.md", "above it (on the GPU machine too: 1.69x", _GPU, lambda d: [_nums(d["env"]["bench_env"]["lines"][3])[1]]),
    ("docs/vector_envs.md", "the bare floor in 14 processes reaches 0.09 of linear there", _GPU, lambda d: [_vec(d, 14)[4]]),
    ("docs/vector_envs.md", "9.90 ms a step = 1.69x its path floor (5.86 ms), 11.09 ms with the audio in the caller's thread",
     "benchmarks/results/gpu_figures.json",
     lambda d: [*_nums(d["env"]["bench_env"]["lines"][3])[:2], _nums(d["env"]["bench_env"]["lines"][1])[0],
                _nums(d["env"]["bench_env_listener_off"]["lines"][2])[0]]),
    # the study READMEs' prose and hand-written tables (their rendered tables are checked above)
    ("studies/navigation_ablation/README.md", "| stored | 1 round (20 rollouts, 8,127 rows; learner reached 10/20) | 36/54 = 0.67 [0.53, 0.78] "
     "| 40/68 | 0.51 | 0.154 |", _ABL, _dagger_stored),
    ("studies/navigation_ablation/README.md", "| level + ILD | 2 rounds (40 rollouts, 18,105 rows; learner reached 6/20, 6/20) | 21/54 = "
     "0.39 [0.27, 0.52] | 22/59 | 0.33 | 0.179 |", f"{_ABL}/ablation_dagger.json", _dagger_row),
    ("studies/navigation_ablation/README.md", "| level + ILD | 1 round (20 rollouts, 8,563 rows; learner reached 10/20) | 39/54 = "
     "0.72 [0.59, 0.82] | 47/68 | 0.58 | 0.140 |", f"{_ABL}/ablation_dagger_ild_ads.json", _dagger_row),
    ("studies/navigation_ablation/README.md", "alone 91/100, **100/100** and 88/100; after a hand-over 38/100, 32/100 and 40/100",
     _ABLATIONS, lambda d: [_pooled(d, level, c) for c in ("skills", "skills_handover") for level in ("none", "shipped", "twice")]),
    ("studies/learners/README.md", "| 91/100 [0.84, 0.95] / **100/100 [0.96, 1.00]** / 88/100 [0.80, 0.93] | 38/100 [0.29, 0.48] / "
     "32/100 [0.24, 0.42] / 40/100 [0.31, 0.50] |", _ABLATIONS, lambda d: [*_pooled_cells(d, "skills"), *_pooled_cells(d, "skills_handover")]),
    ("studies/learners/README.md", "100 of 100 over its two trainings, against 91/100 without perturbation and 88/100 at twice the level",
     _ABLATIONS, lambda d: [_pooled(d, "shipped", "skills").replace("/", " of "), *(_pooled(d, lv, "skills") for lv in ("none", "twice"))]),
    *(("studies/learners/README.md", f"| {label} | {cells}", _ABLATIONS, lambda d, run=run, n=n: _ablation(d, run, n)) for label, cells, run, n in (
        ('CloseSink, chunking off (ACT chunk 1)', '2/9 / 3/9 | 50/50 | 13/50', 'act_chunk1', 9),
        ('CloseSink, no wrist depth', '1/9 / 0/9 | 9/50 = 0.18 [0.10, 0.31] | 3/50', 'act_no_wrist_depth', 9),
        ('CloseSink, diffusion (U-Net, horizon 16, 8 executed)', '0/9 / 1/9 | 6/50 = 0.12 [0.06, 0.24] | 5/50', 'diffusion_closesink', 9),
        ('Pick, diffusion', '0/10 / 0/10 | 0/50 | 0/50', 'diffusion_pick', 10),
        ('OpenDoor, diffusion (ACT: 0/50 and 0/50)', '0/10 / 0/10 | 0/50 | 0/50', 'diffusion_opendoor', 10),
        ('none, seed 0 | 300 of 300 attempts', '3/9 / **6/9** | 46/50 = 0.92 [0.81, 0.97] | 20/50', 'perturbation_none', 9),
        ('none, seed 1 | (the same build)', '3/9 / 5/9 | 45/50 = 0.90 [0.79, 0.96] | 18/50', 'perturbation_none_seed1', 9),
        ('1 cm / 2° (twice), seed 0 | 300 of 385 (85 failed, redrawn)', '4/9 / 5/9 | 50/50 | 31/50', 'perturbation_twice', 9),
        ('1 cm / 2° (twice), seed 1 | (the same build)', '2/9 / 1/9 | 38/50 = 0.76 [0.63, 0.86] | 9/50', 'perturbation_twice_seed1', 9),
    )),
    ("studies/learners/README.md", "its best single run (6/9, no perturbation, seed 0) is not the best on test alone, and twice-seed-1's 2/9 "
     "says nothing of its 38/50", _ABLATIONS, lambda d: [f"{round(d['runs'][r]['details']['CloseSink']['training']['action.ee-act']['best_val_success'] * 9)}/9"
                                                        for r in ("perturbation_none", "perturbation_twice_seed1")] + [_kn(d["runs"]["perturbation_twice_seed1"]["skills"]["CloseSink"])]),
    ("studies/learners/README.md", "at batch 256 for 5.5 minutes", _GPU, lambda d: [f"{d['long_training']['training']['train_seconds'] / 60:.1f}"]),
    ("studies/learners/README.md", "Nine episodes separate nothing (6/9 and 3/9: Wilson [0.35, 0.88] and [0.12, 0.65])", "studies", _nine),
]


@pytest.mark.parametrize("page, quote, results, figures", FIGURES, ids=[f"{p.removesuffix('/README.md').split('/')[-1]}:{q[:40]}" for p, q, *_ in FIGURES])
def test_a_figure_quoted_in_the_docs_is_its_results_json(page: str, quote: str, results: str, figures: Any) -> None:
    text = " ".join((ROOT / page).read_text().split())  # a quote may wrap across lines
    assert quote in text, f"{page}: the quote is gone; update FIGURES with the page"
    rest = quote
    source = ROOT / results
    for figure in figures(str(source.relative_to(ROOT)) if source.is_dir() else json.loads(source.read_text())):
        assert figure in rest, f"{page}: {quote!r} does not show {figure} ({results})"
        rest = rest[rest.index(figure) + len(figure):]


# --- every figure of a study README's prose: held by its results, checked above, or declared -----------------
# A study README's tables between results markers are rendered (above); its prose and hand-written tables
# quote. Each k/n and decimal there must be a figure held by the results the README draws on (its study's
# results/ and every results file it names), one FIGURES checks on that page, or stand in a sentence (a table
# row, with its header) that declares it: "not kept" (a measurement whose files were not committed, such as a
# validation score read from a run folder) or "the paper's" (the paper's own number, no measurement of ours).
# A goal ("the 0.90 goal", "goal ≥ 0.60") is no measurement. The pool is every figure of those files, not the
# quoted cell: this catches a figure nothing there holds, not one copied from the wrong cell; FIGURES does that.
_FIGURE = re.compile(r"(?<![\w.])(\d+/\d+|\d+\.\d+)(?![\w.])")
_DECLARED = re.compile(r"not kept|the paper's")
_GOAL = re.compile(r"goals? (?:of |at )?(?:[≥≤] ?)?\d+\.\d+(?: / \d+\.\d+)*|\d+\.\d+ goal")
_RESULTS = re.compile(r"(?:studies/\w+/|benchmarks/)results/[\w.*/-]*\w")


def _held(obj: Any, out: set[str]) -> set[str]:
    """The figures a results file holds as a page may print them: a number at 0–3 decimals, the k/n (and its
    share) of a {successes|k|correct, n|attempts|episodes} cell or of a [k, n] pair, every figure in a string."""
    if isinstance(obj, dict):
        for v in obj.values():
            _held(v, out)
        for k in (obj.get(a) for a in ("successes", "k", "correct")):
            for n in (obj.get(a) for a in ("n", "attempts", "episodes")):
                if type(k) is int and type(n) is int and n:
                    out |= {f"{k}/{n}", f"{k / n:.2f}"}
    elif isinstance(obj, list):
        for v in obj:
            _held(v, out)
        if len(obj) == 2 and all(type(x) is int for x in obj):
            out.add(f"{obj[0]}/{obj[1]}")
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        x = Decimal(str(abs(obj)))  # a page prints the sign apart ("−0.43") and may round a stored 0.425 half up
        out |= {f"{x:.{d}f}" for d in range(4)} | {str(x.quantize(Decimal(10) ** -d, ROUND_HALF_UP)) for d in range(1, 4)} | {str(abs(obj))}
    elif isinstance(obj, str):
        out |= set(re.findall(r"\d+(?:\.\d+)?(?:/\d+)?", obj))
    return out


def _results_pool(study: Path, text: str) -> set[str]:
    """The figures of the study's results/ and of every results file its README names."""
    paths = {*(study / "results").glob("**/*"), *(p for name in _RESULTS.findall(text) for p in ROOT.glob(name))}
    pool: set[str] = set()
    for path in paths:
        if path.suffix == ".json":
            _held(json.loads(path.read_text()), pool)
        elif path.suffix == ".csv":
            _held(path.read_text(), pool)
    return pool | {f.lstrip("0") for f in pool if f.startswith("0.")}  # ".5" as some pages write it


def _prose_units(text: str) -> list[str]:
    """A README's prose outside rendered tables and code blocks: each table row (with its header), and each sentence."""
    text = re.sub(r"<!-- (results|paper table|headline).*?<!-- end of[^>]*-->", "", text, flags=re.S)
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    units: list[str] = []
    for block in re.split(r"\n\s*\n|\n(?=\s*- )", text):
        rows = [ln for ln in block.splitlines() if ln.lstrip().startswith("|")]
        rest = " ".join(ln for ln in block.splitlines() if not ln.lstrip().startswith("|")).split()
        units += [f"{rows[0]} {row}" for row in rows]  # a row with its table's header, which may declare a column
        units += re.split(r"(?<=[.!?])\s+(?=[A-Z*(`])", " ".join(rest))
    return units


@pytest.mark.parametrize("study", STUDIES, ids=[d.name for d in STUDIES])
def test_every_figure_of_a_study_readme_is_held_checked_or_declared(study: Path) -> None:
    page = f"studies/{study.name}/README.md"
    text = (ROOT / page).read_text()
    checked = {f for p, _, results, figures in FIGURES if p == page
               for f in figures(results if (ROOT / results).is_dir() else json.loads((ROOT / results).read_text()))}
    known = _results_pool(study, text) | checked
    loose = [(f, unit[:120]) for unit in _prose_units(text) if not _DECLARED.search(unit)
             for f in _FIGURE.findall(_GOAL.sub("", unit)) if f not in known]
    assert not loose, f"{page}: figures its results do not hold (check them in FIGURES, name the results, or say not kept): {loose}"
