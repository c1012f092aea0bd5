"""Place's carry done by the drive learner: the split of a Place segment at its first row inside
Place's stance (`learn.carry`) and the learners' options (`--from-stance`, `--with-carries`).

On a real build of one object-relocation episode (Navigate, Pick, Place; audio only, no pictures
stored) and two-step trainings: they check the contract, not what the models learn."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from support.torch_module import torch  # noqa: F401  (skips the module where the test extra leaves torch out)
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.skill_table import STANCE

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


@pytest.fixture(scope="module")
def recipe(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Quickstart with tiny cameras and only the spectrogram stored (train episode 0 moves a furby to a table)."""
    path = tmp_path_factory.mktemp("carry_recipe") / "carry.yaml"
    path.write_text(f"extends: {ROOT / 'recipes' / 'quickstart.yaml'}\nname: carry\n"
                    "robot:\n  head_camera: {width: 16, height: 16}\n  wrist_camera: {width: 16, height: 16, rgb: false}\n"
                    "outputs:\n  observations: [spectrogram]\n  planner_export: false\n")
    return path


@pytest.fixture(scope="module")
def ds(recipe: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("carry") / "ds"
    res = runner.invoke(app, ["build", str(recipe), "--out", str(out), "--split", "train", "--limit", "1", "--workers", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


def _place_segment(ds: Path) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float], str]:
    """(the Place segment's split rows, their base poses, its receptacle's interaction pose, the target)."""
    from echo_data.dataset.reader import StepReader, dataset_recipe, episode_records
    from echo_data.dataset.schema import STATE
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.scene.nav import interaction_pose

    reader = StepReader(ds, "train")
    idx = reader.index
    rows = np.flatnonzero(idx.skill == "Place")
    ep = episode_records(ds)[0]
    k = int(idx.skill_index[rows[0]])
    target = ep["chain"][k]["target"]
    plan = generate_floorplan_from_seed(dataset_recipe(ds)[0], int(ep["scene_seed"]))
    return rows, reader.read([STATE], rows)[STATE][:, :3], interaction_pose(plan, target), target


def test_a_place_segment_splits_at_its_first_row_inside_places_stance(ds: Path) -> None:
    from echo_data.dataset.reader import StepReader
    from echo_data.learn.carry import CARRY, OUTSIDE, PLACING, carry_parts
    from echo_data.skills.navigate import GOAL_TOL, YAW_TOL

    rows, base, pose, _ = _place_segment(ds)
    # the regenerated interaction pose is where the Place expert's drive stopped (within its tolerances)
    assert math.hypot(*(base[-1, :2] - pose[:2])) <= GOAL_TOL and abs(math.remainder(base[-1, 2] - pose[2], 2 * math.pi)) <= YAW_TOL
    dist = np.hypot(base[:, 0] - pose[0], base[:, 1] - pose[1])
    heading = np.abs(np.remainder(base[:, 2] - pose[2] + np.pi, 2 * np.pi) - np.pi)
    first = int(np.argmax((dist <= STANCE.distance) & (heading <= STANCE.heading)))
    assert 0 < first < len(rows) - 1  # a carry and a placing
    part = carry_parts(StepReader(ds, "train"))
    assert (part[rows[:first]] == CARRY).all() and (part[rows[first:]] == PLACING).all()
    assert (np.delete(part, rows) == OUTSIDE).all()  # Navigate's and Pick's rows are no carry


def test_place_from_stance_trains_on_the_stance_rows_only(ds: Path, tmp_path: Path) -> None:
    from echo_data.dataset.reader import StepReader
    from echo_data.learn import runs
    from echo_data.learn.carry import PLACING, carry_parts

    rows, _, _, _ = _place_segment(ds)
    stance = int((carry_parts(StepReader(ds, "train"))[rows] == PLACING).sum())
    counts = {}
    for flag in ("--no-from-stance", "--from-stance"):
        out = tmp_path / flag
        res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Place", "--inputs", "state", flag, "--max-steps", "1", "--out", str(out), "--no-progress"])
        assert res.exit_code == 0, res.output
        counts[flag] = json.loads(res.output)["rows"]["train"]
        assert runs.read_json(out / runs.CONFIG)["from_stance"] is (flag == "--from-stance")
    assert counts["--from-stance"] == stance < counts["--no-from-stance"] == len(rows)


def test_the_options_belong_to_their_skills(ds: Path, tmp_path: Path) -> None:
    for skill, flag in (("Pick", "--from-stance"), ("Navigate", "--from-stance"), ("Place", "--with-carries")):
        res = runner.invoke(app, ["train", "bc", str(ds), "--skill", skill, "--inputs", "state", flag, "--out", str(tmp_path / skill), "--no-progress"])
        assert res.exit_code == 2 and flag in res.output, res.output
        assert not (tmp_path / skill).exists()


def test_a_drive_learner_with_carries_learns_them_as_drives_to_the_receptacle(ds: Path) -> None:
    from echo_data.dataset.reader import StepReader
    from echo_data.learn.carry import CARRY, carry_parts
    from echo_data.learn.data import chain_kinds, load_skill_rows
    from echo_data.learn.features import feature_spec

    reader = StepReader(ds, "train")
    idx = reader.index
    carry = np.flatnonzero(carry_parts(reader) == CARRY)
    nav = np.flatnonzero(idx.skill == "Navigate")
    receptacle = chain_kinds(ds, "train")[(int(idx.episode[carry[0]]), int(idx.skill_index[carry[0]]))]
    spec = feature_spec(ds, ("state", "kind"), kinds=("furby", receptacle))
    rows = load_skill_rows(ds, "train", "Navigate", spec, chunk=2, stop=True, with_carries=True)
    assert len(rows) == len(nav) + len(carry)
    at = np.isin(np.sort(np.concatenate([nav, carry])), carry)  # the carry's rows among the loaded ones (split order)
    assert len(np.unique(rows.segments[at])) == 1 and not np.isin(rows.segments[at], rows.segments[~at]).any()  # a segment of its own
    stop = rows.actions[..., -1]
    assert stop[at][-1, 0] == 1 and stop[at][:-1, 0].sum() == 0  # its STOP on its last row, never on a placing row
    assert rows.action_pad[at][-1, 1]  # its window ends with it
    kinds = rows.inputs["kind"][at].argmax(-1).numpy()
    assert (kinds == 1).all()  # the receptacle's kind
