"""`echo-data view`: an MP4 of one episode with its binaural sound track."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.media import probe_mp4


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 2, "test": 1})


def test_view_writes_video_with_binaural_sound(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "ep.mp4"
    r = CliRunner().invoke(app, ["view", str(ds), "--episode", "1", "--out", str(out)])
    assert r.exit_code == 0, r.output
    ep = next(e for e in pq.read_table(ds / "meta" / "episodes.parquet").to_pylist() if e["split"] == "train" and e["episode_index"] == 1)
    p = probe_mp4(out)
    assert sorted(p["streams"]) == ["audio", "video"]
    assert p["video_frames"] == ep["n_steps"] and p["fps"] == 10.0
    assert p["audio_channels"] == 2 and p["audio_rate"] == 16000
    assert p["duration_s"] == pytest.approx(ep["n_steps"] / 10, abs=0.05)
    assert (p["width"], p["height"]) == (768, 412)


def test_view_bad_episode_is_exit_2_and_writes_nothing(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "none.mp4"
    r = CliRunner().invoke(app, ["view", str(ds), "--episode", "7", "--out", str(out)])
    assert r.exit_code == 2 and "no train episode 7" in r.output and not out.exists()
    r = CliRunner().invoke(app, ["view", str(tmp_path), "--out", str(out)])
    assert r.exit_code == 2 and "manifest.json" in r.output and not out.exists()
