"""The files of a training run folder, each written atomically (a crash leaves the old file).

runs/NAME/
  policy.json     {"kind": "policy" | "planner", "class": "module:Class", ...}: the run's kind
  agent.json      {"class": "module:Class", "kwargs": {}}: an evaluate checkpoint folder, built as
                  Class(checkpoint=folder)
  config.json     the resolved configuration, feature constants included (acting needs no dataset)
  checkpoint.pt   last state (weights, optimiser, position in the epoch): `--resume` reads it
  best.pt         weights with the lowest validation loss: what `from_run` loads
  losses.csv      one row per epoch; curves.png plots it
  eval.json       the run's validation figures (training never reads the test split); dagger.csv: DAgger's rounds
  test.json       the planner's test-split scores, written only by `echo-data evaluate-planner RUN`
  select/         closed-loop selection's scored weights, each a run folder (+ scored.json: the recipe and val episodes scored)
  .echo-data.json the marker (dataset/written.py): kind "run" and every file the run wrote

Every file goes through the writers here, which add its name to the marker before writing it, so
`--overwrite` deletes exactly what runs wrote (a killed write's temporary sibling included) and
refuses a folder without the marker or holding anything else, touching nothing. Run folders from
before the marker are recognised by their policy.json and the file names runs have always had.
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from echo_data.dataset.storage import atomic_write_bytes, canonical_json
from echo_data.dataset.written import NotWrittenByUs, all_files, read_marker, remove_written, write_marker, written_files

CONFIG = "config.json"
POLICY = "policy.json"
AGENT = "agent.json"
CHECKPOINT = "checkpoint.pt"
BEST = "best.pt"
WEIGHTS = "weights.safetensors"  # a reference learner's weights, in place of best.pt (echo_data.learn.reference)
LOSSES = "losses.csv"
CURVES = "curves.png"
EVAL = "eval.json"
TEST = "test.json"
DAGGER_LOG = "dagger.csv"
SELECT_DIR = "select"  # select/scored-NNN: the weights scored at the N-th selection, each a run folder
RUN = "run"  # the marker's kind
RUN_FORMAT = "echo-data-run/1"
_BEFORE_MARKER = re.compile(  # every file a run folder held before the marker existed
    rf"(?:{SELECT_DIR}/scored-\d+/)?(?:config|policy|agent)\.json|(?:{SELECT_DIR}/scored-\d+/)?(?:checkpoint|best)\.pt"
    r"|losses\.csv|curves\.png|eval\.json|dagger\.csv"
    r"|summary\.json|command\.txt"  # what the ablation, paper-table and planner study drivers put beside a run then
)


POLICY_CLASS = "echo_data.learn.policy:SkillPolicy"  # the class a skill-policy run names (agent.json)


class RunError(ValueError):
    """A run folder that cannot be used as asked (one line, names the file)."""


def _note(run: Path, rel: str) -> None:
    """Add `rel` to the file list of the run folder `run`'s marker, before the file is written."""
    marker = read_marker(run)
    if marker is not None and marker["kind"] != RUN:
        raise RunError(f"{run}: holds an echo-data {marker['kind']}, not a training run")
    files = marker.get("files") if marker is not None else None
    listed = [f for f in files if isinstance(f, str)] if isinstance(files, list) else []
    if rel not in listed:
        run.mkdir(parents=True, exist_ok=True)
        write_marker(run, RUN, RUN_FORMAT, [*listed, rel])


def write_file(run: Path, rel: str, data: bytes) -> None:
    """`run/rel`, written atomically (a crash or a full disk leaves the old file or none) and
    listed in the run's marker: the one way a file enters a run folder."""
    _note(run, rel)
    (run / rel).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(run / rel, data)


def write_json(run: Path, rel: str, obj: Any) -> None:
    write_file(run, rel, canonical_json(obj))


def save_torch(run: Path, rel: str, obj: Any) -> None:
    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    write_file(run, rel, buf.getvalue())


def load_torch(path: Path) -> Any:
    import torch

    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except (OSError, RuntimeError, EOFError) as e:
        raise RunError(f"{path}: cannot read checkpoint ({e})") from None


