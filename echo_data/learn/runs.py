"""The files of a training run folder, each written atomically (a crash leaves the old file).

runs/NAME/
  policy.json     {"kind": "policy" | "planner", "class": "module:Class", ...}: the run's kind
  agent.json      {"class": "module:Class", "kwargs": {}}: an evaluate checkpoint folder, built as
                  Class(checkpoint=folder)
  config.json     the resolved configuration, feature constants included (acting needs no dataset)
  checkpoint.pt   last state (weights, optimiser, position in the epoch): `--resume` reads it
  best.pt         weights with the lowest validation loss: what `from_run` loads
  losses.csv      one row per epoch; curves.png plots it
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
from pathlib import Path
from typing import Any

from echo_data.dataset.writer import atomic_write_bytes, atomic_write_json

CONFIG = "config.json"
POLICY = "policy.json"
AGENT = "agent.json"
CHECKPOINT = "checkpoint.pt"
BEST = "best.pt"
LOSSES = "losses.csv"
CURVES = "curves.png"


class RunError(ValueError):
    """A run folder that cannot be used as asked (one line, names the file)."""


def save_torch(path: Path, obj: Any) -> None:
    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_torch(path: Path) -> Any:
    import torch

    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except (OSError, RuntimeError, EOFError) as e:
        raise RunError(f"{path}: cannot read checkpoint ({e})") from None


def read_json(path: Path) -> dict[str, Any]:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise RunError(f"{path}: missing (not a training run folder?)") from None
    except ValueError as e:
        raise RunError(f"{path}: not valid JSON ({e})") from None


def write_run_files(folder: Path, kind: str, cls: str, config: dict[str, Any], extra: dict[str, Any] | None = None) -> None:
    """config.json, policy.json and agent.json."""
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_json(folder / CONFIG, config)
    atomic_write_json(folder / POLICY, {"kind": kind, "class": cls, **(extra or {})})
    atomic_write_json(folder / AGENT, {"class": cls, "kwargs": {}})


def write_losses(folder: Path, rows: list[dict[str, Any]]) -> None:
    """losses.csv from the per-epoch history, and curves.png of its loss columns."""
    if not rows:
        return
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write_bytes(folder / LOSSES, buf.getvalue().encode())
    _plot(folder / CURVES, rows)


def _plot(path: Path, rows: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
    x = [r["step"] for r in rows]
    for key in (k for k in rows[0] if k.endswith("loss")):
        ys = [r[key] for r in rows]
        if all(y == "" or y is None for y in ys):
            continue
        ax.plot(x, [float("nan") if y in ("", None) else y for y in ys], marker="o", ms=3, label=key)
    ax.set_xlabel("optimiser step")
    ax.set_ylabel("loss")
    ax.set_yscale("log")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def check_same_run(folder: Path, given: dict[str, Any], saved: dict[str, Any], keys: tuple[str, ...]) -> None:
    """A resumed run must be the run that was started: the arguments that define it (data, inputs,
    seed...) must equal the saved config's, or the checkpoint would be continued on other data."""
    for key in keys:
        mine, theirs = given[key], saved[key]
        if key == "dataset":
            mine, theirs = str(Path(mine).resolve()), str(Path(theirs).resolve())
        if isinstance(mine, (list, tuple)) and isinstance(theirs, (list, tuple)):
            mine, theirs = list(mine), list(theirs)
        if mine != theirs:
            raise RunError(f"{folder / CONFIG}: {key} is {theirs!r}, not {mine!r}; resume with the same arguments")


def check_out(folder: Path, resume: bool, overwrite: bool) -> None:
    """Refuse to mix runs: a new run needs an empty or absent folder (or --overwrite)."""
    if resume and overwrite:
        raise RunError("--resume and --overwrite exclude each other")
    if folder.exists() and not folder.is_dir():
        raise RunError(f"--out {folder}: exists and is not a folder")
    if resume:
        if not (folder / CHECKPOINT).is_file():
            raise RunError(f"{folder / CHECKPOINT}: nothing to resume")
        return
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise RunError(f"--out {folder}: not empty; pass --resume to continue it or --overwrite to replace it")
    if overwrite and folder.is_dir():
        for name in (CONFIG, POLICY, AGENT, CHECKPOINT, BEST, LOSSES, CURVES, "eval.json"):
            if (folder / name).exists():
                os.remove(folder / name)
        if (folder / "select").is_dir():  # learn.select's scored weights
            shutil.rmtree(folder / "select")
