"""The `echo-data` command line: a thin layer over the library modules."""

from __future__ import annotations

import json

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Training data for sound-triggered mobile manipulation.")


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


if __name__ == "__main__":
    app()
