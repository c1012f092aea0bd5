"""The paper table: the machinery (echo_data.evaluation.table), the paper's catalogue
(studies/paper_table/rows.py) and its driver
(studies/paper_table/paper_table.py): a learned-planner row composed from the planner's run with the
experts and the oracle-planner run with the learned skills, a skill-alone row read from a chain
row, the one definition of "plan right without the receptacle" (the table's and the planner's),
the summary block, the rendering (the committed markdown and the README's copy are the
module's rendering of the committed JSON), and the driver end to end on a real quickstart build.
"""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from support.optional import needs_torch
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.lock import BuildLock
from echo_data.evaluation import table
from echo_data.evaluation.metrics import plan_right_without_receptacle, proportion, wilson
from echo_data.learn.planner import Episodes, score

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "studies" / "paper_table" / "results" / "paper_table.json"
RECIPES = ROOT / "studies" / "paper_table" / "recipes"
_spec = importlib.util.spec_from_file_location("paper_table_rows", ROOT / "studies" / "paper_table" / "rows.py")
assert _spec is not None and _spec.loader is not None
paper = importlib.util.module_from_spec(_spec)  # the paper's catalogue, beside its driver
_spec.loader.exec_module(paper)
CHAIN = [{"skill": "Navigate", "target": "phone"}, {"skill": "Pick", "target": "phone"}]
PLACE = [*CHAIN, {"skill": "Place", "target": "furniture:1"}]


def _record(i: int, plan_right: bool, done: int) -> dict[str, Any]:
    """An episode record as `echo-data evaluate` writes it: `done` skills of the 2-skill chain succeeded."""
    skills = [{"skill": c["skill"], "target": c["target"], "success": k < done, "reason": "" if k < done else "timeout", "steps": 5}
              for k, c in enumerate(CHAIN[: done + 1 if done < 2 else 2])] if plan_right else []
    return {"index": i, "episode_id": f"test-{i}", "setting": "object_relocation", "seed": i, "true_chain": CHAIN,
            "planned_chain": CHAIN if plan_right else CHAIN[:1], "plan_correct": plan_right, "skills": skills,
            "skills_completed": done if plan_right else 0, "success": plan_right and done == 2, "steps": 10 * done + 1,
            "navigate": [{"skill_index": 0, "success": done >= 1, "path_length": 1.0, "expert_length": 1.0, "spl": float(done >= 1)}] if plan_right else [],
            "failure": "" if plan_right and done == 2 else "plan wrong" if not plan_right else "Pick(phone): timeout"}


def test_a_learned_planner_row_keeps_the_skills_outcome_only_where_the_plan_is_right() -> None:
    plans = {"episodes": [_record(0, True, 2), _record(1, False, 0), _record(2, True, 2), _record(3, False, 0)]}
    skills = {"episodes": [_record(0, True, 2), _record(1, True, 2), _record(2, True, 1), _record(3, True, 0)]}
    row = table.composed(plans, skills)
    m = row["metrics"]
    assert set(row) == {"metrics", "skills"} and set(row["skills"]) == set(table.SKILLS)
    assert (m["task_planning"]["k"], m["task_planning"]["n"]) == (2, 4)
    assert (m["skill_completion"]["k"], m["skill_completion"]["n"]) == (1, 4)  # episode 1 succeeded with the true plan, not with this one
    assert [p["k"] for p in m["progressive"]] == [2, 1]
    assert row["skills"]["Navigate"] == table.skill_success([_record(0, True, 2), _record(2, True, 1)], "Navigate")
    assert m["planning_without_place_target"] == proportion(2, 4)  # the wrong plans stay wrong without the receptacle
    assert m["navigate_success"] == proportion(2, 2) and m["episodes"] == 4


def test_a_composed_row_refuses_different_episodes() -> None:
    other = dict(_record(1, True, 2), episode_id="test-99")
    with pytest.raises(SystemExit, match="same episodes"):
        table.composed({"episodes": [_record(0, True, 2), _record(1, True, 2)]}, {"episodes": [_record(0, True, 2), other]})


