"""Training run folders: `--overwrite` deletes only what a run wrote (the marker's file list),
refuses in one line with every byte kept a folder without the marker, holding anything else, or
inside or around the training dataset; a full disk during training is one line, exit 2, and
leaves no half-written file (every file there reads back whole)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from support.cli import one_line_exit_2
from support.optional import needs_torch
from support.synth import build_synth, damageable_copy
from test_faults_disk import _limited, _one_line_exit_2
from test_faults_overwrite import _thesis, tree_digest
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.written import MARKER, all_files
from echo_data.learn import runs

pytestmark = needs_torch  # every test here trains (`echo-data train`)

TRAIN = {
    "bc": ["bc", "--skill", "Navigate", "--inputs", "state"],
    "planner": ["planner"],
}


@pytest.fixture(scope="module")
def ds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("train") / "synth", {"train": 2, "test": 1})


def _argv(algo: str, ds: Path, out: Path, *extra: str) -> list[str]:
    return ["train", TRAIN[algo][0], str(ds), *TRAIN[algo][1:], "--out", str(out), "--max-steps", "1", "--no-progress", *extra]


def _train(algo: str, ds: Path, out: Path, *extra: str) -> None:
    r = CliRunner().invoke(app, _argv(algo, ds, out, *extra))
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("algo", list(TRAIN))
def test_a_run_folder_lists_every_file_it_wrote(algo: str, ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    _train(algo, ds, run)
    marker = json.loads((run / MARKER).read_text())
    assert marker["kind"] == runs.RUN and marker["format"] == runs.RUN_FORMAT and marker["version"]
    assert set(marker["files"]) == set(all_files(run)) - {MARKER}
    assert {runs.CONFIG, runs.POLICY, runs.AGENT, runs.BEST, runs.CHECKPOINT} <= set(marker["files"])


@pytest.mark.parametrize("algo", list(TRAIN))
def test_overwrite_refuses_a_folder_without_the_marker(algo: str, ds: Path, tmp_path: Path) -> None:
    thesis = _thesis(tmp_path / "thesis")
    (thesis / runs.CONFIG).write_text('{"my": "experiment"}')  # names a run also writes
    (thesis / "select").mkdir()
    (thesis / "select" / "chosen.csv").write_text("a,b\n")
    before = tree_digest(thesis)
    one_line_exit_2(_argv(algo, ds, thesis, "--overwrite"), str(thesis), f"has no {MARKER} marker", "nothing was touched")
    assert tree_digest(thesis) == before


@pytest.mark.parametrize("foreign", ["notes.txt", "select/scored-001/mine.pt", "plots/loss.png"])
def test_overwrite_refuses_a_run_holding_anything_else(foreign: str, ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    _train("bc", ds, run)
    (run / foreign).parent.mkdir(parents=True, exist_ok=True)
    (run / foreign).write_text("mine")
    before = tree_digest(run)
    one_line_exit_2(_argv("bc", ds, run, "--overwrite"), f"holds {foreign}, which echo-data did not write")
    assert tree_digest(run) == before


def test_overwrite_replaces_its_own_run_and_one_from_before_the_marker(ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    _train("planner", ds, run)
    (run / f".{runs.BEST}.tmp-4242").write_bytes(b"a killed writer's leftover")
    _train("planner", ds, run, "--overwrite")
    assert not list(run.glob("*.tmp-*")) and (run / runs.EVAL).is_file()
    (run / MARKER).unlink()  # as run folders written before the marker existed
    (run / runs.DAGGER_LOG).write_text("round\n")
    _train("planner", ds, run, "--overwrite")
    assert not (run / runs.DAGGER_LOG).exists() and json.loads((run / MARKER).read_text())["kind"] == runs.RUN
    (run / MARKER).unlink()
    (run / "notes.txt").write_text("mine")  # an old run folder with a user's file: refused whole
    before = tree_digest(run)
    one_line_exit_2(_argv("planner", ds, run, "--overwrite"), "holds notes.txt, which echo-data did not write")
    assert tree_digest(run) == before


def test_overwrite_refuses_a_policy_json_of_another_tool(ds: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    other.mkdir()
    (other / runs.POLICY).write_text(json.dumps({"kind": "policy", "class": "their_lab.models:Net"}))
    (other / runs.BEST).write_bytes(b"their weights")
    before = tree_digest(other)
    one_line_exit_2(_argv("bc", ds, other, "--overwrite"), "marker", "nothing was touched")
    assert tree_digest(other) == before


@pytest.mark.parametrize("algo", list(TRAIN))
def test_out_inside_or_around_the_training_dataset_is_refused(algo: str, ds: Path, tmp_path: Path) -> None:
    parent = tmp_path / "work"
    data = damageable_copy(ds, parent)
    before = tree_digest(parent)
    one_line_exit_2(_argv(algo, data, parent, "--overwrite"), "contains the training dataset")
    one_line_exit_2(_argv(algo, data, data, "--overwrite"), "lies inside the training dataset")
    one_line_exit_2(_argv(algo, data, data / "runs" / "x"), "lies inside the training dataset")
    assert tree_digest(parent) == before


def test_resume_of_a_run_from_before_the_marker_adopts_its_files(ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    _train("bc", ds, run)
    (run / MARKER).unlink()
    (run / "notes.txt").write_text("mine")
    _train("bc", ds, run, "--resume")
    assert set(json.loads((run / MARKER).read_text())["files"]) == set(all_files(run)) - {MARKER, "notes.txt"}


def _whole(run: Path) -> None:
    """Every file in `run` reads back whole: JSON parses, checkpoints load; no temporary file."""
    for rel in all_files(run):
        assert ".tmp-" not in rel, rel
        if rel.endswith(".json"):
            json.loads((run / rel).read_text())
        elif rel.endswith(".pt"):
            runs.load_torch(run / rel)


@pytest.mark.parametrize("algo", list(TRAIN))
@pytest.mark.parametrize("limit", [100, 3000, 200_000])  # the marker, config.json, the checkpoint
def test_training_onto_a_full_disk_is_one_line_and_leaves_nothing_half_written(algo: str, limit: int, ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    res = _limited(limit, ["-m", "echo_data.cli", *_argv(algo, ds, run)])
    _one_line_exit_2(res, "--out", "File too large")
    if run.exists():
        _whole(run)
    # once there is room, --overwrite replaces what the failed run left
    ok = subprocess.run([sys.executable, "-m", "echo_data.cli", *_argv(algo, ds, run, "--overwrite")], capture_output=True, text=True, timeout=600)
    assert ok.returncode == 0, ok.stderr[-2000:]
    _whole(run)


@pytest.mark.parametrize("algo, extra, says", [
    ("bc", ["--seed", str(10**23)], f"--seed {10**23}: must be within [0, 2**64)"),
    ("planner", ["--seed", str(10**23)], f"--seed {10**23}: must be within [0, 2**64)"),
    ("bc", ["--inputs", "depth", "--shift", "100000"], "--shift 100000: must be below the image side"),
])
def test_numbers_past_their_range_are_one_line(algo: str, extra: list[str], says: str, ds: Path, tmp_path: Path) -> None:
    """The issue's literal cases (a 64-bit overflow traceback; a 100000-pixel pad that failed to allocate)."""
    run = tmp_path / "run"
    one_line_exit_2([*_argv(algo, ds, run), *extra], says)
    assert not run.exists()


