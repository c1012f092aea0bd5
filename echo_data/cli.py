"""The `echo-data` command line: a thin layer over the library modules."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING

import typer

if TYPE_CHECKING:
    from echo_data.app.trial import TrialEpisode
    from echo_data.recipe import Recipe

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Training data for sound-triggered mobile manipulation.")

from echo_data.sounds.cli import sounds_app  # noqa: E402

app.add_typer(sounds_app, name="sounds")

from echo_data.agents.runtime import DRIVE_ENDS  # noqa: E402
from echo_data.learn.cli import evaluate_planner_cmd, train_app  # noqa: E402

app.add_typer(train_app, name="train")

from echo_data.learn.reference_cli import reference_app  # noqa: E402

app.add_typer(reference_app, name="reference")


@app.command()
def version() -> None:
    """Print the echo-data version."""
    from echo_data import __version__

    typer.echo(__version__)


@app.command()
def doctor(as_json: bool = typer.Option(False, "--json", help="Print one JSON object.")) -> None:
    """Versions, the rendering device SAPIEN finds, and the fix when rendering is impossible."""
    from dataclasses import asdict

    from echo_data.doctor import run_doctor

    rep = run_doctor()
    if as_json:
        typer.echo(json.dumps(asdict(rep), indent=2))
    else:
        for k, v in {**rep.versions, **rep.optional}.items():
            typer.echo(f"{k:16s} {v}")
        typer.echo(f"{'render device':16s} {rep.device or 'none'}")
        for p in rep.problems:
            typer.echo(f"problem: {p}", err=True)
        typer.echo("ok: this machine can build echo-data datasets" if not rep.problems else "not ok")
    raise typer.Exit(1 if rep.problems else 0)


def _load(recipe_path: Path) -> Recipe:
    """Load a recipe or exit 2 with its one-line error."""
    from echo_data.recipe import RecipeError, load_recipe

    try:
        return load_recipe(recipe_path)
    except RecipeError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(2) from None


def _check_sounds(recipe: Recipe, recipe_path: Path) -> None:
    """An unusable sound folder (unreadable, silent or NaN file; no sound for a split) is one
    line and exit 2 before any episode, as in `build` and `evaluate`."""
    from echo_data.sounds import SoundLibrary, SoundLibraryError

    try:
        SoundLibrary.from_recipe(recipe, recipe_path.resolve().parent).check_covers(recipe)
    except SoundLibraryError as e:
        typer.echo(f"error: {str(e).splitlines()[0]}", err=True)
        raise typer.Exit(2) from None


@app.command()
def trial(
    recipe_path: Path = typer.Argument(..., metavar="RECIPE", help="Recipe YAML."),
    n: int = typer.Option(10, "-n", min=1, help="Episodes to run (train split indices 0..n-1)."),
    seed: int | None = typer.Option(None, "--seed", min=0, help="Replace the recipe's seed."),
    workers: int = typer.Option(1, "--workers", min=1, help="Worker processes."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Run N episodes without writing a dataset; report success per episode and per skill."""
    from dataclasses import asdict

    from echo_data.app.trial import run_trial

    recipe = _load(recipe_path)
    if seed is not None:
        recipe = recipe.model_copy(update={"seed": seed})
    _check_sounds(recipe, recipe_path)

    def tick(e: TrialEpisode) -> None:
        if not as_json:
            status = "ok" if e.success else "FAILED " + "; ".join(f"{s}: {r}" for s, ok, r in e.outcomes if not ok) + e.error
            typer.echo(f"episode {e.index:4d} {e.setting:18s} steps {e.steps:4d} {e.seconds:6.1f}s {status}", err=True)

    rep = run_trial(recipe, recipe_path.resolve().parent, n, workers=workers, progress=tick)
    if as_json:
        d = asdict(rep)
        typer.echo(json.dumps(d, indent=2))
    else:
        typer.echo(f"episodes {rep.episodes}  success rate {rep.success_rate:.3f}")
        for k, v in rep.skills.items():
            typer.echo(f"  {k:10s} {v['successes']}/{v['attempts']}")
        for k, count in rep.failures.items():
            typer.echo(f"  failure  {k}: {count}")
        typer.echo(f"  rejected {rep.rejected}")
        typer.echo(f"  {rep.seconds_per_episode:.1f} s/episode, {rep.steps_per_second:.1f} steps/s")


