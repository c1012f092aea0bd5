"""What every skill learner shares: the config fields common to all algorithms, the action
spaces a learner can clone, and the loss of an action head.

An algorithm is a config class (a dataclass deriving from `SkillConfig`: its own fields, how
many future actions one training row carries, how it acts) and a model class with two methods:
`loss(x, target, valid)` for the shared fit loop (`learn/fit.py`) and `predict(x, state)` for
the shared policy (`learn/policy.py`). The registry (`algos/__init__.py`) names them; the CLI
is generated from the config's fields (`learn/cli.py`).
"""

from __future__ import annotations

import math
from dataclasses import MISSING, asdict, dataclass, field, fields
from typing import Any, ClassVar

from echo_data.dataset.schema import SKILL_STOP
from echo_data.records import ACTION_NAMES, EE_ACTION_NAMES, PRIVILEGED_PREFIX

SEED_LIMIT = 2**64  # numpy's SeedSequence takes any non-negative int; torch.manual_seed 64 bits at most
DEVICES = ("cpu", "cuda", "auto")
# The step-row columns a learner can clone and, per column, its binary entries (learned with a
# classification loss and thresholded at 0.5 when acting). The joint form's gripper is a target
# opening in metres (continuous); the end-effector form's `gripper_close` is 1 = close, 0 = open.
ACTION_COLUMNS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "action": (ACTION_NAMES, ()),
    "action.ee": (EE_ACTION_NAMES, ("gripper_close",)),
}


class ConfigError(ValueError):
    """A config value that cannot train (one line, names the option)."""


def opt(default: Any, help: str, **meta: Any) -> Any:
    """A config field with its command-line help (the CLI is generated from these)."""
    if isinstance(default, (list, dict)):
        return field(default_factory=lambda: type(default)(default), metadata={"help": help, **meta})
    return field(default=default, metadata={"help": help, **meta})


def resolved(default: Any) -> Any:
    """A field filled in from the dataset when a run starts (not an option)."""
    return field(default_factory=lambda: type(default)(default) if isinstance(default, (list, dict)) else default, metadata={"resolved": True})


