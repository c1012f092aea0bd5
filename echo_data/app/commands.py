"""CLI commands for the dataset (`build`, `validate`, `info`), thin wrappers for typer.

Each maps errors to one line on stderr and an exit code: 2 for bad input (recipe, output path,
mode, not a dataset), 1 for a build that could not finish or a dataset with problems.
Register them with `register(app)` or `app.command("build")(build_cmd)`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer


def _fail(message: str, code: int) -> typer.Exit:
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(code)


def build_cmd(
    recipe: Annotated[Path, typer.Argument(help="Recipe YAML file.")],
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Dataset folder (default: out/<recipe name>).")] = None,
    workers: Annotated[int | None, typer.Option("--workers", "-w", help="Parallel episode workers (default: the usable CPU cores).")] = None,
    limit: Annotated[int | None, typer.Option("--limit", help="At most N episodes per split (quick runs).")] = None,
    split: Annotated[list[str] | None, typer.Option("--split", help="Build only this split (repeat for several; default all). Evaluation needs no built test split.")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Continue an interrupted build.")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing dataset.")] = False,
    executor: Annotated[str, typer.Option("--executor", help="local (process pool) or ray.")] = "local",
    address: Annotated[str | None, typer.Option("--address", help="Ray cluster address (host:port, as `ray start --head` prints); with --executor ray.")] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Show a progress bar.")] = True,
    handover_from: Annotated[Path | None, typer.Option("--handover-from", help="An `evaluate --split train --json RUN` output (or its journal): the Navigate expert stops where that learner's drives ended, so the next skill is taught from its hand-overs (docs/handover.md).")] = None,
) -> None:
    """Build the dataset of a recipe: Parquet + WAV shards, manifest, stats, planner export."""
    from echo_data.app.build import BuildError, OutputError, build
    from echo_data.recipe import RecipeError, load_recipe

    if resume and overwrite:
        raise _fail("--resume and --overwrite exclude each other", 2)
    try:
        r = load_recipe(recipe)
    except RecipeError as e:
        raise _fail(str(e), 2) from None
    mode = "resume" if resume else "overwrite" if overwrite else "new"
    if workers is None:
        from echo_data.app.executors import default_workers

        workers = default_workers()
    try:
        summary = build(r, recipe, out if out is not None else Path("out") / r.name, workers=workers, limit=limit, mode=mode, executor=executor, progress=progress, address=address, only=split or None, handover_from=handover_from)  # type: ignore[arg-type]
    except OutputError as e:
        raise _fail(str(e), 2) from None
    except BuildError as e:
        raise _fail(str(e), 1) from None
    typer.echo(str(summary))


def validate_cmd(path: Annotated[Path, typer.Argument(help="Dataset directory (out/<name>).")]) -> None:
    """Check every shard, WAV, index and metadata file of a dataset against its manifest."""
    from echo_data.dataset.manifest import ManifestError
    from echo_data.dataset.reader import is_dataset, read_manifest
    from echo_data.dataset.validate import validate

    if not is_dataset(path):
        raise _fail(f"{path}: not an echo-data dataset (no manifest.json)", 2)
    try:  # a manifest that cannot be read is bad input (one line, exit 2), as a missing one is
        read_manifest(path)
    except ManifestError as e:
        raise _fail(str(e), 2) from None
    with _episode_bar(path, "validate", unit="shard") as bar:
        problems = validate(path, progress=bar.update)
    for p in problems:
        typer.echo(p)
    if problems:
        raise _fail(f"{path}: {len(problems)} problem(s)", 1)
    typer.echo(f"ok: {path}")


def info_cmd(
    path: Annotated[Path, typer.Argument(help="Dataset directory (out/<name>).")],
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
) -> None:
    """Episodes, steps, settings, skills, rejections and size of a dataset (refreshes its README.md card)."""
    from echo_data.dataset.card import write_card
    from echo_data.dataset.info import format_info, info
    from echo_data.dataset.manifest import ManifestError

    try:
        d = info(path)
    except ManifestError as e:
        raise _fail(str(e), 2) from None
    if d["complete"]:
        try:
            write_card(path)
        except OSError as e:  # a read-only copy still gets its summary
            typer.echo(f"warning: {path}/README.md not refreshed ({e.strerror or e})", err=True)
    typer.echo(json.dumps(d, indent=1, sort_keys=True) if as_json else format_info(d))


# Export formats: name -> (module, function). A function takes (source dataset, output folder,
# overwrite=) and returns the export's info (`codebase_version`, `total_episodes`, `total_frames`,
# `splits`); it raises an error with one line for bad input. docs/adding_an_export_format.md.
EXPORT_FORMATS: dict[str, tuple[str, str]] = {
    "lerobot": ("echo_data.dataset.lerobot", "export_lerobot"),
    "robomimic": ("echo_data.dataset.robomimic", "export_robomimic"),
    "zarr": ("echo_data.dataset.zarr_export", "export_zarr"),
}


def _episode_bar(path: Path, desc: str, split: str | None = None, unit: str = "ep") -> Any:
    """A progress bar over the episodes (or, unit "shard", the shards) of the dataset at `path`
    (or of its `split`), counted by its manifest; a bar without a total when it cannot be read."""
    from tqdm.auto import tqdm

    from echo_data.dataset.manifest import ManifestError
    from echo_data.dataset.reader import read_manifest

    try:
        m = read_manifest(path)
    except ManifestError:
        m = {}
    if unit == "shard":
        total = len(m.get("shards", [])) or None
    else:
        counts = m.get("counts", {}).get("episodes", {})
        total = (counts.get(split, 0) if split is not None else sum(counts.values())) or None
    return tqdm(total=total, unit=unit, desc=desc, dynamic_ncols=True, leave=False, disable=None)  # none when stderr is no terminal (logs, pipes)


def export_cmd(
    path: Annotated[Path, typer.Argument(help="Dataset directory (out/<name>).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Export: a folder (lerobot, zarr) or an .hdf5 file (robomimic).")],
    fmt: Annotated[str, typer.Option("--format", help=f"Target format: {', '.join(EXPORT_FORMATS)} (LeRobot v3.0, robomimic HDF5, Diffusion Policy Zarr).")] = "lerobot",
    video: Annotated[list[str] | None, typer.Option("--video", help="lerobot: store this camera as an MP4 video feature (rgb), a keyframe every 2 frames.")] = None,
    split: Annotated[str | None, typer.Option("--split", help="Export this split only (train, val, test; lerobot: default train, as lerobot-train reads every episode of a folder): Diffusion Policy draws validation from every episode it is given.")] = None,
    next_obs: Annotated[bool, typer.Option("--next-obs", help="robomimic: also write next_obs/ (offline RL needs it; BC does not).")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing export.")] = False,
) -> None:
    """Write the dataset in another library's format (LeRobot v3.0, robomimic HDF5, Zarr), next to the original."""
    import importlib

    from echo_data.dataset.manifest import ManifestError
    from echo_data.dataset.validate import DamagedDataset, check_whole
    from echo_data.targets import TargetError, check_file, check_folder, write_failed

    if fmt not in EXPORT_FORMATS:
        raise _fail(f"--format {fmt}: unknown format (use {', '.join(EXPORT_FORMATS)})", 2)
    if video and fmt != "lerobot":
        raise _fail(f"--video: only the lerobot format stores videos, not {fmt}", 2)
    if next_obs and fmt != "robomimic":
        raise _fail(f"--next-obs: only the robomimic format has next_obs, not {fmt}", 2)
    module, name = EXPORT_FORMATS[fmt]
    mod = importlib.import_module(module)
    options: dict[str, Any] = {"video": tuple(video)} if video else {}
    options |= ({"split": split} if split is not None else {}) | ({"next_obs": True} if next_obs else {})
    try:
        (check_folder if out.is_dir() or not out.suffix else check_file)(out, "--out")  # robomimic writes one .hdf5 file
        check_whole(path)
        with _episode_bar(path, f"export {fmt}", split) as bar:
            info = getattr(mod, name)(path, out, overwrite=overwrite, progress=bar.update, **options)
    except (mod.ExportError, TargetError, ManifestError, DamagedDataset) as e:
        raise _fail(str(e), 2) from None
    except OSError as e:
        raise _fail(write_failed("--out", out, e), 2) from None
    typer.echo(f"{out}: {fmt} {info['codebase_version']}, {info['total_episodes']} episodes, {info['total_frames']} frames, splits {info['splits']}")
    for note in info.get("notes", []):  # what a user must know about the written numbers (e.g. clipped actions)
        typer.echo(note)


