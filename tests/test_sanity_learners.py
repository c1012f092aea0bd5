"""studies/learners/sanity_learners.py: the privileged sanity learner's whole path (camera-free build,
every candidate learner (ACT, a chunked MLP) on state + privileged columns with closed-loop checkpoint choice, evaluation on the test
split alone and after a hand-over) in its --tiny form, and its bad input (one line, exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from support.optional import needs_torch

from echo_data.evaluation.metrics import wilson

ROOT = Path(__file__).resolve().parents[1]
DRIVER = ROOT / "studies" / "learners" / "sanity_learners.py"
RECIPES = ROOT / "studies" / "paper_table" / "recipes"  # the table's recipe family: sanity*, cameras_*, nav_audio*


def _driver(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(DRIVER), *args], cwd=ROOT, capture_output=True, text=True, timeout=900)


@pytest.mark.slow
@needs_torch
def test_the_tiny_path_writes_both_blocks_with_wilson_intervals(tmp_path: Path) -> None:
    out = tmp_path / "sanity.json"
    r = _driver("--tiny", "--skills", "Pick", "--workers", "1", "--work", str(tmp_path / "work"), "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads(out.read_text())
    assert doc["commit"] and doc["machine"] and doc["command"].startswith("python studies/learners/sanity_learners.py")
    assert str(tmp_path) not in json.dumps(doc)  # no paths of this machine in the results
    for block in ("skills", "skills_handover"):
        e = doc[block]["Pick"]
        assert set(e) == {"successes", "n", "low", "high"}
        assert 1 <= e["n"] <= 2 and 0 <= e["successes"] <= e["n"]  # 2 test episodes, each with one Pick at most
        low, high = wilson(e["successes"], e["n"])
        assert (e["low"], e["high"]) == (round(low, 4), round(high, 4))
    t = doc["timings"]["Pick"]
    assert t["build_s"] > 0 and t["train_s"] > 0 and t["eval_s"] > 0
    d = doc["details"]["Pick"]
    assert d["action_column"] == "action.ee" and not any(i in d["inputs"] for i in ("depth", "wrist_depth", "rgb"))
    # every learner was trained, and the one tested is the best on validation (ties: the first listed)
    tried = d["training"]
    assert {e["learner"] for e in tried.values()} == {"act", "bc"} and d["learner"] in ("act", "bc")
    best = max(tried.values(), key=lambda e: -1.0 if e["best_val_success"] is None else e["best_val_success"])["best_val_success"]
    assert tried[f"action.ee-{d['learner']}"]["best_val_success"] == best
    # the camera-free build stored no image column
    info = json.loads((tmp_path / "work" / "data" / "sanity_pick_place" / "meta" / "info.json").read_text())
    assert not any("images" in k for k in json.dumps(info.get("features", {})).split('"'))


@pytest.mark.parametrize("args, says", [
    (("--skills", "Pick", "Jump"), "--skills: unknown Jump"),
    (("--inputs", "Pick=state,observation.privileged.nope"), "unknown column observation.privileged.nope"),
    (("--inputs", "Pick=state,depth"), "unknown column depth"),
    (("--learners", "act,gpt"), "--learners"),
    (("--action-columns", "action.joint"), "--action-columns"),
])
def test_bad_arguments_are_one_line_and_exit_2(tmp_path: Path, args: tuple[str, ...], says: str) -> None:
    out = tmp_path / "sanity.json"
    r = _driver(*args, "--work", str(tmp_path / "work"), "--out", str(out))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and says in r.stderr, r.stderr
    assert not out.exists()


def test_a_dataset_without_the_privileged_column_is_one_line_naming_file_and_column(tmp_path: Path) -> None:
    data = tmp_path / "work" / "data" / "sanity_pick_place"
    (data / "meta").mkdir(parents=True)
    (data / "manifest.json").write_text(json.dumps({"complete": True, "episodes": {"train": 1}}))
    (tmp_path / "work" / "data" / "sanity_pick_place.build.json").write_text(json.dumps({"command": "x", "seconds": 1.0}))
    (data / "meta" / "info.json").write_text(json.dumps({"privileged": ["observation.privileged.target_pose"]}))
    out = tmp_path / "sanity.json"
    r = _driver("--skills", "Pick", "--work", str(tmp_path / "work"), "--out", str(out))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "info.json" in r.stderr and "observation.privileged.tcp_to_target" in r.stderr
    assert not out.exists()


CAMERA_DRIVER = ROOT / "studies" / "learners" / "camera_learners.py"


def test_the_camera_learners_read_no_privileged_column(tmp_path: Path) -> None:
    out = tmp_path / "cameras.json"
    r = subprocess.run([sys.executable, str(CAMERA_DRIVER), "--inputs", "CloseSink=depth,observation.privileged.joint_angle",
                        "--work", str(tmp_path / "work"), "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "unknown column observation.privileged.joint_angle" in r.stderr and "no privileged column" in r.stderr
    assert not out.exists()


@pytest.mark.parametrize("name", ["cameras_door_sink", "cameras_pick_place", *(f"cameras_test_{g}{h}" for g in ("pick_place", "door", "sink")
                                                                               for h in ("", "_handover"))])
def test_a_camera_recipe_is_its_sanity_recipe_with_both_depth_cameras_on(name: str) -> None:
    """The camera learners see the privileged learners' episodes (same seed, counts, events, experts):
    only the cameras and the stored observations differ, so their rows compare the inputs alone."""
    from echo_data.recipe import load_recipe

    cams = load_recipe(RECIPES / f"{name}.yaml").model_dump(mode="json")
    sanity = load_recipe(RECIPES / f"{name.replace('cameras_', 'sanity_')}.yaml").model_dump(mode="json")
    for doc in (cams, sanity):
        del doc["name"]
    assert cams["robot"]["head_camera"]["depth"] and cams["robot"]["wrist_camera"]["depth"]
    assert not cams["robot"]["head_camera"]["rgb"] and not sanity["robot"]["head_camera"]["depth"]
    assert cams["outputs"]["observations"] == ["head_depth", "wrist_depth"]
    for doc in (cams, sanity):
        for cam in ("head_camera", "wrist_camera"):
            doc["robot"][cam].pop("depth")
        doc["outputs"].pop("observations")
    assert cams == sanity


def test_the_stop_navigate_data_is_nav_audio_ending_at_the_interaction_pose() -> None:
    """Navigate-stop's episodes are Navigate's (same seed, counts, sounds, experts): only where the
    expert's Navigate ends differs, so the STOP row compares the hand-over alone."""
    from echo_data.recipe import load_recipe

    stop = load_recipe(RECIPES / "nav_audio_stop.yaml").model_dump(mode="json")
    nav = load_recipe(RECIPES / "nav_audio.yaml").model_dump(mode="json")
    assert (stop["experts"]["handover_noise"], nav["experts"]["handover_noise"]) == (0.0, 1.0)
    for doc in (stop, nav):
        del doc["name"]
        del doc["experts"]["handover_noise"]
    assert stop == nav


