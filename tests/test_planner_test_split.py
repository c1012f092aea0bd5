"""Never tuning on the test split: `echo-data train planner` chooses on validation and neither
reads nor needs the test split; `echo-data evaluate-planner RUN [DATASET]` scores it only when
asked, for the dataset the run was trained on, and bad input is one line, exit 2. (That its
figures are the kept checkpoint's on the test split: tests/test_learn.py, on a real build.)"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from support.cli import one_line_exit_2
from support.optional import needs_torch
from support.synth import build_synth, damageable_copy
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.written import MARKER, all_files
from echo_data.learn import runs

pytestmark = needs_torch  # every test here trains

TEST_KEYS = {"test", "test_errors", "test_events_in_order_by_decoder", "test_sounds_heard_in_training"}


@pytest.fixture(scope="module")
def builds(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The same train split twice (synthetic episodes are a function of split and index): built
    alone, and with a test split of 2 episodes, as when the test split is built after training."""
    root = tmp_path_factory.mktemp("planner_test_split")
    return build_synth(root / "train_only", {"train": 3}), build_synth(root / "with_test", {"train": 3, "test": 2})


def _train(ds: Path, run: Path) -> dict:
    r = CliRunner().invoke(app, ["train", "planner", str(ds), "--out", str(run), "--max-steps", "1", "--no-progress"])
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


def test_training_writes_no_test_figures_and_needs_no_test_split(builds: tuple[Path, Path], tmp_path: Path) -> None:
    train_only, with_test = builds
    run = tmp_path / "run"
    report = _train(train_only, run)
    assert report == json.loads((run / runs.EVAL).read_text())
    assert not TEST_KEYS & set(report) and set(report["episodes"]) == {"train", "val"} and "decode" in report
    assert not (run / runs.TEST).exists()
    # asked for, the test split is scored: the run's own dataset has none, the same one with it built has
    one_line_exit_2(["evaluate-planner", str(run)], "no 'test' split to score")
    assert not (run / runs.TEST).exists()
    r = CliRunner().invoke(app, ["evaluate-planner", str(run), str(with_test)])
    assert r.exit_code == 0, r.output
    scored = json.loads(r.stdout)
    assert scored == json.loads((run / runs.TEST).read_text())
    assert set(scored) >= TEST_KEYS and scored["episodes"] == {"test": 2} and scored["decode"] == report["decode"]
    assert scored["test"]["all"]["events_in_order"]["n"] == 2 and scored["test_errors"]["of"] == 2
    assert set(scored["test_events_in_order_by_decoder"]) == {"threshold", "sets"}
    assert runs.TEST in json.loads((run / MARKER).read_text())["files"]  # `train --overwrite` may replace it


def test_evaluate_planner_refuses_bad_input_in_one_line(builds: tuple[Path, Path], tmp_path: Path) -> None:
    _, with_test = builds
    run = tmp_path / "run"
    _train(with_test, run)
    one_line_exit_2(["evaluate-planner", str(tmp_path / "nothing")], "policy.json: missing")
    other = build_synth(tmp_path / "other", {"train": 4, "test": 1})  # another train split
    one_line_exit_2(["evaluate-planner", str(run), str(other)], str(other), "not the dataset", "differs")
    one_line_exit_2(["evaluate-planner", str(run), str(tmp_path)], "not an echo-data dataset")
    damaged = damageable_copy(with_test, tmp_path)
    shard = sorted((damaged / "data").glob("test-*.parquet"))[0]
    shard.write_bytes(shard.read_bytes()[:-100])
    one_line_exit_2(["evaluate-planner", str(run), str(damaged)], f"data/{shard.name}: sha256 differs")
    assert not (run / runs.TEST).exists()
    # a run folder from before the marker is adopted (its files listed) before test.json joins it
    (run / MARKER).unlink()
    r = CliRunner().invoke(app, ["evaluate-planner", str(run)])
    assert r.exit_code == 0, r.output
    assert set(json.loads((run / MARKER).read_text())["files"]) == set(all_files(run)) - {MARKER}
    (run / runs.EVAL).unlink()  # as a run killed before its end
    one_line_exit_2(["evaluate-planner", str(run)], "eval.json: missing", "has not finished")
