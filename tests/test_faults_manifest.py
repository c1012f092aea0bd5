"""A damaged manifest (not UTF-8, a value of the wrong type) is one line naming the file and the
key, exit 2, in every command that reads a dataset: validate, info, build --resume, export, view
and train (evaluate reads no dataset). It was a UnicodeDecodeError or TypeError traceback."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from support.cli import one_line_exit_2
from support.optional import cli_param
from support.synth import build_synth, damageable_copy

QUICK = str(Path(__file__).resolve().parents[1] / "recipes" / "quickstart.yaml")


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("manifest") / "synth", {"train": 2, "test": 1})


def _edit(change: Callable[[dict[str, Any]], None]) -> Callable[[Path], None]:
    def damage(ds: Path) -> None:
        m = json.loads((ds / "manifest.json").read_text())
        change(m)
        (ds / "manifest.json").write_text(json.dumps(m))

    return damage


def _not_utf8(ds: Path) -> None:
    (ds / "manifest.json").write_bytes(b"\xff\xfe{" + (ds / "manifest.json").read_bytes())


DAMAGE: dict[str, tuple[Callable[[Path], None], str]] = {
    "not UTF-8": (_not_utf8, "not UTF-8"),
    "shards not a list": (_edit(lambda m: m.update(shards="data/train-00000-of-00001.parquet")), "shards: must be a list"),
    "limit as text": (_edit(lambda m: m.update(limit="ten")), "limit: must be null or an integer"),
    "splits a list": (_edit(lambda m: m.update(splits=["train"])), "splits: must be a mapping"),
    "a shard's rows as text": (_edit(lambda m: m["shards"][0].update(rows="many")), "shards[0].rows"),
    "complete as text": (_edit(lambda m: m.update(complete="yes")), "complete: must be true or false"),
    "name missing": (_edit(lambda m: m.pop("name")), "name: missing"),
}

COMMANDS = {
    "validate": ["validate", "{ds}"],
    "info": ["info", "{ds}"],
    "export": ["export", "{ds}", "--format", "zarr", "--out", "{tmp}/z"],
    "view": ["view", "{ds}", "--out", "{tmp}/ep.mp4"],
    "train": ["train", "bc", "{ds}", "--skill", "Navigate", "--inputs", "state", "--out", "{tmp}/run", "--no-progress"],
}


@pytest.mark.parametrize("command", [cli_param(c, COMMANDS[c]) for c in sorted(COMMANDS)])
@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_damaged_manifest_is_one_line_naming_file_and_key(case: str, command: str, pristine: Path, tmp_path: Path) -> None:
    damage, says = DAMAGE[case]
    ds = damageable_copy(pristine, tmp_path)
    damage(ds)
    args = [a.format(ds=ds, tmp=tmp_path) for a in COMMANDS[command]]
    one_line_exit_2(args, "manifest.json", says)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["synth"]  # nothing written beside it


@pytest.mark.parametrize("case", ["not UTF-8", "shards not a list", "limit as text"])
def test_build_resume_of_a_damaged_manifest_is_one_line(case: str, pristine: Path, tmp_path: Path) -> None:
    damage, says = DAMAGE[case]
    ds = damageable_copy(pristine, tmp_path)
    damage(ds)
    one_line_exit_2(["build", QUICK, "--out", str(ds), "--resume", "--workers", "1", "--no-progress"], "cannot resume", "manifest.json", says)
