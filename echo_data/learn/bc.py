"""Behaviour cloning of one skill: the training loop (model in `models`, acting in `policy`).

Loss: mean squared error between predicted and expert actions, both normalised with the
dataset's action statistics, over `chunk` future actions (padding past the segment's end masked).
Validation: whole episodes of the train split held out (`split_episodes`); the test split is never
read here. `recurrent` (BC-RNN) trains a GRU on whole skill segments, `seq_batch` segments per
step padded to the longest and masked, its state zero at each segment's first row: exactly what
the policy sees after `reset` at a skill's start, so no train/act mismatch in history length. Deterministic for a seed on CPU: fixed thread count, deterministic kernels, weights
initialised from the seed, and the batch order of epoch e drawn from (seed, e) alone, so a resumed
run draws the same batches as an uninterrupted one.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.learn import runs
from echo_data.learn.data import SkillRows, append_rows, count_rows, load_skill_rows, skill_kinds, skills_in, split_episodes
from echo_data.learn.features import ACTION_FORMS, FeatureSpec, feature_spec, to_action_form
from echo_data.learn.loop import LoopConfig, fit, setup_torch

POLICY_CLASS = "echo_data.learn.policy:BCPolicy"


@dataclass
class BCConfig:
    """Everything that defines a BC run (written resolved to config.json)."""

    dataset: str
    skill: str
    inputs: tuple[str, ...]
    epochs: int = 30
    seed: int = 0
    batch_size: int = 64
    lr: float = 1e-3
    weight_decay: float = 1e-4
    chunk: int = 1  # actions predicted per step
    execute: int = 1  # of those, executed before predicting again
    val_fraction: float = 0.15
    threads: int = 1  # see loop.setup_torch: more threads than free cores is many times slower
    image_size: int = 64
    audio: str = "spectrogram"
    audio_form: str = "level_ild"  # features.AUDIO_FORMS; run folders from before the option were "stored"
    max_steps: int | None = None  # stop (and checkpoint) after this many optimiser steps
    recurrent: bool = False  # a GRU over the steps of a segment (models.BCRNN)
    seq_batch: int = 4  # segments per optimiser step when recurrent
    shift: int = 0  # training images shifted by up to this many pixels (random-shift augmentation); 0 = off
    action_form: str = "absolute"  # features.ACTION_FORMS: what the network predicts
    # Filled in by train_bc:
    features: dict[str, Any] = field(default_factory=dict)
    audio_shape: list[int] | None = None
    action_mean: list[float] = field(default_factory=list)
    action_std: list[float] = field(default_factory=list)
    val_episodes: list[int] = field(default_factory=list)

    @staticmethod
    def from_dict(d: dict[str, Any]) -> BCConfig:
        return BCConfig(**{"audio_form": "stored", **d, "inputs": tuple(d["inputs"])})  # older runs fed the stored form


def build_model(cfg: BCConfig) -> Any:
    from echo_data.learn.models import BCRNN, BCNet, stored_audio_shape

    spec = FeatureSpec.from_dict(cfg.features)
    if cfg.recurrent:
        return BCRNN(spec, stored_audio_shape(cfg.audio_shape))
    return BCNet(spec, stored_audio_shape(cfg.audio_shape), chunk=cfg.chunk)


def resolve(cfg: BCConfig) -> BCConfig:
    """Check the request against the dataset and freeze the constants (raises FeatureError /
    RunError with a one-line message)."""
    import json

    from echo_data.learn.models import audio_shape

    root = Path(cfg.dataset)
    if not (root / "manifest.json").is_file():
        raise runs.RunError(f"{root}: not an echo-data dataset (no manifest.json)")
    manifest = runs.read_json(root / "manifest.json")
    if "train" not in manifest.get("splits", {}):
        raise runs.RunError(f"{root / 'manifest.json'}: no 'train' split to learn from")
    if cfg.chunk < 1 or not 1 <= cfg.execute <= cfg.chunk:
        raise runs.RunError(f"--chunk {cfg.chunk} / --execute {cfg.execute}: need 1 <= execute <= chunk")
    if cfg.action_form not in ACTION_FORMS:
        raise runs.RunError(f"--action-form: unknown form {cfg.action_form!r}; choose from {', '.join(ACTION_FORMS)}")
    if cfg.action_form == "delta" and not {"state", "state_raw"} & set(cfg.inputs):
        raise runs.RunError("--action-form delta adds the predicted change to the measured joints: --inputs needs state")
    if cfg.recurrent and cfg.chunk != 1:
        raise runs.RunError(f"--gru predicts one action per step: --chunk must be 1, got {cfg.chunk}")
    skills = skills_in(root, "train")
    if cfg.skill not in skills:
        raise runs.RunError(f"--skill {cfg.skill!r}: no such rows in {root} (train split has {', '.join(skills)})")
    spec = feature_spec(root, cfg.inputs, audio=cfg.audio, image_size=cfg.image_size, audio_form=cfg.audio_form,
                        kinds=skill_kinds(root, "train", cfg.skill))
    stats = json.loads((root / "meta" / "stats.json").read_text())["action"]
    shape = audio_shape(spec, manifest["layout"])
    return BCConfig(
        **{
            **asdict(cfg),
            "dataset": str(root.resolve()),
            "features": spec.to_dict(),
            "audio_shape": list(shape) if shape else None,
            "action_mean": list(stats["mean"]),
            "action_std": [s if s > 1e-3 else 1.0 for s in stats["std"]],
        }
    )


def _masked_mse(pred: Any, target: Any, valid: Any) -> Any:
    err = ((pred - target) ** 2).mean(dim=2)
    return (err * valid).sum() / valid.sum().clamp(min=1)


class _Units:
    """What one optimiser step draws: rows (feed-forward) or whole segments (recurrent), and how a
    draw becomes predictions over rows: (pred (N, chunk, A), row index (N,), real (N,) bool; padding
    rows of a short segment are not real)."""

    def __init__(self, rows: SkillRows, recurrent: bool, model: Any) -> None:
        import torch

        self.rows, self.recurrent, self.model, self.torch = rows, recurrent, model, torch
        if recurrent:
            if (rows.segments < 0).any():
                raise runs.RunError("a recurrent model trains on whole segments: appended (DAgger) rows have none")
            ids, first, count = np.unique(rows.segments, return_index=True, return_counts=True)
            self.spans = {int(i): (int(f), int(c)) for i, f, c in zip(ids, first, count, strict=True)}

    def split(self, is_val: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Train and validation units (row indices or segment ids) from the per-row mask."""
        if not self.recurrent:
            return np.flatnonzero(~is_val), np.flatnonzero(is_val)
        seg = np.array(sorted(self.spans))
        val = np.array([is_val[self.spans[s][0]] for s in seg], dtype=bool)
        return seg[~val], seg[val]

    def forward(self, units: np.ndarray, shift: int = 0, seed: int = 0) -> tuple[Any, np.ndarray, np.ndarray]:
        torch, inputs = self.torch, self.rows.inputs
        rng = np.random.default_rng([seed, len(units), *units.tolist()])  # from the batch itself: a resumed run draws alike
        if not self.recurrent:
            t = torch.from_numpy(units)
            x = {k: _shifted(v[t], shift, rng) if k in IMAGE_INPUTS else v[t] for k, v in inputs.items()}
            return self.model(x), units, np.ones(len(units), dtype=bool)
        spans = [self.spans[int(s)] for s in units]
        length = max(c for _, c in spans)
        steps = np.arange(length)
        real = steps[None, :] < np.array([c for _, c in spans])[:, None]
        ix = np.array([f + np.minimum(steps, c - 1) for f, c in spans])  # padded with each segment's last row
        t = torch.from_numpy(ix.reshape(-1))
        x = {k: v[t].view(len(spans), length, *v.shape[1:]) for k, v in inputs.items()}
        x = {k: _shifted(v, shift, rng) if k in IMAGE_INPUTS else v for k, v in x.items()}
        pred, _ = self.model(x)
        return pred.reshape(-1, *pred.shape[2:]), ix.reshape(-1), real.reshape(-1)