def test_a_derived_skill_alone_row_counts_the_skills_attempts() -> None:
    row = table.derived({"episodes": [_record(0, True, 2), _record(1, True, 0), _record(2, True, 1)]}, "Navigate")
    assert row == {"skills": {"Navigate": proportion(2, 3)}}


def test_the_handover_is_the_experts_path_minus_the_driven_one_over_successful_first_navigates() -> None:
    eps = [_record(i, True, 2) for i in range(3)] + [_record(3, True, 0)]  # the last Navigate failed: not counted
    for e, driven in zip(eps, (0.5, 0.8, 1.0, 0.1), strict=True):
        e["navigate"][0]["path_length"] = driven
    h = table.handover(eps)
    assert h is not None and h["n"] == 3 and h["quartiles_m"][1] == 0.2  # 1.0 - 0.8
    assert "goal_distance_m" not in h  # evaluations from before the hand-over pose was recorded
    for e, (d, turn, arm) in zip(eps, ((0.1, 0.0, 0.0), (0.3, math.pi / 18, 0.2), (0.5, math.pi / 9, 0.4), (2.0, 1.0, 1.0)), strict=True):
        e["navigate"][0].update(goal_distance=d, heading_error=turn, arm_moved=arm)
    h = table.handover(eps)
    assert h is not None and h["goal_distance_m"][1] == 0.3 and h["heading_error_deg"][1] == 10.0 and h["arm_moved_rad"][1] == 0.2


# --- one definition of "plan right without the receptacle" ------------------------------------

ELSEWHERE = [*CHAIN, {"skill": "Place", "target": "furniture:4"}]  # another receptacle
NO_PLACE = CHAIN  # the Place step missing
TWICE = [*PLACE, {"skill": "Place", "target": "furniture:1"}]  # a Place too many
CASES = [(PLACE, True), (ELSEWHERE, True), (NO_PLACE, False), (TWICE, False), ([CHAIN[1], CHAIN[0], PLACE[2]], False)]


@pytest.mark.parametrize(("planned", "right"), CASES)
def test_only_the_place_receptacle_is_forgiven(planned: list[dict[str, str]], right: bool) -> None:
    assert plan_right_without_receptacle(planned, PLACE) is right
    assert plan_right_without_receptacle(None, PLACE) is False


def test_the_table_and_the_planner_count_plans_right_without_the_receptacle_alike() -> None:
    """The planner's own score (`chain_without_place_target`) and the table's column
    (`planning_without_place_target`) on the same plans: a missing or extra Place step is wrong in
    both (the planner once dropped Place steps before comparing, which forgave them)."""
    templates = {"phone": [["Navigate", "phone"], ["Pick", "phone"], ["Place", "furniture:4"]], "bell": [["Navigate", "phone"], ["Pick", "phone"]],
                 "twice": [["Navigate", "phone"], ["Pick", "phone"], ["Place", "furniture:1"], ["Place", "furniture:1"]]}
    predicted = [["phone"], ["bell"], ["twice"], []]
    chains = [PLACE] * len(predicted)
    ep = Episodes(inputs={}, index=np.arange(len(predicted)), frame=np.zeros(len(predicted), dtype=int), events=[["phone"]] * len(predicted),
                  chains=chains, sounds=[["s"]] * len(predicted))
    planner = score(predicted, ep, templates)["all"]["chain_without_place_target"]
    planned = [[{"skill": s, "target": t} for cat in p for s, t in templates[cat]] for p in predicted]
    episodes = [{"planned_chain": p, "true_chain": c} for p, c in zip(planned, chains, strict=True)]
    tabled = table.planning_without_place_target(episodes)
    assert (planner["correct"], planner["n"]) == (tabled["k"], tabled["n"]) == (1, 4)  # only the other receptacle is right


# --- summary and rendering ----------------------------------------------------------------------

def _entry(k: int, n: int, planned: int | None = None) -> dict[str, Any]:
    return {"command": "echo-data evaluate ...", "commit": "c", "metrics": {"episodes": n, "task_planning": proportion(n if planned is None else planned, n),
            "skill_completion": proportion(k, n), "progressive": [proportion(k, n)], "planning_without_place_target": proportion(n, n)},
            "skills": {s: proportion(k, n) for s in table.SKILLS}}


