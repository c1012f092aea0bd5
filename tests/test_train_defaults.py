"""`echo-data train`'s per-skill defaults (echo_data/learn/defaults.py): what a user who names only
the skill trains with, recorded in config.json; explicit options and `--config FILE` win; a default
input the dataset does not store is left out (an explicit one is refused); and the paper table's
learners, whose options are spelled from the same table, still pass the arguments their committed
runs were trained with."""

from __future__ import annotations

import json
import shlex
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from support.cli import one_line_exit_2
from support.synth import build_synth
from support.torch_module import torch  # noqa: F401  (skips where the test extra leaves torch out)
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.learn import runs
from echo_data.learn.defaults import MANIPULATION, NAVIGATE, resolve
from echo_data.recipe import OutputsConfig

ROOT = Path(__file__).resolve().parents[1]
SMALL = ["--chunk", "2", "--d-model", "16", "--heads", "2", "--layers", "1", "--max-steps", "1", "--no-progress"]


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 3, "test": 1})


@pytest.fixture(scope="module")
def no_wrist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset whose recipe stores the head depth and the audio but no wrist depth."""
    outputs = OutputsConfig(episodes_per_shard=2, observations=("head_depth", "spectrogram"))
    return build_synth(tmp_path_factory.mktemp("nowrist") / "synth", {"train": 3, "test": 1}, outputs=outputs)


def _train(ds: Path, out: Path, *args: str) -> tuple[dict[str, Any], str]:
    """`train act DATASET ARGS` with a tiny network and one optimiser step: (config.json, stderr)."""
    r = CliRunner().invoke(app, ["train", "act", str(ds), *args, *SMALL, "--out", str(out)])
    assert r.exit_code == 0, r.output
    return runs.read_json(out / runs.CONFIG), r.stderr


def test_a_skill_alone_trains_with_the_studies_options_and_config_json_records_them(ds: Path, tmp_path: Path) -> None:
    cfg, err = _train(ds, tmp_path / "pick", "--skill", "Pick")
    assert tuple(cfg["inputs"]) == MANIPULATION.inputs == ("depth", "wrist_depth", "state", "kind")
    assert (cfg["shift"], cfg["epochs"], cfg["select_every"], cfg["select_episodes"]) == (4, 20, 10, 10)
    assert cfg["action_column"] == "action"  # the synthetic recipe's env acts in the joint form
    assert not err


def test_explicit_options_and_the_config_file_win_over_the_skills_defaults(ds: Path, tmp_path: Path) -> None:
    conf = tmp_path / "c.yaml"
    conf.write_text("epochs: 3\nselect-every: 0\n")
    cfg, _ = _train(ds, tmp_path / "run", "--skill", "Pick", "--config", str(conf), "--shift", "2", "--inputs", "depth,state")
    assert (cfg["epochs"], cfg["select_every"], cfg["shift"], tuple(cfg["inputs"])) == (3, 0, 2, ("depth", "state"))
    assert cfg["select_episodes"] == 10  # still the skill's


def test_navigate_hears_without_a_camera_and_no_image_means_no_shift(ds: Path) -> None:
    nav, notes = resolve("Navigate", {}, ds)
    assert nav["inputs"] == NAVIGATE.inputs == ("audio", "state", "kind") and nav["shift"] == 0 and not notes
    assert (nav["epochs"], nav["select_every"], nav["select_episodes"]) == (20, 5, 10)
    assert resolve("Pick", {"inputs": "state,kind"}, ds)[0]["shift"] == 0
    assert resolve("Stretch", {}, ds) == ({}, [])  # not a skill of the table: the config's defaults, and its refusal


def test_an_action_column_the_recipe_cannot_act_in_is_chosen_on_validation_loss(ds: Path) -> None:
    """The env of the dataset's recipe takes one form: a closed-loop choice in the other could not run."""
    got, notes = resolve("Pick", {"action_column": "action.ee"}, ds)
    assert got["select_every"] == 0 and "action_column" not in got
    assert len(notes) == 1 and "--action-column action.ee" in notes[0] and str(ds) in notes[0]
    assert resolve("Pick", {"action_column": "action"}, ds)[0]["select_every"] == 10


def test_a_default_input_the_dataset_lacks_is_left_out_and_an_explicit_one_refused(no_wrist: Path, tmp_path: Path) -> None:
    cfg, err = _train(no_wrist, tmp_path / "pick", "--skill", "Pick")
    assert tuple(cfg["inputs"]) == ("depth", "state", "kind") and cfg["shift"] == 4
    (note,) = err.splitlines()
    assert note.startswith("note: ") and str(no_wrist) in note and "wrist_depth" in note
    one_line_exit_2(["train", "act", str(no_wrist), "--skill", "Pick", "--inputs", "wrist_depth,state", *SMALL, "--out", str(tmp_path / "r")],
                    str(no_wrist), "wrist_depth")
    assert not (tmp_path / "r").exists()


def test_a_resumed_run_keeps_the_options_it_started_with(ds: Path, tmp_path: Path) -> None:
    """A run trained before the per-skill defaults (or with other options) continues as it began."""
    out = tmp_path / "old"
    first, _ = _train(ds, out, "--skill", "Pick", "--inputs", "depth,state", "--epochs", "2", "--select-every", "0")
    again, _ = _train(ds, out, "--skill", "Pick", "--resume")
    assert {k: again[k] for k in ("inputs", "epochs", "select_every", "shift")} == {k: first[k] for k in ("inputs", "epochs", "select_every", "shift")}


def test_help_says_the_defaults_are_per_skill() -> None:
    r = CliRunner().invoke(app, ["train", "act", "--help"], terminal_width=200)
    text = " ".join(r.output.split())
    assert r.exit_code == 0 and "default per skill" in text and "Unset options default per skill" in text
    assert "--inputs depth,wrist_depth,state,kind --shift 4" in text and "Navigate --inputs audio,state,kind" in text


def _options(tokens: list[str]) -> dict[str, str]:
    """`--name value` pairs (a flag alone: "") of a train command's options."""
    out: dict[str, str] = {}
    for i, t in enumerate(tokens):
        if t.startswith("--"):
            out[t] = tokens[i + 1] if i + 1 < len(tokens) and not tokens[i + 1].startswith("--") else ""
    return out


def test_the_paper_tables_learners_pass_what_their_committed_runs_were_trained_with() -> None:
    """rows.py spells MANIPULATION and NAVIGATE from the defaults' table: every learner's committed training
    command (studies/paper_table/results/paper_table.json) holds exactly the options rows.py passes."""
    sys.path.insert(0, str(ROOT / "studies" / "paper_table"))
    try:
        from rows import LEARNERS
    finally:
        sys.path.remove(str(ROOT / "studies" / "paper_table"))
    trained = json.loads((ROOT / "studies" / "paper_table" / "results" / "paper_table.json").read_text())["training"]
    checked = 0
    for name, spec in LEARNERS.items():
        if name not in trained:
            continue
        tokens = shlex.split(trained[name]["command"])
        assert tokens[1:3] == ["train", spec.algo] and tokens[tokens.index("--skill") + 1] == spec.skill, name
        held = {k: v for k, v in _options(tokens).items() if k not in ("--out", "--no-progress", "--skill") and (k, v) != ("--threads", "1")}
        assert held == _options(["--inputs", spec.inputs, *spec.options]), name
        checked += 1
    assert checked >= 10
