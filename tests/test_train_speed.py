"""benchmarks/train_speed.py, the training-speed figure of issue 29 (CPU here, CPU and CUDA on a GPU
machine): it trains what it says for as many steps as it says, and cuts the whole-skill run to its
time budget by the rate it measured. Timings are never asserted."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from support.torch_module import torch  # noqa: F401  skips where the test extra leaves torch out

ROOT = Path(__file__).resolve().parent.parent


def _speed(ds: Path, *extra: str) -> dict:
    cmd = [sys.executable, str(ROOT / "benchmarks" / "train_speed.py"), str(ds), "--skill", "Navigate", "--inputs", "state",
           "--algo", "act", "--steps", "2", "--devices", "cpu", "--action-column", "action.ee", *extra]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    docs, dec, i = [], json.JSONDecoder(), 0
    while (j := res.stdout.find("{", i)) >= 0:
        doc, i = dec.raw_decode(res.stdout, j)
        docs.append(doc)
    return docs[-1]  # with --full-steps the short rows come first, then the whole document


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 3, "test": 1})


def test_train_speed_reports_the_steps_it_trained_and_the_options_it_was_given(ds: Path) -> None:
    doc = _speed(ds, "--full-steps", "9")
    assert doc["action_column"] == "action.ee" and doc["skill"] == "Navigate"
    [row] = doc["rows"]
    assert row["device"] == "cpu" and row["steps"] == 2 and row["samples_per_second"] > 0
    full = doc["full"]
    assert full["total_steps"] == 9 and not full["cut"] and full["asked_steps"] == 9


def test_the_whole_skill_run_is_cut_to_its_budget_and_says_so(ds: Path) -> None:
    full = _speed(ds, "--full-steps", "100000", "--full-budget", "0.5")["full"]
    assert full["cut"] and full["total_steps"] < 100000