@app.command()
def preview(
    recipe_path: Path = typer.Argument(..., metavar="RECIPE", help="Recipe YAML."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of the previewed episode (replaces the recipe's)."),
    out: Path = typer.Option(Path("preview"), "--out", help="Folder for the pictures and sound."),
) -> None:
    """Write one episode's spec, top-down plan, first head frame, a contact sheet of head frames every 2 s, heard audio and acoustic map."""
    from echo_data.dataset.written import NotWrittenByUs
    from echo_data.outputs import OutputError, check_output_path
    from echo_data.preview import PREVIEW_STAGES, check_preview_out, write_preview

    recipe = _load(recipe_path)
    try:  # before minutes of simulation: a file, a read-only or too long path, a folder of other files is refused now
        check_output_path(out)
        check_preview_out(out)
    except (OutputError, NotWrittenByUs) as e:
        typer.echo(f"error: --out {e}", err=True)
        raise typer.Exit(2) from None
    _check_sounds(recipe, recipe_path)
    from tqdm.auto import tqdm

    try:
        # disable=None: no bar when stderr is no terminal (logs, pipes)
        with tqdm(total=PREVIEW_STAGES, unit="stage", desc="preview", dynamic_ncols=True, leave=False, disable=None) as bar:

            def stage(name: str) -> None:
                bar.set_postfix_str(name, refresh=False)
                bar.update(1)

            summary = write_preview(recipe, recipe_path.resolve().parent, seed, out, progress=stage, note=bar.set_postfix_str)
    except NotWrittenByUs as e:  # files put there while it ran
        typer.echo(f"error: --out {e}", err=True)
        raise typer.Exit(2) from None
    except OSError as e:  # a writer that names no file (matplotlib, soundfile) on a full disk too
        from echo_data.targets import write_failed

        typer.echo(f"error: {write_failed('--out', out, e)}", err=True)
        raise typer.Exit(2) from None
    # one line: the whole spec is in episode.json
    chain = summary["chain"]
    assert isinstance(chain, list)
    typer.echo(
        f"{summary['setting']} seed {seed}: {' -> '.join(map(str, chain))} "
        f"{'succeeded' if summary['success'] else 'failed'} in {summary['steps']} steps (the whole episode: {out / 'episode.json'})"
    )
    typer.echo(f"wrote {', '.join(sorted(p.name for p in out.iterdir() if not p.name.startswith('.')))} to {out}")


# `--drive-end`'s choices, from their one owner (typer takes choices as an Enum).
DriveEnd = Enum("DriveEnd", {v: v for v in DRIVE_ENDS}, type=str)  # type: ignore[misc]


@app.command()
def evaluate(
    recipe_path: Path = typer.Argument(..., metavar="RECIPE", help="Recipe YAML (its episodes, split sizes and budgets)."),
    split: str = typer.Option("test", "--split", help="Split to evaluate on."),
    n: int = typer.Option(30, "-n", min=1, help="Episodes: indices 0..n-1 of the split."),
    policy: list[str] = typer.Option(
        ["oracle"], "--policy",
        help="Skill policy: oracle | random | still | reference (the shipped learners; SKILL=reference:NAME a listed one) | module:Class | checkpoint folder; repeat as SKILL=POLICY for one per skill "
        "(e.g. --policy Navigate=runs/nav --policy oracle: skills not named use the plain one, default oracle).",
    ),
    planner: str = typer.Option("oracle", "--planner", help="Planner: oracle | reference (the shipped one; reference:NAME a listed one) | module:Class | checkpoint folder."),
    workers: int = typer.Option(1, "--workers", min=1, help="Worker processes."),
    json_out: Path | None = typer.Option(None, "--json", help="Write the results (metrics, per-episode outcomes) here."),
    video: Path | None = typer.Option(None, "--video", help="Write one MP4 per episode (picture + binaural sound) into this folder."),
    resume: bool = typer.Option(False, "--resume", help="Continue an interrupted evaluation from the episodes recorded next to --json (OUT.episodes.jsonl)."),
    drive_end: DriveEnd = typer.Option(
        "handover", "--drive-end",
        help="How a learned Navigate that does not STOP ends: handover (the first step inside the next skill's stance, docs/handover.md) | "
        "centre (on until it stands in the stance's centre) | success (the first step inside the paper's 1.5 m success region)."),
) -> None:
    """Run a policy closed-loop on a split and report the paper's metrics with 95 % intervals."""
    from echo_data.evaluation.cli import run_evaluate

    code = run_evaluate(_load(recipe_path), recipe_path, split, n, tuple(policy), planner, workers, json_out, video, resume, drive_end.value)
    raise typer.Exit(code)


app.command("evaluate-planner")(evaluate_planner_cmd)  # beside evaluate: the planner alone, open loop on the test split

# Dataset commands (build, validate, info) live in echo_data.app.commands.
from echo_data.app.commands import register as _register_dataset_commands  # noqa: E402

_register_dataset_commands(app)


def _is(e: BaseException, name: str) -> bool:
    """Match click's exceptions by class name: typer vendors its own copy of click."""
    return any(c.__name__ == name for c in type(e).__mro__)


def main() -> None:
    """The `echo-data` entry point: the app, with usage errors as the README promises them:
    one line naming the command and the argument, exit 2 (not click's multi-line usage box)."""
    import sys

    try:
        code = app(standalone_mode=False)
    except Exception as e:
        if _is(e, "NoArgsIsHelpError"):  # `echo-data build` alone: show its help
            ctx = getattr(e, "ctx", None)
            typer.echo(ctx.get_help() if ctx is not None else str(e))
            code = 0
        elif _is(e, "UsageError"):
            ctx = getattr(e, "ctx", None)
            where = ctx.command_path if ctx is not None else "echo-data"
            typer.echo(f"error: {where}: {' '.join(e.format_message().split())}", err=True)  # type: ignore[attr-defined]
            code = 2
        elif _is(e, "Abort"):
            typer.echo("aborted", err=True)
            code = 130
        else:
            raise
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