def test_the_summary_names_rows_and_settings_and_leaves_the_unmeasured_empty() -> None:
    doc = {"rows": {"oracle planner + learned skills": {"multi_event": _entry(3, 50)}, "Pick alone": {"object_relocation": _entry(8, 50)},
                    "Navigate alone": {"object_relocation": {"skills": {"Navigate": proportion(30, 50)}},
                                       "state_transition": {"skills": {"Navigate": proportion(40, 49)}}}},
           "previous_session": {"rows": {"Place alone": {"object_relocation": _entry(1, 50)}, "Pick alone": {"object_relocation": _entry(9, 50)}}}}
    s = paper.summary(doc)
    lo, hi = wilson(3, 50)
    assert s["completion"]["oracle planner + learned skills"]["multi_event"] == {"successes": 3, "n": 50, "low": round(lo, 4), "high": round(hi, 4)}
    assert s["completion"]["oracle planner + learned skills"]["object_relocation"] is None  # in the spec, not measured
    assert s["completion"]["oracle planner + learned skills* (paper-comparable)"] == dict.fromkeys(paper.SETTINGS)
    assert s["skills_alone"]["Navigate"]["successes"] == 70 and s["skills_alone"]["Navigate"]["n"] == 99  # over both settings
    assert s["skills_alone"]["Pick"]["successes"] == 8 and "previous_session" not in s["skills_alone"]["Pick"]  # this session's wins
    assert s["skills_alone"]["Place"]["previous_session"] is True and s["skills_alone"]["Place"]["successes"] == 1
    assert s["skills_alone"]["Pick (paper-comparable)"] is None and s["skills_alone"]["OpenDoor"] is None
    assert set(s["skills_alone"]) == {r.label for r in paper.ROWS.values() if r.skill_alone}


def test_an_unmeasured_row_renders_as_not_measured_and_a_measured_one_with_its_counts() -> None:
    md = paper.markdown({"rows": {"oracle planner + learned skills": {s: _entry(2, 50, planned=49) for s in paper.SETTINGS}}})
    line = next(x for x in md.splitlines() if x.startswith("| oracle planner + learned skills* (paper-comparable) |"))
    assert line.count(table.NOT_MEASURED) == 6
    ours = next(x for x in md.splitlines() if x.startswith("| oracle planner + learned skills |"))
    assert ours.count("0.98 [0.90, 1.00] (49/50)") == 3 and ours.count("0.04 [0.01, 0.13] (2/50)") == 3  # Wilson: [0.011, 0.135]
    assert "| Pick | pick place | not measured |" in md and "| Pick (paper-comparable) | pick place | not measured |" in md
    assert "| Pick after a hand-over | pick place handover | not measured |" in md
    assert "49/50 = 0.98 [0.90, 1.00] | 50/50 = 1.00 [0.93, 1.00] |" in md  # exact and receptacle-free planning where they differ


def test_the_committed_json_markdown_and_readme_are_one_rendering() -> None:
    doc = json.loads(RESULTS.read_text())
    assert set(doc["rows"]) <= set(paper.ROWS), "a row in the JSON the catalogue does not know would vanish from the table"
    assert doc["summary"] == paper.summary(doc)
    md = paper.markdown(doc)
    assert RESULTS.with_suffix(".md").read_text() == md
    for path, begin, end, rendered in paper.copies(ROOT):  # the study's README (all of it) and the repository's (the headline)
        assert paper.rendered_copy(path.read_text(), begin, end) == rendered(doc), f"{path.name}'s table: python studies/paper_table/paper_table.py --render"
    headline = paper.headline(doc)
    assert "| row | state transition: planning |" in headline and "| skill alone | settings | success |" in headline
    commands = [e.get("command", "") for per in doc["rows"].values() for e in per.values()]
    commands += [t.get("command", "") for t in doc["training"].values()] + [d["command"] for d in doc["datasets"].values()]
    assert all(c and " /" not in c and "=/" not in c for c in commands), "a command names a path of the machine it ran on"