@dataclass
class SkillConfig:
    """Everything that defines a skill-learning run (written resolved to the run's config.json)."""

    ALGO: ClassVar[str] = ""
    SEQUENCE: ClassVar[bool] = False  # trains on whole skill segments (a recurrent model)

    dataset: str = opt("", "Dataset folder.", positional=True)
    skill: str = opt("", "Skill whose step rows are cloned (Navigate, Pick, Place, OpenDoor, CloseSink).", required=True)
    inputs: tuple[str, ...] = opt(
        ("audio", "depth", "state"),
        "Comma list of audio, depth (head), wrist_depth, rgb (head), state (base-frame proprioception, velocities left out), "
        "state_raw (all 25 entries: measures the shortcut), target (the goal position: the paper's * rows), kind (target kind, one-hot), "
        f"or a privileged column by its full name ({PRIVILEGED_PREFIX}...; never a default).",
    )
    epochs: int = opt(30, "Passes over the training rows.")
    seed: int = opt(0, "Seed of initialisation, split and batch order (0 <= seed < 2**64).")
    batch_size: int = opt(64, "Rows (or segments, for a recurrent learner) per optimiser step.")
    lr: float = opt(1e-3, "AdamW learning rate (finite, > 0).")
    weight_decay: float = opt(1e-4, "AdamW weight decay.")
    val_fraction: float = opt(0.15, "Share of train episodes held out for the validation loss.")
    threads: int = opt(1, "torch CPU threads (reproducible for a fixed count; 1 is fastest on a busy machine).")
    device: str = opt("cpu", "Where to train: cpu, cuda or auto (cuda when there is one).")
    image_size: int = opt(64, "Side images are area-downsampled to; 0 = their stored resolution.")
    encoder: str = opt("cnn", "Image encoder: cnn (strided convolutions, flattened) or spatial_softmax (keypoints: where things are).")
    audio: str = opt("spectrogram", "Audio feature: spectrogram or mel.")
    audio_form: str = opt("level_ild", "How audio is fed: level_ild (each ear in dB plus their difference) or stored.")
    max_steps: int | None = opt(None, "Stop (and checkpoint) after this many optimiser steps.")
    shift: int = opt(0, "Random-shift augmentation of training images: up to N pixels (0 = off; below the image side).")
    action_form: str = opt("absolute", "What the network predicts: absolute or delta (joint targets as the change from the measured joints).")
    action_column: str = opt("action", f"Action column cloned: {', '.join(ACTION_COLUMNS)}.")
    select_every: int = opt(0, "Every N epochs run the policy closed loop on validation-split episodes; best.pt = the best success (0 = lowest validation loss).")
    select_episodes: int = opt(3, "Validation-split episodes per closed-loop selection.")
    select_recipe: str = opt("", "Recipe YAML whose val split --select-every scores on (never its test split): the condition the run is "
                                 "measured in, e.g. after a hand-over (default: the dataset's own recipe).")
    stop: bool = opt(False, "Also learn each segment's last row (the dataset's skill_stop) as a binary output and end the skill when "
                            "it is predicted (SoundSpaces' STOP; the skill is then judged once, where the policy stopped).")
    switch_ahead: int = opt(1, "A binary entry (the gripper) switches as soon as the newest predicted chunk switches it within "
                               "this many steps (1: the current step's prediction alone; at most the chunk).")
    from_stance: bool = opt(False, "Place: train only on each segment's rows from the first one inside Place's stance on (the carry before it "
                                   "is the drive learner's: --with-carries); evaluate then carries with the drive policy first (docs/handover.md).")
    with_carries: bool = opt(False, "Navigate: also train on the carry of every Place segment (its rows before Place's stance) as a drive to the "
                                    "receptacle, its kind as the kind input (docs/handover.md).")
    # Filled in when the run starts:
    algo: str = resolved("")
    features: dict[str, Any] = resolved({})
    audio_shape: list[int] | None = resolved(None)
    action_mean: list[float] = resolved([])
    action_std: list[float] = resolved([])
    val_episodes: list[int] = resolved([])
    stop_weight: float = resolved(1.0)  # with `stop`: the STOP's positive-class weight, set from the training rows (`binary_weights`)
    stop_threshold: float = resolved(0.5)  # with `stop`: STOP when its probability passes this (chosen on validation: learn.select)
    select_recipe_sha256: str = resolved("")  # with `select_recipe`: its content hash when the run started (learn.select)
    held_entries: list[list[float]] = resolved([])  # [[index, value], ...]: entries the same on every training row; acted exactly (`held_entries`)

    # How the algorithm trains and acts; each algorithm overrides what differs.
    def window(self) -> int:
        """Future actions (t .. t+window-1 within the segment) one training row carries."""
        return 1

    def execute_steps(self) -> int:
        """Predicted actions executed before predicting again."""
        return 1

    def history(self) -> int:
        """Observation steps a prediction reads (t-history+1 .. t, clamped to the segment's start)."""
        return 1

    def ensemble_weight(self) -> float | None:
        """ACT's temporal ensembling weight m (None: off)."""
        return None

    def check(self) -> None:
        """Raise ConfigError on values no run can use (checked before anything is written)."""
        if not (isinstance(self.lr, float | int) and math.isfinite(self.lr) and self.lr > 0):
            raise ConfigError(f"--lr {self.lr}: must be a finite number > 0")
        if not 0 <= self.seed < SEED_LIMIT:
            raise ConfigError(f"--seed {self.seed}: must be within [0, 2**64)")
        if not (math.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise ConfigError(f"--weight-decay {self.weight_decay}: must be a finite number >= 0")
        if not 0 <= self.val_fraction < 1:
            raise ConfigError(f"--val-fraction {self.val_fraction}: must be within [0, 1)")
        for name in ("epochs", "batch_size", "threads", "select_episodes"):
            if getattr(self, name) < 1:
                raise ConfigError(f"--{name.replace('_', '-')} {getattr(self, name)}: must be >= 1")
        if self.max_steps is not None and self.max_steps < 1:
            raise ConfigError(f"--max-steps {self.max_steps}: must be >= 1")
        if not 1 <= self.switch_ahead <= self.window():
            raise ConfigError(f"--switch-ahead {self.switch_ahead}: need 1 <= switch-ahead <= the actions predicted per step ({self.window()})")
        if self.select_every < 0 or self.shift < 0 or self.image_size < 0:
            raise ConfigError("--select-every, --shift and --image-size must be >= 0")
        if self.select_recipe and not self.select_every:
            raise ConfigError("--select-recipe: chooses the checkpoint closed loop; it needs --select-every")
        if self.device not in DEVICES:
            raise ConfigError(f"--device {self.device!r}: choose from {', '.join(DEVICES)}")
        if self.encoder not in ("cnn", "spatial_softmax"):
            raise ConfigError(f"--encoder {self.encoder!r}: choose from cnn, spatial_softmax")
        if self.action_column not in ACTION_COLUMNS:
            raise ConfigError(f"--action-column {self.action_column!r}: choose from {', '.join(ACTION_COLUMNS)}")
        if self.action_form == "delta" and self.action_column != "action":
            raise ConfigError("--action-form delta is the joint form's change from the measured joints: it needs --action-column action")
        if self.stop and self.action_form != "absolute":
            raise ConfigError("--stop: learns the stop beside the action as stored; it needs --action-form absolute")
        self._check_carry()

    def _check_carry(self) -> None:
        """--from-stance is a deliver skill's (Place), --with-carries the approach skill's (Navigate)."""
        from echo_data.skill_table import SKILLS

        role = SKILLS[self.skill].role if self.skill in SKILLS else None
        if self.from_stance and role != "deliver":
            raise ConfigError(f"--from-stance: applies to a skill that carries to its own stance ({', '.join(n for n, s in SKILLS.items() if s.role == 'deliver')}), not {self.skill!r}")
        if self.with_carries and role != "approach":
            raise ConfigError(f"--with-carries: applies to the drive skill ({', '.join(n for n, s in SKILLS.items() if s.role == 'approach')}), not {self.skill!r}")

    @property
    def action_names(self) -> tuple[str, ...]:
        """The cloned action's entries (what the policy gives the environment)."""
        return ACTION_COLUMNS[self.action_column][0]

    @property
    def target_names(self) -> tuple[str, ...]:
        """What the network predicts per step: the action, then with `stop` the skill's STOP."""
        return self.action_names + ((SKILL_STOP,) if self.stop else ())

    @property
    def binary(self) -> tuple[int, ...]:
        """Indices (in `target_names`) of the binary entries: the gripper's, and the STOP."""
        names, binary = ACTION_COLUMNS[self.action_column]
        return tuple(names.index(n) for n in binary) + ((len(names),) if self.stop else ())

    def binary_weights(self) -> tuple[float, ...]:
        """Positive-class weight of each binary entry's cross-entropy: 1 for the gripper; for the
        STOP `stop_weight`, the training rows' non-last rows per last row. Why: a segment has one
        last row against ~100 others and the expert is nearly at rest over its last few, so
        unweighted the probability at the goal stays near 1/(rows at rest) and never passes 0.5:
        the policy would never stop. Balanced, it stops where the expert's states end."""
        _, binary = ACTION_COLUMNS[self.action_column]
        return (1.0,) * len(binary) + ((float(self.stop_weight),) if self.stop else ())

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "algo": self.ALGO}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Any:
        """A saved config; keys of other algorithms or older runs that this class lacks are dropped."""
        names = {f.name for f in fields(cls)}
        kept = {k: v for k, v in d.items() if k in names}
        if "inputs" in kept:
            kept["inputs"] = tuple(kept["inputs"])
        return cls(**kept)

    @classmethod
    def options(cls) -> list[Any]:
        """The fields a user sets (the CLI's options), in declaration order."""
        return [f for f in fields(cls) if not f.metadata.get("resolved") and not f.metadata.get("positional")]

    @classmethod
    def default_of(cls, f: Any) -> Any:
        return f.default_factory() if f.default is MISSING else f.default


