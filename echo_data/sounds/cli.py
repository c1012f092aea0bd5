"""`echo-data sounds`: list the sound instances and export them as WAV files to listen to."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from echo_data.categories import CATEGORIES

if TYPE_CHECKING:
    from echo_data.sounds.library import SoundInstance, SoundLibrary

sounds_app = typer.Typer(add_completion=False, no_args_is_help=True, help="List and export the sound library.")

_CATEGORY = typer.Option(None, "--category", "-c", help=f"Only this category ({', '.join(CATEGORIES)}).")
_SPLIT = typer.Option(None, "--split", "-s", help="Only this split (train or test).")
_RECIPE = typer.Option(None, "--recipe", "-r", help="Use this recipe's sounds (built-ins and/or its WAV folders).")


def _library(recipe: Path | None) -> SoundLibrary:
    from echo_data.recipe import RecipeError, load_recipe
    from echo_data.sounds import SoundLibrary, SoundLibraryError

    try:
        if recipe is None:
            return SoundLibrary.builtin()
        return SoundLibrary.from_recipe(load_recipe(recipe), recipe_dir=recipe.resolve().parent)
    except (RecipeError, SoundLibraryError) as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(2) from None


def _select(lib: SoundLibrary, category: str | None, split: str | None) -> list[SoundInstance]:
    try:
        return lib.instances(category=category, split=split)
    except ValueError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(2) from None


@sounds_app.command("list")
def list_sounds(
    as_json: bool = typer.Option(False, "--json", help="Print a JSON list of {id, category, split, duration, source}."),
    category: str | None = _CATEGORY,
    split: str | None = _SPLIT,
    recipe: Path | None = _RECIPE,
) -> None:
    """Every sound instance with id, category, split, loop duration and source (builtin or file)."""
    items = _select(_library(recipe), category, split)
    if as_json:
        typer.echo(json.dumps([asdict(s) for s in items], indent=1))
        return
    width = max([len(s.id) for s in items] + [2])
    typer.echo(f"{'id':<{width}}  {'category':<8}  {'split':<5}  {'duration':>8}  source")
    for s in items:
        typer.echo(f"{s.id:<{width}}  {s.category:<8}  {s.split:<5}  {s.duration:>7.2f}s  {s.source}")
    typer.echo(f"{len(items)} instances")


@sounds_app.command("export")
def export_sounds(
    out_dir: Path = typer.Argument(..., help="Folder to write <id>.wav files into (created if missing)."),
    category: str | None = _CATEGORY,
    split: str | None = _SPLIT,
    seconds: float = typer.Option(3.0, "--seconds", min=0.01, max=600.0, help="Length of each file (the loop repeated)."),
    sample_rate: int = typer.Option(16000, "--sample-rate", min=8000, max=96000, help="Sample rate of the files."),
    recipe: Path | None = _RECIPE,
) -> None:
    """Write the dry instances as 16-bit WAV files so a person can listen to them."""
    import soundfile as sf

    lib = _library(recipe)
    items = _select(lib, category, split)
    from echo_data.outputs import OutputError, check_output_path

    try:
        check_output_path(out_dir)
    except OutputError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(2) from None
    created = not out_dir.exists()
    name = out_dir
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        for s in items:
            x = lib.waveform(s.id, sample_rate=sample_rate, seconds=seconds)
            name = out_dir / f"{s.id}.wav"
            tmp = out_dir / f".{s.id}.wav.tmp"
            try:
                sf.write(str(tmp), x, sample_rate, subtype="PCM_16", format="WAV")
                tmp.replace(out_dir / f"{s.id}.wav")
            finally:
                tmp.unlink(missing_ok=True)
    except (OSError, RuntimeError) as e:  # soundfile reports a failed open as a RuntimeError (LibsndfileError)
        if created and out_dir.is_dir() and not any(out_dir.iterdir()):  # leave no empty folder behind
            out_dir.rmdir()
        typer.echo(f"error: {out_dir}: cannot write {name} ({getattr(e, 'strerror', None) or ' '.join(str(e).split())})", err=True)
        raise typer.Exit(2) from None
    typer.echo(f"wrote {len(items)} files to {out_dir}")
