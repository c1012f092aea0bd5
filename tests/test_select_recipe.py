"""`--select-recipe`: the closed-loop checkpoint choice (`--select-every`) runs on the val split of
another recipe (the condition a run is measured in, e.g. after a hand-over), never on test; a
recipe that cannot serve is refused before anything is written (issue #45 point 5)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from support.torch_module import torch  # noqa: F401  (skips the module where the test extra leaves torch out)
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.episode import episode_seed
from echo_data.learn import runs
from echo_data.learn.select import SCORED, SELECT_DIR
from echo_data.recipe import load_recipe

runner = CliRunner()


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 3, "test": 1})


def _recipe(tmp_path: Path, body: str, name: str = "select.yaml") -> Path:
    path = tmp_path / name
    path.write_text(body)
    return path


def _train(ds: Path, out: Path, *extra: str) -> tuple[int, str]:
    args = ["train", "bc", str(ds), "--skill", "Navigate", "--inputs", "state", "--out", str(out), "--no-progress", "--threads", "1", *extra]
    res = runner.invoke(app, args)
    return res.exit_code, res.output


# A recipe of its own seed whose Navigate ends after a few steps (a fast episode); val episodes given.
HANDOVER = "name: sel_handover\nseed: 11\nsplits: {train: 1, val: 2, test: 1}\nexperts: {handover_noise: 1.0}\nrobot: {max_steps: {Navigate: 4, Pick: 250, Place: 250, OpenDoor: 300, CloseSink: 200}}\n"


@pytest.mark.parametrize(
    "body, extra, message",
    [
        (None, (), "select.yaml: file not found"),
        ("name: sel\nsplits: {train: 1, val: 1}\nbogus: 1\n", (), "select.yaml: bogus: unknown key"),
        # a test-only recipe: selection never runs on test, and no setting of its own can be given val episodes
        ("name: sel\nsplits: {test: 2}\n", (), "splits builds no train or val episode of a setting holding Navigate (only test)"),
        ("name: sel\ncomposition: {object_relocation: {test: 2}}\n", (), "composition builds no train or val episode of a setting holding Navigate (only test)"),
        ("name: sel\nsplits: {train: 1, val: 2}\nrobot: {action_space: ee_delta}\n", (), "acts in robot.action_space ee_delta, whose policies clone action.ee"),
        # the learner reads the head depth camera, which this recipe turns off
        ("name: sel\nsplits: {train: 1, val: 2}\nrobot: {head_camera: {rgb: false, depth: false}}\n", ("--inputs", "depth,state"),
         "its cameras cannot give observation.images.head_depth"),
    ],
)
def test_an_unusable_select_recipe_is_refused_before_anything_is_written(ds: Path, tmp_path: Path, body: str | None, extra: tuple[str, ...], message: str) -> None:
    path = tmp_path / "select.yaml" if body is None else _recipe(tmp_path, body)
    out = tmp_path / "run"
    code, output = _train(ds, out, "--select-every", "1", "--select-recipe", str(path), *extra)
    assert code == 2 and message in output and "--select-recipe" in output and len(output.strip().splitlines()) == 1, output
    assert not out.exists()


def test_a_select_recipe_without_val_episodes_gets_them_in_a_setting_of_its_own(ds: Path) -> None:
    """As for the dataset's recipe: val episodes added to a setting that builds the skill's
    episodes (train here), never taken from its test split."""
    from echo_data.learn.select import validation_recipe
    from echo_data.recipe import recipe_from_mapping

    given = recipe_from_mapping({"name": "sel", "composition": {"object_relocation": {"train": 1, "test": 2}, "state_transition": {"test": 2}}})
    got = validation_recipe(ds, "Navigate", 3, given, "sel.yaml")
    assert got.composition["object_relocation"] == {"train": 1, "test": 2, "val": 3} and got.composition["state_transition"] == {"test": 2, "val": 0}
    assert got.splits == {"train": 1, "test": 4, "val": 3}
    held = recipe_from_mapping({"name": "sel", "composition": {"object_relocation": {"train": 1, "val": 3, "test": 2}}})
    assert validation_recipe(ds, "Navigate", 3, held, "sel.yaml") is held


def test_select_recipe_needs_select_every(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    code, output = _train(ds, out, "--select-every", "0", "--select-recipe", str(_recipe(tmp_path, HANDOVER)))  # Navigate's default chooses every 5
    assert code == 2 and "--select-recipe: chooses the checkpoint closed loop; it needs --select-every" in output, output
    assert not out.exists()


def test_checkpoint_chosen_on_the_select_recipes_val_split_and_resume_keeps_it(ds: Path, tmp_path: Path) -> None:
    """The scored episodes are the select recipe's val episodes (its seed, split "val"); the run
    records the recipe's path and hash; resuming with another recipe (or with the file changed) is refused."""
    path = _recipe(tmp_path, HANDOVER)
    out = tmp_path / "run"
    code, output = _train(ds, out, "--epochs", "1", "--select-every", "1", "--select-episodes", "1", "--select-recipe", str(path))
    assert code == 0, output
    given = load_recipe(path)
    summary = json.loads(output)
    assert summary["select_recipe"] == {"path": str(path), "sha256": given.content_hash()}
    config = json.loads((out / runs.CONFIG).read_text())
    assert config["select_recipe"] == str(path) and config["select_recipe_sha256"] == given.content_hash()
    scored = json.loads((out / SELECT_DIR / "scored-001" / SCORED).read_text())
    assert scored["split"] == "val" and scored["recipe"]["name"] == "sel_handover" and scored["recipe"]["content_hash"] == given.content_hash()
    (episode,) = scored["episodes"]
    draws = {split: {episode_seed(given.seed, split, episode["index"], k) for k in range(100)} for split in ("val", "test")}
    assert episode["seed"] in draws["val"] and episode["seed"] not in draws["test"]
    assert runs.load_torch(out / runs.BEST)["val_success"] in (0.0, 1.0)

    other = _recipe(tmp_path, HANDOVER.replace("seed: 11", "seed: 12"), "other.yaml")
    code, output = _train(ds, out, "--resume", "--epochs", "2", "--select-every", "1", "--select-episodes", "1", "--select-recipe", str(other))
    assert code == 2 and f"select_recipe is {str(path)!r}, not {str(other)!r}" in output, output
    path.write_text(HANDOVER.replace("handover_noise: 1.0", "handover_noise: 0.5"))
    code, output = _train(ds, out, "--resume", "--epochs", "2", "--select-every", "1", "--select-episodes", "1", "--select-recipe", str(path))
    assert code == 2 and "changed since the run started" in output and len(output.strip().splitlines()) == 1, output
    assert not (out / SELECT_DIR / "scored-002").exists()