def test_a_killed_run_resumes_and_overwrite_clears_what_it_left(ds: Path, tmp_path: Path) -> None:
    """SIGKILL mid-training (between or inside atomic writes): every file left reads back whole,
    `--resume` continues from the checkpoint, and `--overwrite` clears even a killed write's
    temporary sibling (its name is on the marker's list)."""
    import os
    import signal
    import time

    run = tmp_path / "run"
    argv = [sys.executable, "-m", "echo_data.cli", "train", "bc", str(ds), "--skill", "Navigate", "--inputs", "state", "--out", str(run), "--epochs", "100000", "--no-progress"]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while not (run / runs.CHECKPOINT).is_file() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.2)
        time.sleep(0.5)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    assert (run / runs.CHECKPOINT).is_file()
    (run / f".{runs.CHECKPOINT}.tmp-{proc.pid}").write_bytes(b"half a checkpoint")  # as a kill inside the write leaves
    left_whole = [rel for rel in all_files(run) if ".tmp-" not in rel]
    for rel in left_whole:
        if rel.endswith(".json"):
            json.loads((run / rel).read_text())
        elif rel.endswith(".pt"):
            runs.load_torch(run / rel)
    step = runs.load_torch(run / runs.CHECKPOINT)["state"]["step"]
    r = CliRunner().invoke(app, ["train", "bc", str(ds), "--skill", "Navigate", "--inputs", "state", "--out", str(run), "--epochs", "100000",
                                 "--max-steps", str(step + 1), "--resume", "--no-progress"])
    assert r.exit_code == 0, r.output
    assert runs.load_torch(run / runs.CHECKPOINT)["state"]["step"] == step + 1
    _train("bc", ds, run, "--overwrite")
    _whole(run)