def held_entries(actions: Any) -> list[list[float]]:
    """[[index, value], ...] of the action entries that hold one value on every training row
    (`actions` (N, A), in the run's action form), which the policy then emits exactly.

    Why: the targets are normalised by the dataset's statistics over every skill, so an entry
    that one skill never moves (Navigate's TCP change: the experts hold the arm while driving)
    is a non-zero constant the network only approximates. Acted in the end-effector form, a TCP
    change that is not exactly zero re-solves the arm's inverse kinematics, whose null-space pull
    towards READY refolds the redundant arm drive after drive (measured: the learned Navigate
    moved an arm joint by 1.3 rad per drive, docs/learners.md); a zero change holds the joint
    targets bit for bit (docs/action_spaces.md)."""
    import numpy as np

    a = np.asarray(actions)
    if not len(a):
        return []
    lo, hi = a.min(axis=0), a.max(axis=0)
    return [[int(i), float(lo[i])] for i in np.flatnonzero(lo == hi)]


def action_loss(pred: Any, target: Any, valid: Any, binary: tuple[int, ...], l1: bool = False, pos_weight: tuple[float, ...] = ()) -> Any:
    """Mean over valid (row, step) pairs of the regression error of continuous entries (squared,
    or absolute for `l1`) plus the binary cross-entropy of binary ones (`pred` holds logits there;
    `pos_weight`, one per binary entry, weights their positive class: `SkillConfig.binary_weights`).

    pred, target: (N, W, A); valid: (N, W) float (0 where the window ran past the segment)."""
    import torch
    import torch.nn.functional as F

    cont = [i for i in range(pred.shape[-1]) if i not in binary]
    diff = pred[..., cont] - target[..., cont]
    err = (diff.abs() if l1 else diff**2).sum(dim=-1)
    if binary:
        b = list(binary)
        w = torch.tensor(pos_weight, dtype=pred.dtype, device=pred.device) if any(v != 1.0 for v in pos_weight) else None  # all 1: the plain loss
        err = err + F.binary_cross_entropy_with_logits(pred[..., b], target[..., b], pos_weight=w, reduction="none").sum(dim=-1)
    err = err / pred.shape[-1]
    return (err * valid).sum() / torch.clamp(valid.sum(), min=1)


def to_probabilities(pred: Any, binary: tuple[int, ...]) -> Any:
    """Raw head outputs -> predictions: logits of binary entries become probabilities."""
    import torch

    if not binary:
        return pred
    out = pred.clone()
    out[..., list(binary)] = torch.sigmoid(pred[..., list(binary)])
    return out
