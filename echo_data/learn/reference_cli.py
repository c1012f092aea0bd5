"""`echo-data reference`: make a reference learner from a training run, list the shipped set."""

from __future__ import annotations

import json
from pathlib import Path

import typer

reference_app = typer.Typer(add_completion=False, no_args_is_help=True, help="The shipped reference learners (docs/learners.md#reference-learners-a-row-reproduced-with-no-training).")


def _root(to: Path | None) -> Path:
    from echo_data.learn.reference import reference_dir

    return reference_dir() if to is None else to


@reference_app.command("add")
def add_cmd(
    run: Path = typer.Argument(..., metavar="RUN", help="A training run folder (echo-data train ... --out RUN)."),
    name: str = typer.Option(..., "--name", help="The learner's folder name in the reference set."),
    data: Path | None = typer.Option(None, "--data", help="The dataset the run was trained on (default: the one its config.json names)."),
    to: Path | None = typer.Option(None, "--to", help="The reference set (default: $ECHO_DATA_REFERENCE, else the package's echo_data/reference)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace a learner of the same name."),
    serve: bool = typer.Option(True, "--serve/--variant", help="Serve its skill (or be the planner), or ship it as a variant: --policy SKILL=reference:NAME."),
    join: bool = typer.Option(False, "--join", help="Serve its skill beside the learners already serving it: another training seed of their command (--policy reference shares the episodes out over the seeds)."),
) -> None:
    """Convert RUN's best weights to safetensors (fp16 where its actions do not change), copy its
    config and data recipe, record their SHA-256, and let it serve its skill (or be the planner)."""
    from echo_data.learn.reference import ReferenceError, add
    from echo_data.learn.runs import RunError

    try:
        entry = add(run, name, _root(to), data, overwrite, serve, join)
    except (ReferenceError, RunError) as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(2) from None
    typer.echo(json.dumps(entry, indent=1))


@reference_app.command("list")
def list_cmd(to: Path | None = typer.Option(None, "--to", help="The reference set (default as for add).")) -> None:
    """Which learner serves which skill, the planner, and the shipped weights' size and hashes."""
    from echo_data.learn.reference import ReferenceError, ReferenceSet, shipped_bytes

    try:
        refs = ReferenceSet.load(_root(to))
    except ReferenceError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(2) from None
    from echo_data.skills import EXPERTS

    for who in [*EXPERTS, "planner"]:
        skill = None if who == "planner" else who
        served = ([refs.planner] if refs.planner else []) if skill is None else refs.served(who)
        names = [n for n in refs.of(skill) if n not in served]
        shas = [str(refs.learners[n]["weights_sha256"])[:12] for n in served]
        line = f"{who:<10} {'+'.join(served) or '-'}" + (f"  sha256 {' '.join(shas)}" if served else "")
        typer.echo(line + (f"  variants: {', '.join(names)}" if names else ""))
    typer.echo(f"weights: {shipped_bytes(refs.root) / 2**20:.2f} MB")
