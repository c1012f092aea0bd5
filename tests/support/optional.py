"""Libraries the test extra installs on one Python and cannot on another: where a test needs one,
it says so here, so that it skips with the reason where the extra leaves the library out and fails
everywhere else (the extra promises it there, and a broken install must not pass as a skip).

torch: the registry's `torch==2.13.0` for Python 3.12 is a CUDA build (several GB); its CPU wheel
exists for 3.11 only, so the test extra installs torch below 3.12 only (pyproject.toml,
docs/SIMULATION_NOTES.md#dependencies). A test module that imports torch at its top imports it
from `support.torch_module` instead; a test that needs it inside (training through `echo-data
train`, a torch reader) carries `@needs_torch`."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Sequence

import pytest

# The first Python each library is left out of the test extra on, and why (pyproject.toml's `test`).
LEFT_OUT_FROM = {"torch": ((3, 12), "the registry's torch==2.13.0 for Python 3.12 is a CUDA build, so the test extra leaves it out")}


def left_out(module: str) -> str | None:
    """Why `module` may be missing here (the reason to skip), or None where its absence is a failure."""
    first, why = LEFT_OUT_FROM[module]
    if sys.version_info[:2] >= first and importlib.util.find_spec(module) is None:
        return f"needs {module}, not installed: {why} (docs/SIMULATION_NOTES.md#dependencies)"
    return None


def needs(module: str) -> pytest.MarkDecorator:
    """A marker: skip where the test extra leaves `module` out and it is missing; run (and fail if it is
    missing) everywhere else."""
    reason = left_out(module)
    return pytest.mark.skipif(reason is not None, reason=reason or "")


needs_torch = needs("torch")


def cli_param(value: object, argv: Sequence[str]) -> object:
    """A parametrize value for the `echo-data` command line `argv`: needs torch where it trains."""
    return pytest.param(value, marks=needs_torch if argv[0] == "train" else ())
