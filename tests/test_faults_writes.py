"""Write errors are one line naming the option, exit 2, before any work: `export --out`,
`view --out` and `train --out` into a place that cannot be written (`evaluate --video` and
`--json`: `test_faults_evaluate`)."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.cli import one_line_exit_2
from support.optional import cli_param
from support.synth import build_synth

RO = Path("/sys/echo-data-test")  # not writable, even for root


@pytest.fixture(scope="module")
def ds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("writes") / "synth", {"train": 2, "test": 1})


@pytest.mark.parametrize("command", [cli_param(c, c) for c in [
    ["export", "{ds}", "--out", "{ro}/export"],
    ["export", "{ds}", "--format", "zarr", "--out", "{ro}/export"],
    ["export", "{ds}", "--format", "robomimic", "--out", "{ro}/export.hdf5"],
    ["view", "{ds}", "--out", "{ro}/ep.mp4"],
    ["train", "bc", "{ds}", "--skill", "Navigate", "--inputs", "state", "--out", "{ro}/run", "--no-progress"],
    ["train", "planner", "{ds}", "--out", "{ro}/run", "--no-progress"],
]])
def test_output_that_cannot_be_written_is_one_line_exit_2(command: list[str], ds: Path) -> None:
    args = [a.format(ds=ds, ro=RO) for a in command]
    one_line_exit_2(args, "--out", "not writable")


def test_view_out_that_is_a_file_inside_a_file(ds: Path, tmp_path: Path) -> None:
    f = tmp_path / "f"
    f.write_text("x")
    one_line_exit_2(["view", str(ds), "--out", str(f / "ep.mp4")], "--out", str(f))
    one_line_exit_2(["export", str(ds), "--out", str(f / "export")], "--out", str(f))
