"""validate / info: a sound dataset passes; corruption of any kind is reported."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import typer
from support.synth import build_synth, damageable_copy
from typer.testing import CliRunner

from echo_data.app.commands import register
from echo_data.dataset.info import info
from echo_data.dataset.validate import validate


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("val") / "synth", {"train": 3, "test": 2})


@pytest.fixture
def ds(pristine: Path, tmp_path: Path) -> Path:
    return damageable_copy(pristine, tmp_path)


def _cli(args: list[str]):  # noqa: ANN202
    app = typer.Typer()
    register(app)
    return CliRunner().invoke(app, args)


def test_sound_dataset_has_no_problems(ds: Path) -> None:
    assert validate(ds) == []
    res = _cli(["validate", str(ds)])
    assert res.exit_code == 0 and "ok" in res.output


def test_corrupted_shard_is_reported(ds: Path) -> None:
    shard = ds / "data" / "train-00001-of-00002.parquet"
    data = bytearray(shard.read_bytes())
    data[len(data) // 3 : len(data) // 3 + 64] = bytes(64)
    shard.write_bytes(bytes(data))
    problems = validate(ds)
    assert any("train-00001-of-00002.parquet: sha256" in p for p in problems), problems
    res = _cli(["validate", str(ds)])
    assert res.exit_code == 1


def test_truncated_wav_is_reported(ds: Path) -> None:
    wav = ds / "audio" / "test" / "test-000001.wav"
    wav.write_bytes(wav.read_bytes()[:-1000])
    problems = validate(ds)
    assert any("test-000001" in p and "sha256" in p for p in problems), problems
    assert any("test-000001" in p and "samples" in p for p in problems), problems


def test_missing_stats_missing_wav_and_leftovers_are_reported(ds: Path) -> None:
    (ds / "meta" / "stats.json").unlink()
    (ds / "audio" / "train" / "train-000000.wav").unlink()
    (ds / "data" / ".train-00000-of-00002.parquet.tmp-1").write_bytes(b"x")
    problems = "\n".join(validate(ds))
    assert "meta/stats.json" in problems and "missing audio/train/train-000000.wav" in problems
    assert "leftover temporary file" in problems


def test_incomplete_build_is_reported(ds: Path) -> None:
    m = json.loads((ds / "manifest.json").read_text())
    m["complete"] = False
    (ds / "manifest.json").write_text(json.dumps(m))
    assert any("not complete" in p for p in validate(ds))


def test_not_a_dataset(tmp_path: Path) -> None:
    assert validate(tmp_path) and "no manifest.json" in validate(tmp_path)[0]
    assert _cli(["validate", str(tmp_path)]).exit_code == 2
    assert _cli(["info", str(tmp_path)]).exit_code == 2


def test_info(ds: Path) -> None:
    d = info(ds)
    assert d["episodes"] == {"train": 3, "test": 2}
    assert d["steps"] == sum(d["steps_per_split"].values()) > 0
    assert d["skills"]["Pick"]["attempts"] >= d["skills"]["Pick"]["successes"] > 0
    assert d["bytes"] > 0 and d["sound_instances"] == {"test": 2, "train": 3}
    assert d["rejections"]["object_moved"] > 0 and d["settings"]["train"] == {"object_relocation": 2, "state_transition": 1}
    res = _cli(["info", str(ds), "--json"])
    assert res.exit_code == 0 and json.loads(res.output)["episodes"] == {"train": 3, "test": 2}
