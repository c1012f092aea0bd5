"""Each study's README command reproduces its JSON: the driver's tiny path (a few episodes, a few
training steps) runs into a temporary folder and writes a JSON of the committed one's shape, which
the README's result table renders from. (The paper table's and the learner studies' tiny paths are
tests/test_table.py's and tests/test_sanity_learners.py's; studies without a results JSON say
why in their README.)"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
needs_torch = pytest.mark.skipif(importlib.util.find_spec("torch") is None, reason="the learners need torch")
needs_mplib = pytest.mark.skipif(importlib.util.find_spec("mplib") is None, reason="the carry search needs mplib")


def _run(driver: str, *args: str, timeout: int = 900) -> str:
    """`python studies/DRIVER ARGS` from the checkout, as the README runs it; its stdout."""
    r = subprocess.run([sys.executable, str(ROOT / "studies" / driver), *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stdout


def _committed(study: str, name: str) -> dict[str, Any]:
    return json.loads((ROOT / "studies" / study / "results" / name).read_text())


def _renderer(name: str) -> Any:
    """studies/results_tables.py's renderer `name` (the README table's)."""
    sys.path.insert(0, str(ROOT / "studies"))
    try:
        import results_tables
    finally:
        sys.path.remove(str(ROOT / "studies"))
    return getattr(results_tables, name)


def test_handover_drives_tiny_writes_the_table_the_readme_renders(tmp_path: Path) -> None:
    out = tmp_path / "drives.json"
    _run("handover/drives.py", "--episodes", "1", "--settings", "state_transition", "--out", str(out))
    doc, held = json.loads(out.read_text()), _committed("handover", "drives.json")
    assert set(doc) == set(held) and set(doc["starts"]) == set(held["starts"])
    assert doc["episodes_per_setting"] == 1 and doc["settings"] == ["state_transition"]
    for run in doc["starts"].values():  # one state-transition episode: one door or sink segment from each start
        assert len(run["segments"]) == 1 and set(run["skills"]) <= {"OpenDoor", "CloseSink"} and len(run["skills"]) == 1
    table = _renderer("drives")(doc)
    assert "| exact pose |" in table and "1 test episodes of each of state_transition" in table


def test_expert_noise_tiny_writes_the_runs_the_committed_json_holds(tmp_path: Path) -> None:
    out = tmp_path / "expert_noise.json"
    _run("experts/expert_noise.py", "--recipes", "recipes/state_transition.yaml", "--levels", "0", "-n", "1", "--workers", "1", "--out", str(out))
    doc, held = json.loads(out.read_text()), _committed("experts", "expert_noise.json")
    assert set(doc) <= set(held) and {"commit", "n", "command", "runs"} <= set(doc)
    (run,) = doc["runs"]
    assert set(run) == set(held["runs"][0]) and run["episodes"] == 1 and run["action_noise"] == 0.0
    assert 0 <= run["successes"] <= 1 and run["wilson95"][0] <= run["success_rate"] <= run["wilson95"][1]



def test_door_sink_experts_tiny_writes_the_figures_the_committed_json_holds(tmp_path: Path) -> None:
    out = tmp_path / "door_sink.json"
    _run("experts/door_sink_experts.py", "recipes/state_transition.yaml", "-n", "1", "--start", "handover", "--json", str(out))
    doc, held = json.loads(out.read_text()), _committed("experts", "door_sink_experts_handover.json")
    assert set(doc) == set(held) and doc["command"].endswith("recipes/state_transition.yaml -n 1 --start handover")
    (skill,) = doc["skills"]  # train episode 0 of state transition: one door or one sink
    figures = doc["skills"][skill]
    assert skill in held["skills"] and set(figures) == set(held["skills"][skill])
    assert figures["n"] + figures["skipped"] == 1 and figures["successes"] <= figures["n"] and 0 < figures["steps_max"] <= 300


def test_handover_starts_tiny_writes_the_runs_the_committed_json_holds(tmp_path: Path) -> None:
    out = tmp_path / "handover_starts.json"
    _run("experts/handover_starts.py", "--recipes", "recipes/state_transition.yaml", "--levels", "1.0", "-n", "1", "--out", str(out))
    doc, held = json.loads(out.read_text()), _committed("experts", "handover_starts.json")
    assert set(doc) == set(held)
    (run,) = doc["runs"]
    assert set(run) == set(held["runs"][0]) and run["n"] == 1 and run["handover_noise"] == 1.0 and run["successes"] <= 1
    if run["successes"]:  # where the drive stopped: within Navigate's 1.5 m region, facing within 15 degrees
        assert len(run["distance_m_quartiles"]) == 3 and max(run["distance_m_quartiles"]) <= 1.5
        assert max(run["heading_error_deg_quartiles"]) <= 15.0


def test_pick_handover_tiny_prints_the_counts_the_committed_json_holds() -> None:
    last = _run("experts/pick_handover.py", "recipes/object_relocation.yaml", "-n", "1").strip().splitlines()[-1]
    counts, held = json.loads(last), _committed("experts", "pick_place_experts.json")["handover"]
    assert set(counts) == set(held) - {"command"} and all(set(counts[s]) == set(held[s]) for s in counts)
    assert counts["Pick"]["n"] <= 1 and counts["Place"]["n"] <= counts["Pick"]["successes"]


def test_pick_place_figures_tiny_writes_the_figures_the_committed_json_holds(tmp_path: Path) -> None:
    """One object-relocation episode with both cameras (what a learner sees of the object)."""
    out = tmp_path / "figures.json"
    _run("experts/pick_place_figures.py", "recipes/object_relocation.yaml", "-n", "1", "--json", str(out))
    doc, held = json.loads(out.read_text()), _committed("experts", "pick_place_experts.json")["figures"]
    assert set(doc) == set(held) - {"command"} and doc["episodes"] == 1  # the committed one adds the command it ran
    rows = doc["pick_rows_per_segment"]
    assert set(rows) == set(held["pick_rows_per_segment"]) and rows["rows"] == rows["base"] + rows["untuck"] + rows["object"] > 0
    assert all(0.0 <= doc["visible_pick"][k] <= 1.0 for k in ("some_camera", "head", "wrist"))

@needs_mplib
def test_carry_search_tiny_reports_what_it_reached() -> None:
    """The carry search writes no JSON: its result is a constant of the code (README)."""
    text = _run("carry_search/carry_search.py", "-n", "20")
    assert "hand-down configurations reached from READY" in text and "clear the head view" in text


@needs_torch
@pytest.mark.slow
def test_navigation_ablation_tiny_writes_the_rows_the_readme_renders(tmp_path: Path) -> None:
    out = tmp_path / "ablation.json"
    _run("navigation_ablation/ablation.py", "--limit", "2", "--episodes", "1", "--rows", "state", "--no-planner", "--epochs", "1",
         "--workers", "1", "--data", str(tmp_path / "data"), "--runs", str(tmp_path / "runs"), "--out", str(out))
    doc, held = json.loads(out.read_text()), _committed("navigation_ablation", "ablation.json")
    assert set(held) - {"build_seconds"} <= set(doc) and doc["limit"] == 2
    (row,) = doc["navigate"]
    assert set(held["navigate"][0]) <= set(row) and row["inputs"] == "state" and row["episodes"] == 1
    assert row["first_navigate"]["n"] <= 1 and (tmp_path / "ablation-nav-state.json").is_file()
    assert "| state |" in _renderer("ablation")(doc)


@needs_torch
@pytest.mark.slow
def test_planner_tiny_writes_the_rows_the_readme_renders(tmp_path: Path) -> None:
    out = tmp_path / "planner.json"
    _run("planner/planner_table.py", "--limit", "2", "--rows", "audio|--epochs 1 --max-steps 2", "--workers", "1",
         "--data", str(tmp_path / "data"), "--runs", str(tmp_path / "runs"), "--out", str(out))
    doc, held = json.loads(out.read_text()), _committed("planner", "planner_fresh.json")
    assert set(held) <= set(doc) and doc["commands"][0].startswith("echo-data build") and "--limit 2" in doc["commands"][0]
    (row,) = doc["rows"]
    assert set(held["rows"][0]) <= set(row) and row["inputs"] == "audio" and row["flags"] == "--epochs 1 --max-steps 2"
    assert {"single_event", "multi_event", "all"} <= set(row["test"])
    assert "| audio | `--epochs 1 --max-steps 2` |" in _renderer("planner")(doc)


@needs_torch
@pytest.mark.slow
def test_user_check_tiny_runs_the_readme_commands_and_scores_the_run_it_trained(tmp_path: Path) -> None:
    """The user check on its recipe made small (2 train episodes at 32 px, flat look), 1 epoch of a small
    ACT with no closed-loop choice (`--tiny`), 1 test episode; run again, every step is reused."""
    from echo_data.learn import runs

    recipe = tmp_path / "tiny.yaml"
    recipe.write_text(f"extends: {ROOT / 'studies' / 'user_check' / 'recipes' / 'user_check.yaml'}\nname: user_check_tiny\n"
                      "splits: {train: 2, val: 1, test: 1}\nscene: {look: flat}\n"
                      "robot:\n  head_camera: {width: 32, height: 32}\n  wrist_camera: {width: 32, height: 32}\n")
    work, out = tmp_path / "work", tmp_path / "user_check.json"
    args = ("--recipe", str(recipe), "--tiny", "--episodes", "1", "--workers", "1", "--work", str(work), "--out", str(out))
    _run("user_check/user_check.py", *args)
    doc, held = json.loads(out.read_text()), _committed("user_check", "user_check.json")
    assert set(held) <= set(doc) and doc["seeds"] == {"recipe": 7331, "training": 0} and not doc["reused"]
    assert doc["commands"]["train"] == ("echo-data train act WORK/data --skill Pick --seed 0 --epochs 1 --select-every 0 --d-model 32 --heads 2 "
                                        "--layers 1 --image-size 0 --out WORK/runs/Pick")
    assert doc["commands"]["build"].endswith("--split train --workers 1 --out WORK/data") and "--policy Pick=WORK/runs/Pick" in doc["commands"]["evaluate"]
    assert doc["training"]["options"] == {"inputs": ["depth", "wrist_depth", "state", "kind"], "action_column": "action", "shift": 4,
                                          "epochs": 1, "select_every": 0, "select_episodes": 10}  # the skill's defaults but for --tiny's two
    result = doc["result"]
    assert result["n"] <= 1 and result["successes"] <= result["n"] and all(s > 0 for s in doc["seconds"].values())
    assert result["weights_sha256"] == doc["training"]["weights_sha256"] == runs.file_sha256(work / "runs" / "Pick" / "best.pt")
    assert "| Pick |" in _renderer("user_check")(doc)
    _run("user_check/user_check.py", *args)
    again = json.loads(out.read_text())
    assert again["reused"] == ["build", "train", "evaluate"] and again["result"] == result and again["seconds"] == doc["seconds"]