def test_every_row_names_known_learners_rows_and_settings() -> None:
    for row in paper.ROWS.values():
        if isinstance(row, table.EvaluatedRow):
            assert set(row.policy.values()) <= set(paper.LEARNERS) and set(row.policy) <= set(table.SKILLS), row.name
            several = {len(paper.LEARNERS[x].trained_seeds) for x in row.policy.values()} - {1}
            assert len(several) <= 1, f"{row.name}: its learners' seed lists must be one length (evaluation.seeds)"
            if row.grasp == "physical":
                assert all((RECIPES / paper.recipe(row, s)).is_file() for s in row.settings), row.name
        elif isinstance(row, table.ComposedRow):
            assert {row.plans, row.outcomes} <= set(paper.ROWS) and row.grasp == paper.ROWS[row.outcomes].grasp == paper.ROWS[row.plans].grasp
        else:
            assert row.source in paper.ROWS
    assert all(spec.dataset in paper.DATASETS for spec in paper.LEARNERS.values())
    # as committed: one training, seed 0, but the learners over three seeds (the Oracle* row's: theirs
    # the options of the one-seed learner named, seed 0 being its command exactly)
    three = {"CloseSink-3seeds": None, "Navigate-target-3seeds": "Navigate-target", "OpenDoor-magic-3seeds": "OpenDoor-magic"}
    assert all(s.trained_seeds == (0,) for name, s in paper.LEARNERS.items() if name not in three)
    for name, single in three.items():
        spec = paper.LEARNERS[name]
        assert spec.trained_seeds == (0, 1, 2), name
        if single is not None:
            one = paper.LEARNERS[single]
            assert (spec.dataset, spec.skill, spec.inputs, spec.algo, spec.options_for(0)) == (one.dataset, one.skill, one.inputs, one.algo, one.options_for(0))
    sink = paper.LEARNERS["CloseSink-3seeds"]
    # the command its three runs are trained with (option order aside; the table's device choice)
    lead = ["--action-column", "action.ee", "--epochs", "20", "--select-every", "10", "--shift", "4", "--select-episodes", "10", "--seed", "2",
            "--select-recipe", "studies/paper_table/recipes/cameras_test_sink.yaml"]
    opts = sink.options_for(2)
    assert (sink.algo, sink.dataset, sink.skill, sink.inputs) == ("act", "cameras_door_sink", "CloseSink", "depth,wrist_depth,state,kind")
    assert dict(zip(opts[::2], opts[1::2], strict=True)) == {**dict(zip(lead[::2], lead[1::2], strict=True)), "--device": "auto"}


def test_the_results_lock_waits_for_its_holder(tmp_path: Path) -> None:
    order: list[str] = []

    def second() -> None:
        with BuildLock(tmp_path, name=".t.lock", wait=True):
            order.append("second holds it")

    with BuildLock(tmp_path, name=".t.lock", wait=True):
        t = threading.Thread(target=second)
        t.start()
        time.sleep(0.3)
        order.append("first lets go")
    t.join(timeout=30)
    assert order == ["first lets go", "second holds it"]


# --- the driver, end to end --------------------------------------------------------------------

