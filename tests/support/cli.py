"""Assertions on the command line's promise: bad input is one `error:` line and exit 2."""

from __future__ import annotations

from typer.testing import CliRunner

from echo_data.cli import app


def one_line_exit_2(args: list[str], *needles: str) -> None:
    """Run `echo-data ARGS`: exit 2 with exactly one `error:` line containing every needle."""
    r = CliRunner().invoke(app, args)
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert r.exit_code == 2 and len(err) == 1, r.output
    for n in needles:
        assert n in err[0], (n, err[0])