def test_door_near_recipe_is_the_door_sink_recipe_with_doors_only_and_near_handovers() -> None:
    """The OpenDoor-near learner's data (studies/paper_table/recipes/cameras_door_near.yaml) differs from the table's
    OpenDoor data only in what the stance study changes: every state event a door, 160 training
    episodes (about the door segments of cameras_door_sink's 300) and hand-overs within 0.3 of the
    success region's radius; cameras, perturbation and experts are the same."""
    from echo_data.recipe import load_recipe

    near = load_recipe(RECIPES / "cameras_door_near.yaml").model_dump(mode="json")
    door_sink = load_recipe(RECIPES / "cameras_door_sink.yaml").model_dump(mode="json")
    assert (near["experts"]["handover_noise"], door_sink["experts"]["handover_noise"]) == (0.3, 1.0)
    assert near["events"]["categories"]["sink"] == 0.0 < door_sink["events"]["categories"]["sink"]
    assert near["composition"]["state_transition"]["train"] == 160
    for doc in (near, door_sink):
        for key in ("name", "composition", "splits"):
            del doc[key]
        del doc["experts"]["handover_noise"]
        del doc["events"]["categories"]
    assert near == door_sink


@pytest.mark.parametrize(("name", "level"), [("cameras_door_sink_p0", (0.0, 0.0)), ("cameras_door_sink_p2", (1.0, 2.0))])
def test_a_perturbation_recipe_is_the_door_sink_recipe_at_another_level(name: str, level: tuple[float, float]) -> None:
    """The perturbation-level ablation's data differs from the camera learners' OpenDoor/CloseSink
    data only in the experts' per-step end-effector perturbation (none, and twice the shipped
    0.5 cm / 1 degree), so its rows compare the level alone."""
    from echo_data.recipe import load_recipe

    other = load_recipe(RECIPES / f"{name}.yaml").model_dump(mode="json")
    shipped = load_recipe(RECIPES / "cameras_door_sink.yaml").model_dump(mode="json")
    assert (shipped["experts"]["perturbation"]["position_cm"], shipped["experts"]["perturbation"]["rotation_deg"]) == (0.5, 1.0)
    assert (other["experts"]["perturbation"]["position_cm"], other["experts"]["perturbation"]["rotation_deg"]) == level
    for doc in (other, shipped):
        del doc["name"]
        del doc["experts"]["perturbation"]
    assert other == shipped


def test_the_driver_names_an_unknown_training_recipe(tmp_path: Path) -> None:
    out = tmp_path / "cameras.json"
    r = subprocess.run([sys.executable, str(CAMERA_DRIVER), "--data", "CloseSink=cameras_door_sink_p9",
                        "--work", str(tmp_path / "work"), "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "--data CloseSink: no recipe studies/paper_table/recipes/cameras_door_sink_p9.yaml" in r.stderr
    assert not out.exists() and not (tmp_path / "work").exists()


def test_another_training_recipe_is_read_and_names_its_run(tmp_path: Path) -> None:
    """--data CloseSink=RECIPE trains on WORK/data/RECIPE and names the run folder after it (and
    after a seed other than 0), so a perturbation level or a second seed never reuses (or
    overwrites) another run. A stand-in dataset
    makes the training fail at once; the driver records the failure and says which command ran."""
    work = tmp_path / "work"
    data = work / "data" / "cameras_door_sink_p0"
    (data / "meta").mkdir(parents=True)
    (data / "manifest.json").write_text(json.dumps({"complete": True, "episodes": {"train": 1}}))
    (work / "data" / "cameras_door_sink_p0.build.json").write_text(json.dumps({"command": "x", "seconds": 1.0}))
    out = tmp_path / "cameras.json"
    r = subprocess.run([sys.executable, str(CAMERA_DRIVER), "--skills", "CloseSink", "--data", "CloseSink=cameras_door_sink_p0", "--seed", "1",
                        "--work", str(work), "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stderr[-2000:]
    doc = json.loads(out.read_text())
    assert set(doc["failed"]) == {"CloseSink"} and "cameras_door_sink_p0" in doc["datasets"]
    log = (work / "camera_learners.log").read_text()
    assert f"echo-data train act {data} --skill CloseSink" in log
    assert f"--seed 1 --out {work / 'runs' / 'CloseSink-action.ee-act-cameras_door_sink_p0-seed1'}" in log
    assert not (work / "data" / "cameras_door_sink").exists()  # the study's own recipe was never built