@pytest.fixture(scope="module")
def quickstart(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real quickstart build of one train episode (object relocation: Navigate, Pick, Place),
    acting in the end-effector form the table's learners clone (`action.ee`)."""
    tmp = tmp_path_factory.mktemp("table")
    out, recipe = tmp / "qs", tmp / "quickstart_ee.yaml"
    recipe.write_text(f"extends: {ROOT / 'recipes' / 'quickstart.yaml'}\nname: quickstart_ee\nrobot: {{action_space: ee_delta}}\n")
    res = CliRunner().invoke(app, ["build", str(recipe), "--out", str(out), "--split", "train", "--limit", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


@needs_torch
def test_paper_table_tiny_evaluates_a_learner_in_evaluate_and_resumes(quickstart: Path, tmp_path: Path) -> None:
    runs_dir, out = tmp_path / "runs", tmp_path / "table.json"
    cmd = [sys.executable, str(ROOT / "studies" / "paper_table" / "paper_table.py"), "--tiny", "--data", str(quickstart), "--runs", str(runs_dir), "--out", str(out),
           "--rows", "Pick alone", "--workers", "1"]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads(out.read_text())
    assert set(doc["training"]) == {"Pick"}  # only the learners the chosen rows drive
    row = doc["rows"]["Pick alone"]["quickstart"]
    assert row["command"].startswith("echo-data evaluate") and "Pick=" in row["command"] and len(doc["commit"]) >= 40
    assert row["metrics"]["episodes"] == 1 and row["skills"]["Pick"]["n"] <= 1
    pick = doc["summary"]["skills_alone"]["Pick"]
    assert (pick["successes"], pick["n"]) == (row["skills"]["Pick"]["k"], row["skills"]["Pick"]["n"])
    evals = sorted(runs_dir.glob("eval-*.json"))
    stamp = [p.stat().st_mtime_ns for p in evals]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)  # everything is in the JSON: nothing is run again
    assert r.returncode == 0, r.stderr[-3000:]
    assert [p.stat().st_mtime_ns for p in evals] == stamp and json.loads(out.read_text())["rows"] == doc["rows"]
    md = out.with_suffix(".md").read_text()
    # measured with the run's own weights, not the shipped reference learners': the table marks it stale itself
    assert "| Pick § |" in md and "§ stale: measured with weights that are not the shipped reference learners'" in md
    r = subprocess.run([*cmd[:2], "--rows", "no such row", "--out", str(out)], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and "no such row" in r.stderr


def _study_eval(runs_dir: Path, recipe: str, **change: Any) -> dict[str, Any]:
    """An `echo-data evaluate --json` document as a study writes it: Pick learned (weights RUNS/Pick), one test episode."""
    from echo_data.agents.loading import folder_sha256
    from echo_data.evaluation.metrics import summarise
    from echo_data.recipe import load_recipe

    eps = [_record(0, True, 2)]
    doc = {"recipe": {"path": f"recipes/{recipe}", "name": recipe[:-5], "content_hash": load_recipe(RECIPES / recipe).content_hash()},
           "split": "test", "n": 1, "planner": {"name": "oracle"}, "wall_seconds": 12.5, "episodes": eps, "metrics": {"all": summarise(eps)},
           "policy": {"name": "Pick=elsewhere,oracle", "skills": {"*": {"name": "oracle"}, "Pick": {"checkpoint_sha256": folder_sha256(runs_dir / "Pick")}}}}
    doc.update(change)
    return doc


def test_an_evaluation_is_adopted_only_with_the_same_recipe_split_size_and_weights(tmp_path: Path) -> None:
    runs_dir, out = tmp_path / "runs", tmp_path / "table.json"
    (runs_dir / "Pick").mkdir(parents=True)
    (runs_dir / "Pick" / "best.pt").write_bytes(b"weights")
    cmd = [sys.executable, str(ROOT / "studies" / "paper_table" / "paper_table.py"), "--runs", str(runs_dir), "--out", str(out), "-n", "1", "--workers", "1", "--adopt"]
    ev = tmp_path / "study.json"

    def adopt(doc: dict[str, Any]) -> subprocess.CompletedProcess[str]:
        ev.write_text(json.dumps(doc))
        return subprocess.run([*cmd, str(ev)], cwd=ROOT, capture_output=True, text=True)

    r = adopt(_study_eval(runs_dir, "cameras_test_pick_place_handover.yaml"))
    assert r.returncode == 0, r.stderr[-2000:]
    entry = json.loads(out.read_text())["rows"]["Pick after a hand-over"]["pick_place_handover"]
    assert entry["skills"]["Pick"]["k"] == 1 and "adopted" in entry and entry["wall_seconds"] == 12.5
    assert entry["command"].startswith("echo-data evaluate studies/paper_table/recipes/cameras_test_pick_place_handover.yaml --split test -n 1 --policy=Pick=")
    assert (runs_dir / "eval-Pick_after_a_hand-over-pick_place_handover.json").is_file()
    refused = [_study_eval(runs_dir, "cameras_test_pick_place.yaml", n=50),  # another size
               {**_study_eval(runs_dir, "cameras_test_pick_place.yaml"), "recipe": {"path": "studies/paper_table/recipes/cameras_test_pick_place.yaml", "content_hash": "0" * 64}},
               _study_eval(runs_dir, "cameras_test_door.yaml")]  # no row evaluates Pick there
    for doc in refused:
        r = adopt(doc)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--adopt" in r.stderr, r.stderr
    (runs_dir / "Pick" / "best.pt").write_bytes(b"other weights")
    r = adopt(_study_eval(runs_dir, "cameras_test_pick_place.yaml", policy={"skills": {"Pick": {"checkpoint_sha256": "f" * 64}}}))
    assert r.returncode == 2 and "not the evaluated weights" in r.stderr
    assert "Pick alone" not in json.loads(out.read_text())["rows"]  # nothing refused was written


# --- a row over several training seeds ---------------------------------------------------------

@needs_torch
def test_paper_table_tiny_trains_two_seeds_and_measures_a_row_over_both(quickstart: Path, tmp_path: Path) -> None:
    """The catalogue's Pick learner given two training seeds (the rest of the catalogue as
    committed): each seed trained into its own run, the row evaluated with both (`+`, an episode
    each under --tiny), the entry holding the seeds, each seed's weights and figures, the table
    showing the range; a reference set that ships another weights file for one seed makes the row stale."""
    from echo_data.evaluation.provenance import stale_rows
    from echo_data.learn import runs
    from echo_data.learn.reference import ReferenceSet

    runs_dir, out = tmp_path / "runs", tmp_path / "table.json"
    argv = ["paper_table.py", "--tiny", "--data", str(quickstart), "--runs", str(runs_dir), "--out", str(out), "--rows", "Pick alone", "--workers", "1"]
    script = ("import dataclasses, runpy, sys; sys.path.insert(0, 'studies/paper_table'); import rows; "
              "rows.LEARNERS['Pick'] = dataclasses.replace(rows.LEARNERS['Pick'], seeds=(0, 1)); "
              f"sys.argv = {argv!r}; runpy.run_path('studies/paper_table/paper_table.py', run_name='__main__')")
    r = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads(out.read_text())
    assert set(doc["training"]) == {"Pick", "Pick-s1"}  # seed 0 keeps the learner's folder
    assert "--seed 0 " in doc["training"]["Pick"]["command"] and "--seed 1 " in doc["training"]["Pick-s1"]["command"]
    entry = doc["rows"]["Pick alone"]["quickstart"]
    assert f"--policy=Pick={runs_dir / 'Pick'}+{runs_dir / 'Pick-s1'}" in entry["command"]
    assert entry["seeds"] == {"Pick": [0, 1]} and entry["metrics"]["episodes"] == 2  # an episode per seed
    shas = [runs.file_sha256(runs_dir / run / runs.BEST) for run in ("Pick", "Pick-s1")]
    assert shas[0] != shas[1] and entry["weights"]["skills"]["Pick"] == shas  # each seed's weights, in seed order
    each = [m["skills"].get("Pick", {"k": 0, "n": 0}) for m in entry["per_seed"]]
    assert len(each) == 2 and sum(p["k"] for p in each) == entry["skills"]["Pick"]["k"] and sum(p["n"] for p in each) == entry["skills"]["Pick"]["n"]
    cell = doc["summary"]["skills_alone"]["Pick"]
    assert set(cell) == {"successes", "n", "low", "high", "per_seed"} and [(x["successes"], x["n"]) for x in cell["per_seed"]] == [(p["k"], p["n"]) for p in each]
    line = next(x for x in out.with_suffix(".md").read_text().splitlines() if x.startswith("| Pick "))
    assert line.endswith(f"; {table.seed_range([(p['k'], p['n']) for p in each])} |") and "2 seeds " in line
    ships = {"seed0": {"skill": "Pick", "weights_sha256": shas[0]}, "seed1": {"skill": "Pick", "weights_sha256": shas[1]}}
    assert stale_rows(doc["rows"], ReferenceSet(tmp_path, ships)) == set()
    swapped = {**ships, "seed1": {"skill": "Pick", "weights_sha256": "0" * 64}}  # seed 1 retrained: its weights are not the measured ones
    assert stale_rows(doc["rows"], ReferenceSet(tmp_path, swapped)) == {"Pick alone"}


def test_the_per_seed_range_renders_lowest_to_highest() -> None:
    assert table.seed_range([(16, 17), (12, 17), (13, 16)]) == "3 seeds 12/17–16/17"
    assert table.seed_range([(5, 10), (5, 10)]) == "2 seeds 5/10 each" and table.seed_range(None) == ""
    entry = {**_entry(41, 50), "per_seed": [{"skill_completion": proportion(k, n), "skills": {"CloseSink": proportion(k, n)}} for k, n in ((12, 17), (16, 17), (13, 16))]}
    md = paper.markdown({"rows": {"CloseSink alone (3 seeds)": {"sink": entry}, "oracle planner + learned skills": {"multi_event": entry}}})
    assert "| CloseSink (3 seeds) | sink | 41/50 = 0.82 [0.69, 0.90]; 3 seeds 12/17–16/17 |" in md
    assert "0.82 [0.69, 0.90] (41/50; 3 seeds 12/17–16/17)" in md and "K seeds a/b–c/d" in md
    s = paper.summary({"rows": {"CloseSink alone (3 seeds)": {"sink": entry}}})["skills_alone"]["CloseSink (3 seeds)"]
    assert (s["successes"], s["n"]) == (41, 50) and [x["successes"] for x in s["per_seed"]] == [12, 16, 13]


def _sink_eval(runs_dir: Path, folders: list[str]) -> dict[str, Any]:
    """An `echo-data evaluate --json` document of CloseSink alone on cameras_test_sink.yaml, one
    test episode per member, member j acted by RUNS/folders[j] (evaluation.seeds)."""
    from echo_data.agents.loading import folder_sha256
    from echo_data.evaluation.metrics import summarise
    from echo_data.evaluation.seeds import per_seed
    from echo_data.recipe import load_recipe

    chain = [{"skill": "CloseSink", "target": "sink"}]
    eps = [{**_record(j, True, 1), "true_chain": chain, "planned_chain": chain, "navigate": [], "member": j, "success": j != 1,
            "skills": [{"skill": "CloseSink", "target": "sink", "success": j != 1, "reason": "", "steps": 5}]} for j in range(len(folders))]
    members = [{"skills": {"*": {"name": "oracle"}, "CloseSink": {"checkpoint_sha256": folder_sha256(runs_dir / f)}}} for f in folders]
    return {"recipe": {"path": "studies/paper_table/recipes/cameras_test_sink.yaml", "content_hash": load_recipe(RECIPES / "cameras_test_sink.yaml").content_hash()},
            "split": "test", "n": len(folders), "planner": {"name": "oracle"}, "wall_seconds": 3.0, "episodes": eps, "metrics": {"all": summarise(eps)},
            "policy": {"name": "CloseSink=" + "+".join(folders) + ",oracle", "members": members}, "seeds": per_seed(eps, len(folders))}


def test_an_evaluation_over_three_seeds_is_adopted_only_with_each_seeds_weights(tmp_path: Path) -> None:
    runs_dir, out = tmp_path / "runs", tmp_path / "table.json"
    folders = [table.run_name("CloseSink-3seeds", s) for s in paper.LEARNERS["CloseSink-3seeds"].trained_seeds]
    assert folders == ["CloseSink-3seeds", "CloseSink-3seeds-s1", "CloseSink-3seeds-s2"]
    for i, f in enumerate(folders):
        (runs_dir / f).mkdir(parents=True)
        (runs_dir / f / "best.pt").write_bytes(b"seed %d" % i)
    cmd = [sys.executable, str(ROOT / "studies" / "paper_table" / "paper_table.py"), "--runs", str(runs_dir), "--out", str(out), "-n", "3", "--workers", "1", "--adopt"]
    ev = tmp_path / "study.json"

    def adopt(doc: dict[str, Any]) -> subprocess.CompletedProcess[str]:
        ev.write_text(json.dumps(doc))
        return subprocess.run([*cmd, str(ev)], cwd=ROOT, capture_output=True, text=True)

    for wrong in ([folders[0], folders[2], folders[1]], folders[:1]):  # two seeds swapped; one seed's run alone
        r = adopt(_sink_eval(runs_dir, wrong))
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--adopt" in r.stderr, r.stderr
    assert not out.exists()
    r = adopt(_sink_eval(runs_dir, folders))
    assert r.returncode == 0, r.stderr[-2000:]
    doc = json.loads(out.read_text())
    entry = doc["rows"]["CloseSink alone (3 seeds)"]["sink"]
    assert entry["seeds"] == {"CloseSink": [0, 1, 2]} and "+" in entry["adopted"]
    assert "--policy=CloseSink=" + "+".join(str(runs_dir / f) for f in folders) in entry["command"]
    assert [m["skills"]["CloseSink"]["k"] for m in entry["per_seed"]] == [1, 0, 1] and entry["skills"]["CloseSink"]["k"] == 2
    assert [x["successes"] for x in doc["summary"]["skills_alone"]["CloseSink (3 seeds)"]["per_seed"]] == [1, 0, 1]


def test_a_chain_evaluation_without_the_learners_its_setting_never_calls_is_adopted(tmp_path: Path) -> None:
    """The Oracle* row names a learner for every skill, a state-transition episode calls Navigate,
    OpenDoor and CloseSink only: an evaluation with those three (CloseSink over its three seeds,
    the one-seed learners repeated in every member) is the row's entry, its command naming only
    them; an episode that calls a skill the evaluation has no learner for is refused."""
    from echo_data.agents.loading import folder_sha256
    from echo_data.evaluation.metrics import summarise
    from echo_data.evaluation.seeds import per_seed
    from echo_data.recipe import load_recipe

    runs_dir, out = tmp_path / "runs", tmp_path / "table.json"
    sinks = [table.run_name("CloseSink-3seeds", s) for s in paper.LEARNERS["CloseSink-3seeds"].trained_seeds]
    for i, f in enumerate([*sinks, "Navigate-target", "OpenDoor-magic"]):
        (runs_dir / f).mkdir(parents=True)
        (runs_dir / f / "best.pt").write_bytes(b"run %d" % i)
    recipe = "cameras_test_state_transition_magic.yaml"

    def doc(last: str) -> dict[str, Any]:
        eps = []
        for j in range(3):
            chain = [{"skill": "Navigate", "target": "x"}, {"skill": last if j == 2 else ("OpenDoor", "CloseSink")[j], "target": "x"}]
            eps.append({**_record(j, True, 2), "true_chain": chain, "planned_chain": chain, "navigate": [], "member": j, "success": True,
                        "skills": [{**c, "success": True, "reason": "", "steps": 5} for c in chain]})
        members = [{"skills": {"*": {"name": "oracle"}, "Navigate": {"checkpoint_sha256": folder_sha256(runs_dir / "Navigate-target")},
                               "OpenDoor": {"checkpoint_sha256": folder_sha256(runs_dir / "OpenDoor-magic")},
                               "CloseSink": {"checkpoint_sha256": folder_sha256(runs_dir / f)}}} for f in sinks]
        return {"recipe": {"path": f"studies/paper_table/recipes/{recipe}", "content_hash": load_recipe(RECIPES / recipe).content_hash()},
                "split": "test", "n": 3, "planner": {"name": "oracle"}, "wall_seconds": 3.0, "episodes": eps, "metrics": {"all": summarise(eps)},
                "policy": {"name": "several", "members": members}, "seeds": per_seed(eps, 3)}

    ev = tmp_path / "chain.json"
    cmd = [sys.executable, str(ROOT / "studies" / "paper_table" / "paper_table.py"), "--runs", str(runs_dir), "--out", str(out), "-n", "3", "--workers", "1", "--adopt", str(ev)]
    ev.write_text(json.dumps(doc("Pick")))  # an episode calls Pick, which the evaluation has no learner for
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    ev.write_text(json.dumps(doc("CloseSink")))
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    entry = json.loads(out.read_text())["rows"]["oracle planner + learned skills* (paper-comparable)"]["state_transition"]
    assert entry["seeds"] == {"CloseSink": [0, 1, 2]} and "Pick" not in entry["command"] and "Place" not in entry["command"]
    assert f"--policy=Navigate={runs_dir / 'Navigate-target'} " in entry["command"] + " "