IMAGE_INPUTS = ("depth", "wrist_depth", "rgb", "image")


def _shifted(x: Any, shift: int, rng: np.random.Generator) -> Any:
    """Random-shift augmentation (DrQ, Kostrikov et al. 2020; RAD, Laskin et al. 2020): pad each
    image by `shift` pixels (edge values repeated) and crop back at a random offset, one offset
    per sample (per segment for sequences: the camera is off by a constant). Why: with tens of
    demonstrations a CNN otherwise keys on exact pixel positions of one room."""
    if shift <= 0:
        return x
    import torch
    import torch.nn.functional as F

    c, h, w = x.shape[-3:]
    parts = []
    for sample in x:  # (C, H, W), or (T, C, H, W) for a segment
        dy, dx = (int(v) for v in rng.integers(0, 2 * shift + 1, size=2))
        padded = F.pad(sample.reshape(-1, c, h, w), (shift, shift, shift, shift), mode="replicate")
        parts.append(padded[..., dy : dy + h, dx : dx + w].reshape(sample.shape))
    return torch.stack(parts)


def train_bc(cfg: BCConfig, out: Path, resume: bool = False, overwrite: bool = False, progress: bool = True, extra: Any = None) -> dict[str, Any]:
    """Train (or continue) a BC run in `out`; returns the summary also printed by the CLI.

    `extra` (DAgger's labelled rollouts: `inputs`, `actions` (n, 1, ACTION_DIM)) is appended to
    the training rows, never to validation."""
    from tqdm import tqdm

    runs.check_out(out, resume, overwrite)
    if resume:
        saved = BCConfig.from_dict(runs.read_json(out / runs.CONFIG))
        runs.check_same_run(out, asdict(cfg), asdict(saved), ("dataset", "skill", "inputs", "seed", "chunk", "audio_form", "recurrent", "action_form"))
        cfg = BCConfig.from_dict({**asdict(saved), "epochs": cfg.epochs, "max_steps": cfg.max_steps})
    else:
        cfg = resolve(cfg)
    torch = setup_torch(cfg.seed, cfg.threads)
    spec = FeatureSpec.from_dict(cfg.features)
    root = Path(cfg.dataset)
    total_rows = count_rows(root, "train", cfg.skill)
    with tqdm(total=total_rows, desc=f"decode {cfg.skill}", unit="row", disable=not progress, leave=False) as bar:
        rows = load_skill_rows(root, "train", cfg.skill, spec, chunk=cfg.chunk, tick=bar.update)
    val_eps = split_episodes(rows.episodes, cfg.val_fraction, cfg.seed)
    cfg.val_episodes = [int(e) for e in val_eps]
    if cfg.action_form != "absolute":
        if extra is not None and len(extra):
            raise runs.RunError(f"--action-form {cfg.action_form} does not take DAgger rows (their states are not kept)")
        assert rows.states is not None
        rows.actions = to_action_form(rows.actions, rows.states, cfg.action_form)
        if not resume:  # the skill's own training rows set the scale (validation rows left out)
            kept = ~np.isin(rows.episodes, val_eps)
            fit_rows = rows.actions[kept][~rows.action_pad[kept]]
            cfg.action_mean = [float(v) for v in fit_rows.mean(axis=0)]
            cfg.action_std = [float(v) if v > 1e-3 else 1.0 for v in fit_rows.std(axis=0)]
    if extra is not None and len(extra):
        rows = append_rows(rows, extra.inputs, extra.actions)
    is_val = np.isin(rows.episodes, val_eps)
    tr, va = np.flatnonzero(~is_val), np.flatnonzero(is_val)
    mean, std = np.asarray(cfg.action_mean, np.float32), np.asarray(cfg.action_std, np.float32)
    target = torch.from_numpy((rows.actions - mean) / std)
    valid = torch.from_numpy(~rows.action_pad).float()

    torch.manual_seed(cfg.seed)
    model = build_model(cfg)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    runs.write_run_files(out, "policy", POLICY_CLASS, asdict(cfg), {"skill": cfg.skill, "inputs": list(cfg.inputs)})
    scale = torch.from_numpy(std)
    units = _Units(rows, cfg.recurrent, model)
    tr_units, va_units = units.split(is_val)

    def loss_fn(ix: np.ndarray) -> Any:
        pred, at, real = units.forward(ix, cfg.shift, cfg.seed)
        return _masked_mse(pred, target[at], valid[at] * torch.from_numpy(real)[:, None])

    def validate() -> dict[str, float]:
        """Normalised MSE; mean absolute error of the next action in physical units, over all
        dimensions and over the base velocities (m/s, rad/s) alone (every validation row once)."""
        if len(va_units) == 0:
            return {"val_loss": math.nan, "val_action_mae": math.nan, "val_base_mae": math.nan}
        se, ae, base, n = 0.0, 0.0, 0.0, 0
        with torch.no_grad():
            for lo in range(0, len(va_units), 8 if cfg.recurrent else 512):
                pred, at, real = units.forward(va_units[lo : lo + (8 if cfg.recurrent else 512)])
                pred, at = pred[torch.from_numpy(real)], at[real]
                se += float(_masked_mse(pred, target[at], valid[at])) * len(at)
                err = (pred[:, 0] - target[at][:, 0]).abs() * scale
                ae += float(err.mean()) * len(at)
                base += float(err[:, :3].mean()) * len(at)
                n += len(at)
        return {"val_loss": se / n, "val_action_mae": ae / n, "val_base_mae": base / n}

    loop = LoopConfig(cfg.epochs, cfg.seq_batch if cfg.recurrent else cfg.batch_size, cfg.seed, cfg.max_steps)
    state = fit(model, opt, tr_units, loss_fn, validate, loop, out, resume, progress, desc=f"train {cfg.skill}")
    # Reference: the validation loss of always answering the mean training action of this skill.
    mean_val = float(_masked_mse(target[tr].mean(dim=0, keepdim=True).expand(len(va), -1, -1), target[va], valid[va])) if len(va) else math.nan
    return {
        "run": str(out),
        "skill": cfg.skill,
        "inputs": list(cfg.inputs),
        "state_fed": list(spec.state_names),
        "rows": {"train": int(len(tr)), "val": int(len(va)), "dagger": int(len(extra)) if extra is not None else 0},
        "episodes": {"train": int(len(np.unique(rows.episodes[tr]))), "val": int(len(val_eps))},
        "step": state["step"],
        "epoch": state["epoch"],
        "seconds": round(state["seconds"], 1),
        "best_val_loss": state["best_val"] if state["best_val"] != math.inf else None,
        "val_loss_of_mean_train_action": mean_val,
        "last": state["history"][-1] if state["history"] else None,
    }
