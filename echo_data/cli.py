"""The `echo-data` command line: a thin layer over the library modules."""

from __future__ import annotations

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Training data for sound-triggered mobile manipulation.")


@app.command()
def version() -> None:
    """Print the echo-data version."""
    from echo_data import __version__

    typer.echo(__version__)


if __name__ == "__main__":
    app()
