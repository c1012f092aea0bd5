"""Damaged inputs: `export`, `view` and `train` on a dataset with a truncated shard or a missing
WAV say which file is damaged (validate's own checks) in one line, exit 2, and write nothing."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from support.optional import cli_param
from support.synth import build_synth, damageable_copy
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.validate import validate


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("damaged") / "synth", {"train": 2, "test": 1})


def _truncate_shard(ds: Path) -> str:
    shard = sorted((ds / "data").glob("train-*.parquet"))[0]
    shard.write_bytes(shard.read_bytes()[:-100])
    return f"data/{shard.name}: sha256 differs"


def _remove_wav(ds: Path) -> str:
    wav = ds / "audio" / "train" / "train-000000.wav"
    wav.unlink()
    return "missing audio/train/train-000000.wav"


DAMAGE: dict[str, Callable[[Path], str]] = {"truncated shard": _truncate_shard, "missing wav": _remove_wav}
COMMANDS = {
    "export": ["export", "{ds}", "--out", "{out}/export"],
    "view": ["view", "{ds}", "--episode", "0", "--out", "{out}/ep.mp4"],
    "train bc": ["train", "bc", "{ds}", "--skill", "Navigate", "--inputs", "state", "--out", "{out}/run", "--no-progress"],
    "train planner": ["train", "planner", "{ds}", "--out", "{out}/run", "--no-progress"],
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
@pytest.mark.parametrize("command", [cli_param(c, COMMANDS[c]) for c in sorted(COMMANDS)])
def test_damaged_dataset_is_one_line_naming_the_file(damage: str, command: str, pristine: Path, tmp_path: Path) -> None:
    ds = damageable_copy(pristine, tmp_path)
    says = DAMAGE[damage](ds)
    assert any(says in p for p in validate(ds))  # the same words validate uses
    out = tmp_path / "out"
    r = CliRunner().invoke(app, [a.format(ds=ds, out=out) for a in COMMANDS[command]])
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert r.exit_code == 2 and len(err) == 1, r.output
    assert says in err[0] and "Traceback" not in r.output, err[0]
    assert not out.exists()


@pytest.mark.parametrize("command", [cli_param(c, COMMANDS[c]) for c in sorted(COMMANDS)])
def test_unfinished_build_says_so_and_how_to_finish_it(command: str, pristine: Path, tmp_path: Path) -> None:
    """A build stopped before its end (no meta/episodes.parquet yet) is not damaged: the one line
    says it is unfinished and that `build --resume` finishes it."""
    import json

    ds = damageable_copy(pristine, tmp_path)
    manifest = json.loads((ds / "manifest.json").read_text())
    (ds / "manifest.json").write_text(json.dumps({**manifest, "complete": False}))
    (ds / "meta" / "episodes.parquet").unlink()
    out = tmp_path / "out"
    r = CliRunner().invoke(app, [a.format(ds=ds, out=out) for a in COMMANDS[command]])
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert r.exit_code == 2 and len(err) == 1, r.output
    assert "unfinished build" in err[0] and "echo-data build" in err[0] and "--resume" in err[0], err[0]
    assert "damaged" not in err[0] and "Traceback" not in r.output
    assert not out.exists()
