"""`echo-data train`'s per-skill defaults: the options the studies chose for each skill, so a user
who names only the skill trains the learner the studies measured (explicit options and `--config
FILE` values win; config.json records what was resolved).

Where each choice comes from (the learners study's results, its results/ folder):
- Manipulation (Pick, Place, OpenDoor, CloseSink): head and wrist depth, base-frame proprioception
  and the target kind; random shift of up to 4 px; 20 epochs, the checkpoint chosen closed loop on
  10 validation episodes every 10 epochs (camera_learners.json: ACT so trained scored CloseSink
  50/50 and Pick 27/50 alone). Without the wrist camera CloseSink fell to 9/50
  (camera_ablations.json, act_no_wrist_depth); ACT itself (chunk 20, its config's default) beat
  a one-step ACT after a hand-over (28/50 against 13/50, act_chunk1) and diffusion (Pick 0/50,
  CloseSink 6/50).
- Navigate: the binaural level and ILD (`--audio-form level_ild`, the config's default),
  proprioception and the target kind, no camera; 20 epochs, chosen every 5 epochs on 10
  validation episodes (navigate_from_sound.json: BC-RNN so trained, 61/100 on test).
- Action column: every study cloned `action.ee` on recipes whose env acts in `ee_delta`; the
  default is the column the dataset's own recipe acts in (`robot.action_space`), because a learner
  of the other form could neither be chosen closed loop on that recipe's val split nor evaluated
  on it (the env takes one form).

The studies' drivers pass these options explicitly (their committed runs stay reproducible); the
paper table study spells its learners' options (rows.py: MANIPULATION, NAVIGATE) from this table,
and tests/test_train_defaults.py holds them to the commands its committed runs were trained with.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from echo_data.learn.features import AUDIO_COLUMNS, IMAGE_INPUT_COLUMNS, STATE
from echo_data.skill_table import SKILLS


@dataclass(frozen=True)
class SkillDefaults:
    """The options a skill's learner is trained with unless told otherwise."""

    inputs: tuple[str, ...]
    epochs: int
    select_every: int
    select_episodes: int
    shift: int  # image learners only: 0 where the resolved inputs hold no image


MANIPULATION = SkillDefaults(("depth", "wrist_depth", "state", "kind"), epochs=20, select_every=10, select_episodes=10, shift=4)
NAVIGATE = SkillDefaults(("audio", "state", "kind"), epochs=20, select_every=5, select_episodes=10, shift=0)
# Per skill of the skill table: its drive (the approach role) learns as Navigate, every other skill as manipulation.
SKILL_DEFAULTS: dict[str, SkillDefaults] = {name: NAVIGATE if s.role == "approach" else MANIPULATION for name, s in SKILLS.items()}
STUDY_ACTION_COLUMN = "action.ee"  # what every study cloned (on ee_delta recipes)
RESOLVED = ("inputs", "action_column", "shift", "epochs", "select_every", "select_episodes")  # the options this module fills in


def stored_inputs(dataset: Path, names: tuple[str, ...], audio: str) -> tuple[str, ...] | None:
    """The inputs among `names` whose columns `dataset` stores (its train statistics), None when
    they cannot be read (training then says what is wrong with the dataset)."""
    try:
        stats = json.loads((dataset / "meta" / "stats.json").read_text())
    except (OSError, ValueError):
        return None
    column = {**IMAGE_INPUT_COLUMNS, "audio": AUDIO_COLUMNS.get(audio, ""), "state": STATE}
    return tuple(n for n in names if n not in column or column[n] in stats)


def recipe_column(dataset: Path) -> str | None:
    """The action column the env of `dataset`'s recipe acts in (None: no readable recipe)."""
    from echo_data.dataset.reader import dataset_recipe
    from echo_data.learn.select import COLUMN_OF_SPACE

    try:
        recipe, _ = dataset_recipe(dataset)
    except (OSError, ValueError, KeyError):  # no readable manifest or recipe: training's own checks name the file and key
        return None
    return COLUMN_OF_SPACE[recipe.robot.action_space]


def resolve(skill: str, given: Mapping[str, Any], dataset: Path) -> tuple[dict[str, Any], list[str]]:
    """The values of RESOLVED options that `given` (the command line over `--config FILE`) lacks,
    for `skill` on `dataset`, and notes for the user where the dataset changed a default: a default
    input the dataset does not store is left out (never an explicit one: that is refused by the
    training as before), and a closed-loop choice that the recipe cannot run (the action column
    given is not the one its env acts in) falls back to the lowest validation loss."""
    table = SKILL_DEFAULTS.get(skill)
    if table is None:  # not a skill of the table: the config's own defaults (and its refusal)
        return {}, []
    out: dict[str, Any] = {}
    notes: list[str] = []
    if "inputs" not in given:
        held = stored_inputs(dataset, table.inputs, str(given.get("audio", "spectrogram")))
        out["inputs"] = table.inputs if held is None else held
        if held is not None and held != table.inputs:
            notes.append(f"{dataset} stores no {', '.join(n for n in table.inputs if n not in held)}: "
                         f"{skill} trains on {','.join(held)} (its default inputs are {','.join(table.inputs)})")
    column = recipe_column(dataset)
    if "action_column" not in given and column is not None:
        out["action_column"] = column
    inputs = given.get("inputs", out.get("inputs", table.inputs))
    names = inputs.split(",") if isinstance(inputs, str) else list(inputs)
    if "shift" not in given:
        out["shift"] = table.shift if any(n.strip() in IMAGE_INPUT_COLUMNS for n in names) else 0
    if "epochs" not in given:
        out["epochs"] = table.epochs
    if "select_every" not in given:
        chosen = given.get("action_column", out.get("action_column"))
        if column is None or chosen == column:
            out["select_every"] = table.select_every
        else:
            out["select_every"] = 0
            notes.append(f"--action-column {chosen}: {dataset}'s recipe acts in {column}, so the checkpoint is the lowest validation loss, "
                         "not chosen closed loop")
    if "select_episodes" not in given:
        out["select_episodes"] = table.select_episodes
    return out, notes


def help_line() -> str:
    """What `--help` says of the per-skill defaults."""
    m, n = MANIPULATION, NAVIGATE
    return (f"Unset options default per skill (echo_data/learn/defaults.py): Pick, Place, OpenDoor, CloseSink --inputs {','.join(m.inputs)} --shift {m.shift} "
            f"--epochs {m.epochs} --select-every {m.select_every} --select-episodes {m.select_episodes}; Navigate --inputs {','.join(n.inputs)} "
            f"--epochs {n.epochs} --select-every {n.select_every} --select-episodes {n.select_episodes}; --action-column the form the dataset's "
            "recipe acts in; a default input the dataset does not store is left out.")
