"""`echo-data sounds list/export` through the real command line app."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import soundfile as sf
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.sounds import SoundLibrary

runner = CliRunner()


def test_list_json_has_113_instances_in_the_paper_counts() -> None:
    r = runner.invoke(app, ["sounds", "list", "--json"])
    assert r.exit_code == 0, r.output
    items = json.loads(r.stdout)
    assert len(items) == 113
    assert all({"id", "category", "split", "duration", "source"} <= set(x) for x in items)
    counts = Counter((x["category"], x["split"]) for x in items)
    assert counts == {("alarm", "train"): 11, ("alarm", "test"): 5, ("furby", "train"): 30, ("furby", "test"): 14,
                      ("phone", "train"): 19, ("phone", "test"): 9, ("sink", "train"): 6, ("sink", "test"): 3,
                      ("doorbell", "train"): 11, ("doorbell", "test"): 5}
    assert {x["source"] for x in items} == {"builtin"}


def test_list_table_and_filters() -> None:
    r = runner.invoke(app, ["sounds", "list", "--category", "phone", "--split", "test"])
    assert r.exit_code == 0, r.output
    assert "phone-test-09" in r.stdout and "phone-train" not in r.stdout and "9 instances" in r.stdout
    r = runner.invoke(app, ["sounds", "list", "--category", "cat"])
    assert r.exit_code == 2 and "unknown sound category" in r.output


def test_list_with_a_recipe_adds_user_folders(tmp_path: Path) -> None:
    (tmp_path / "bells").mkdir()
    for i in range(2):
        sf.write(str(tmp_path / "bells" / f"b{i}.wav"), 0.3 * np.sin(np.arange(8000) * (0.2 + i * 0.1)), 8000)
    recipe = tmp_path / "r.yaml"
    recipe.write_text("name: r\nsounds:\n  builtin: false\n  folders:\n    doorbell: bells\n")
    r = runner.invoke(app, ["sounds", "list", "--json", "--recipe", str(recipe)])
    assert r.exit_code == 0, r.output
    items = json.loads(r.stdout)
    assert len(items) == 2 and {x["split"] for x in items} == {"train", "test"}
    (tmp_path / "bells" / "b9.wav").write_bytes(b"not a wav")
    r = runner.invoke(app, ["sounds", "list", "--recipe", str(recipe)])
    assert r.exit_code == 2 and "b9.wav" in r.output


def test_export_writes_listenable_wavs(tmp_path: Path) -> None:
    out = tmp_path / "wav"
    r = runner.invoke(app, ["sounds", "export", str(out), "--category", "sink", "--split", "test", "--seconds", "1.5"])
    assert r.exit_code == 0, r.output
    files = sorted(p.name for p in out.iterdir())
    assert files == ["sink-test-01.wav", "sink-test-02.wav", "sink-test-03.wav"]
    info = sf.info(str(out / "sink-test-01.wav"))
    assert (info.samplerate, info.frames, info.channels, info.subtype) == (16000, 24000, 1, "PCM_16")
    x, _ = sf.read(str(out / "sink-test-01.wav"), dtype="float32")
    ref = SoundLibrary.builtin().waveform("sink-test-01", 16000, seconds=1.5)
    assert np.max(np.abs(x - ref)) < 1e-4
    r = runner.invoke(app, ["sounds", "export", str(out), "--category", "alarm", "--split", "train",
                            "--seconds", "0.5", "--sample-rate", "48000"])
    assert r.exit_code == 0 and len(list(out.glob("alarm-train-*.wav"))) == 11
    assert sf.info(str(out / "alarm-train-01.wav")).samplerate == 48000