def load_weights(folder: Path) -> tuple[dict[str, Any], Path]:
    """(state dict, the file it came from) a policy acts with: a reference learner's
    weights.safetensors (fp16 tensors widened to fp32, the dtype the model computes in), else
    the run's best.pt, else its last checkpoint.pt."""
    if (folder / WEIGHTS).is_file():
        from safetensors import SafetensorError
        from safetensors.torch import load_file

        try:
            state = load_file(str(folder / WEIGHTS))
        except (OSError, SafetensorError) as e:
            raise RunError(f"{folder / WEIGHTS}: cannot read weights ({e})") from None
        return {k: v.float() if v.is_floating_point() else v for k, v in state.items()}, folder / WEIGHTS
    path = folder / BEST if (folder / BEST).is_file() else folder / CHECKPOINT
    return load_torch(path)["model"], path


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes: the identity of the weights an evaluation acted with."""
    import hashlib

    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_json(path: Path) -> dict[str, Any]:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise RunError(f"{path}: missing (not a training run folder?)") from None
    except ValueError as e:
        raise RunError(f"{path}: not valid JSON ({e})") from None


def write_run_files(run: Path, kind: str, cls: str, config: dict[str, Any], extra: dict[str, Any] | None = None, at: str = "") -> None:
    """config.json, policy.json and agent.json of the run `run` (of its sub-folder `at`)."""
    sub = f"{at}/" if at else ""
    write_json(run, sub + CONFIG, config)
    write_json(run, sub + POLICY, {"kind": kind, "class": cls, **(extra or {})})
    write_json(run, sub + AGENT, {"class": cls, "kwargs": {}})


def write_losses(folder: Path, rows: list[dict[str, Any]]) -> None:
    """losses.csv from the per-epoch history, and curves.png of its loss columns."""
    if not rows:
        return
    buf = io.StringIO()
    names = list(dict.fromkeys(k for r in rows for k in r))  # a column only some epochs carry (a STOP run's chosen threshold) too
    w = csv.DictWriter(buf, fieldnames=names, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    write_file(folder, LOSSES, buf.getvalue().encode())
    write_file(folder, CURVES, _plot(rows))


def _plot(rows: list[dict[str, Any]]) -> bytes:
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
    return buf.getvalue()


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
    """Refuse to mix runs: a new run needs an empty or absent folder, or --overwrite of a run
    folder holding only what runs wrote (then removed by the marker's list, never rmtree)."""
    if resume and overwrite:
        raise RunError("--resume and --overwrite exclude each other")
    if folder.exists() and not folder.is_dir():
        raise RunError(f"--out {folder}: exists and is not a folder")
    if resume:
        if not (folder / CHECKPOINT).is_file():
            raise RunError(f"{folder / CHECKPOINT}: nothing to resume")
        marker = read_marker(folder)
        if marker is not None and marker["kind"] != RUN:
            raise RunError(f"--out {folder}: holds an echo-data {marker['kind']}, not a training run")
        adopt(folder)
        return
    if folder.is_dir() and any(folder.iterdir()):
        if not overwrite:
            raise RunError(f"--out {folder}: not empty; pass --resume to continue it or --overwrite to replace it")
        try:  # every file is checked before the first is deleted
            files = written_files(folder, RUN, _run_before_marker(folder))
        except NotWrittenByUs as e:
            raise RunError(f"--out {e}") from None
        remove_written(folder, files)


def adopt(folder: Path) -> None:
    """A run folder from before the marker gets one listing its own files (from now on
    `--overwrite` removes them), before anything adds a file to it; a marked folder is left as is."""
    if read_marker(folder) is None:
        write_marker(folder, RUN, RUN_FORMAT, [f for f in all_files(folder) if _BEFORE_MARKER.fullmatch(f)])


def _run_before_marker(folder: Path) -> Callable[[str], bool] | None:
    """For a folder without the marker whose policy.json is an echo-data run's: the names run
    folders held before the marker existed (None: not recognised, refused)."""
    if read_marker(folder) is not None:
        return None
    try:
        policy = json.loads((folder / POLICY).read_bytes().decode("utf-8"))
    except (OSError, ValueError):
        return None
    ours = isinstance(policy, dict) and policy.get("kind") in ("policy", "planner") and str(policy.get("class", "")).startswith("echo_data.learn.")
    return (lambda rel: _BEFORE_MARKER.fullmatch(rel) is not None) if ours else None
