"""studies/learner_probes/first_steps.py: the expert's side is the dataset's own first actions of each segment,
the learner's side comes from the run's chosen checkpoint."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from support.torch_module import torch  # noqa: F401  skips where the test extra leaves torch out
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.records import EE_ACTION_NAMES

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "studies" / "learner_probes"))

from first_steps import first_steps  # noqa: E402


def test_first_steps_pairs_the_experts_first_actions_with_the_learners(synth_dataset: Callable[[dict[str, int]], Path], tmp_path: Path) -> None:
    ds = synth_dataset({"train": 3, "test": 1})
    run = tmp_path / "act"
    res = CliRunner().invoke(app, ["train", "act", str(ds), "--skill", "Navigate", "--inputs", "state", "--action-column", "action.ee",
                                   "--max-steps", "2", "--chunk", "4", "--d-model", "32", "--heads", "2", "--layers", "1",
                                   "--out", str(run), "--no-progress"])
    assert res.exit_code == 0, res.output
    doc = first_steps(run, ds, (0, 1), 2)
    assert doc["skill"] == "Navigate" and doc["segments"] == 2
    t = pq.read_table(sorted((ds / "data").glob("train-*.parquet"))[0], columns=["skill", "action.ee"]).to_pydict()
    first = [a for s, a in zip(t["skill"], t["action.ee"], strict=True) if s == "Navigate"][0]
    assert doc["steps"]["0"]["expert_v"][0] == round(first[EE_ACTION_NAMES.index("base_vx")], 3)
    assert doc["steps"]["0"]["expert_w"][0] == round(first[EE_ACTION_NAMES.index("base_wz")], 3)
    assert len(doc["steps"]["1"]["learner_v"]) == 2 and all(np.isfinite(doc["steps"]["1"]["learner_w"]))
