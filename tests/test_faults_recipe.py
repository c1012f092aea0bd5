"""Recipes and sound folders that were accepted, crashed or exited 1: each is now one line naming
the file and the key, exit 2, in every command that loads a recipe, before anything is written."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from support.cli import one_line_exit_2

from echo_data.recipe import MAX_EXTENDS_DEPTH, MAX_NESTING, RecipeError, load_recipe

SMALL = "name: t\nsplits: {train: 1, test: 1}\n"
# (recipe text, words the error line must hold)
SEMANTICS = {
    "every target weight 0": (SMALL + "events: {categories: {phone: 0, alarm: 0, furby: 0, doorbell: 1, sink: 1}}\n", ["events.categories.phone", "weight 0"]),
    "the only target weight 0": (SMALL + "objects: {targets: [alarm]}\nevents: {categories: {phone: 1, alarm: 0, furby: 1, doorbell: 1, sink: 1}}\n", ["events.categories.alarm", "weight 0"]),
    "state weights 0": (SMALL + "setting: state_transition\nevents: {categories: {phone: 1, alarm: 1, furby: 1, doorbell: 0, sink: 0}}\n", ["events.categories.doorbell", "state_transition"]),
    "multi_event without targets": (SMALL + "setting: multi_event\nobjects: {targets: []}\n", ["objects.targets", "multi_event"]),
    "empty targets": (SMALL + "objects: {targets: []}\n", ["objects.targets", "empty"]),
    "unknown distractor shape": (SMALL + "objects: {distractor_shapes: [mug, spaceship]}\n", ["objects.distractor_shapes.1", "'mug'"]),
    "no distractor shapes": (SMALL + "objects: {distractor_shapes: []}\n", ["objects", "distractor_shapes is empty"]),
    "a target twice": (SMALL + "objects: {targets: [phone, phone]}\n", ["objects.targets", "at most once"]),
    "flat composition": ("name: t\ncomposition: {object_relocation: 5}\n", ["composition.object_relocation", "dictionary"]),
    "composition of text": ("name: t\ncomposition: {object_relocation: {train: 2}, state_transition: lots}\n", ["composition.state_transition"]),
}


@pytest.mark.parametrize("case", sorted(SEMANTICS))
def test_recipe_contradictions_are_one_line_naming_the_key(case: str, tmp_path: Path) -> None:
    text, needles = SEMANTICS[case]
    recipe = tmp_path / "r.yaml"
    recipe.write_text(text)
    out = tmp_path / "out"
    one_line_exit_2(["build", str(recipe), "--out", str(out), "--workers", "1", "--no-progress"], str(recipe), *needles)
    assert not out.exists()


def test_states_only_recipe_needs_no_targets(tmp_path: Path) -> None:
    recipe = tmp_path / "r.yaml"
    recipe.write_text(SMALL + "setting: state_transition\nobjects: {targets: []}\nevents: {categories: {phone: 0, alarm: 0, furby: 0, doorbell: 1, sink: 1}}\n")
    assert load_recipe(recipe).categories_drawn() == ["doorbell", "sink"]


def test_a_zero_weight_category_is_never_drawn(tmp_path: Path) -> None:
    """The pure sampler with alarm at weight 0: episodes draw phones and furbies only."""
    from echo_data.scene.draw import Reject, draw_episode
    from echo_data.sounds import SoundLibrary

    recipe = tmp_path / "r.yaml"
    recipe.write_text(SMALL + "events: {categories: {phone: 1, alarm: 0, furby: 1, doorbell: 1, sink: 1}}\n")
    r = load_recipe(recipe)
    assert "alarm" not in r.categories_drawn()
    lib = SoundLibrary.builtin()
    drawn = []
    for seed in range(40):
        try:
            spec = draw_episode(r, "train", 0, 0, seed, lib)
        except Reject:
            continue
        drawn += [e.category for e in spec.events]
    assert len(drawn) >= 10 and "alarm" not in drawn and {"phone", "furby"} <= set(drawn)


COMMANDS = {
    "build": ["build", "{r}", "--out", "{tmp}/out"],
    "trial": ["trial", "{r}", "-n", "1"],
    "preview": ["preview", "{r}", "--out", "{tmp}/prev"],
    "evaluate": ["evaluate", "{r}", "-n", "1"],
    "sounds list": ["sounds", "list", "--recipe", "{r}"],
}


def _loop(tmp_path: Path) -> tuple[Path, str]:
    (tmp_path / "loop.yaml").symlink_to("loop.yaml")  # a link to itself: resolving it never ends
    r = tmp_path / "r.yaml"
    r.write_text("extends: loop.yaml\nname: t\n")
    return r, "symlink loop"


def _self_link(tmp_path: Path) -> tuple[Path, str]:
    r = tmp_path / "r.yaml"
    r.symlink_to("r.yaml")
    return r, "symlink loop"


def _deep_yaml(tmp_path: Path) -> tuple[Path, str]:
    r = tmp_path / "r.yaml"
    r.write_text("name: t\nscene: " + "[" * 3000 + "]" * 3000 + "\n")
    return r, f"nested more than {MAX_NESTING} levels"


def _deep_mapping(tmp_path: Path) -> tuple[Path, str]:
    r = tmp_path / "r.yaml"
    r.write_text("name: t\nrobot: " + "{a: " * 60 + "1" + "}" * 60 + "\n")
    return r, "robot.a.a.a"


def _long_chain(tmp_path: Path) -> tuple[Path, str]:
    n = MAX_EXTENDS_DEPTH + 5
    for i in range(n):
        (tmp_path / f"c{i}.yaml").write_text(f"extends: c{i + 1}.yaml\n" if i < n - 1 else "name: t\n")
    return tmp_path / "c0.yaml", f"more than {MAX_EXTENDS_DEPTH} files"


LOADS = {"extends symlink loop": _loop, "recipe links to itself": _self_link, "3000 nested brackets": _deep_yaml,
         "60 nested mappings": _deep_mapping, "long extends chain": _long_chain}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", sorted(LOADS))
def test_recipe_loops_and_depth_are_one_line_in_every_command(case: str, command: str, tmp_path: Path) -> None:
    recipe, says = LOADS[case](tmp_path)
    before = sorted(os.listdir(tmp_path))
    one_line_exit_2([a.format(r=recipe, tmp=tmp_path) for a in COMMANDS[command]], says)
    assert sorted(os.listdir(tmp_path)) == before
    with pytest.raises(RecipeError):
        load_recipe(recipe)


def _folder_recipe(tmp_path: Path, files: dict[str, np.ndarray], extra: str = "") -> Path:
    folder = tmp_path / "phones"
    folder.mkdir()
    for name, x in files.items():
        sf.write(str(folder / name), x, 16000, subtype="PCM_16")
    recipe = tmp_path / "r.yaml"
    recipe.write_text(SMALL + "sounds: {folders: {phone: phones}" + extra + "}\n")
    return recipe


RING = 0.4 * np.sin(np.arange(16000) * 0.2)


@pytest.mark.parametrize("command", ["build", "evaluate", "trial", "preview"])
def test_a_silent_user_wav_is_exit_2(command: str, tmp_path: Path) -> None:
    recipe = _folder_recipe(tmp_path, {"ring.wav": RING, "quiet.wav": np.zeros(16000)})
    one_line_exit_2([a.format(r=recipe, tmp=tmp_path) for a in COMMANDS[command]], "quiet.wav", "silent")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["phones", "r.yaml"]


@pytest.mark.parametrize("command", ["build", "evaluate", "trial", "preview"])
def test_a_one_file_folder_without_built_ins_has_no_test_sound_exit_2(command: str, tmp_path: Path) -> None:
    recipe = _folder_recipe(tmp_path, {"ring.wav": RING}, ", builtin: false")
    recipe.write_text(recipe.read_text() + "events: {categories: {phone: 1, alarm: 0, furby: 0, doorbell: 0, sink: 0}}\n")
    one_line_exit_2([a.format(r=recipe, tmp=tmp_path) for a in COMMANDS[command]], "sounds.folders.phone", "no test sound")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["phones", "r.yaml"]