def view_cmd(
    path: Annotated[Path, typer.Argument(help="Dataset directory (out/<name>).")],
    episode: Annotated[int, typer.Option("--episode", "-e", help="Episode index within the split.")] = 0,
    split: Annotated[str, typer.Option("--split", help="Split of the episode.")] = "train",
    out: Annotated[Path | None, typer.Option("--out", "-o", help="MP4 to write (default: <split>-<episode>.mp4 here, unless --rerun alone is given).")] = None,
    rerun: Annotated[Path | None, typer.Option("--rerun", help="Also (or, without --out, only) write a Rerun recording (.rrd) to scrub through with `rerun FILE.rrd`.")] = None,
) -> None:
    """Write an MP4 of one episode (head RGB, head and wrist depth, top-down map, scrolling binaural
    spectrogram, the active skill, the sound at a stated listening gain) and/or a Rerun recording."""
    from echo_data.dataset.manifest import ManifestError
    from echo_data.dataset.validate import DamagedDataset, check_whole
    from echo_data.targets import TargetError, check_file, write_failed
    from echo_data.view import ViewError, render_episode_video
    from echo_data.viz.recording import RecordingTargetError, check_rerun_target, write_recording

    target = out if out is not None else (Path(f"{split}-{episode:06d}.mp4") if rerun is None else None)
    writing: tuple[str, Path] | None = None  # the option and file being written when an OSError comes
    try:
        if target is not None:
            check_file(target, "--out")
        if rerun is not None:
            check_rerun_target(rerun)
        check_whole(path, split, episode)
        if target is not None:
            writing = ("--out", target)
            summary = render_episode_video(path, episode, target, split=split)
            typer.echo(f"wrote {summary['path']}: {summary['frames']} frames, {summary['seconds']:.1f} s with binaural sound ({summary['listening']})")
        if rerun is not None:
            writing = ("--rerun", rerun)
            rec = write_recording(path, episode, rerun, split=split)
            typer.echo(f"wrote {rec['path']}: {rec['steps']} steps, cameras {', '.join(rec['cameras'])} (open it with `rerun {rec['path']}`)")
    except (ManifestError, ViewError, RecordingTargetError, TargetError, DamagedDataset) as e:
        raise _fail(str(e), 2) from None
    except OSError as e:
        if writing is None:
            raise
        raise _fail(write_failed(writing[0], writing[1], e), 2) from None


def register(app: typer.Typer) -> None:
    """Add `build`, `validate`, `info` and `export` to an app."""
    app.command("build")(build_cmd)
    app.command("validate")(validate_cmd)
    app.command("info")(info_cmd)
    app.command("export")(export_cmd)
    app.command("view")(view_cmd)
