"""The command line as a user meets it: doctor, trial, preview, and bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from echo_data.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def small_recipe(tmp_path: Path, base: str, extra: str = "") -> Path:
    """A recipe extending a shipped one with small cameras (fast on a CPU renderer)."""
    p = tmp_path / "r.yaml"
    p.write_text(
        f"extends: {ROOT / 'recipes' / base}\n"
        "robot:\n  head_camera: {width: 48, height: 48}\n  wrist_camera: {width: 32, height: 32, rgb: false}\n" + extra
    )
    return p


def test_doctor_finds_a_render_device() -> None:
    out = subprocess.run([sys.executable, "-m", "echo_data.cli", "doctor", "--json"], capture_output=True, text=True, timeout=300)
    rep = json.loads(out.stdout)
    assert out.returncode == 0, rep["problems"]
    assert rep["render_ok"] and rep["device"]
    assert rep["versions"]["sapien"] == "3.0.3"


def test_doctor_names_a_missing_vulkan_loader(monkeypatch: pytest.MonkeyPatch) -> None:
    import echo_data.doctor as doctor

    assert doctor.vulkan_loader()  # this machine renders through its system loader
    monkeypatch.setattr(doctor, "vulkan_loader", lambda: None)
    assert doctor.NO_LOADER not in doctor.run_doctor().problems  # rendering works: no loader problem to name
    monkeypatch.setattr(doctor, "_PROBE", "raise SystemExit('RuntimeError: failed to find a rendering device')")
    rep = doctor.run_doctor()
    assert doctor.NO_LOADER in rep.problems and any(p.startswith("rendering failed") for p in rep.problems)


def test_bad_recipe_is_one_line_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nrobot:\n  control_hz: fast\n")
    res = runner.invoke(app, ["trial", str(bad), "-n", "1"])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "robot.control_hz" in lines[0] and "bad.yaml" in lines[0]


@pytest.mark.slow
def test_trial_json_reports_the_contract_keys(tmp_path: Path) -> None:
    res = runner.invoke(app, ["trial", str(small_recipe(tmp_path, "state_transition.yaml")), "-n", "1", "--json"])
    assert res.exit_code == 0, res.output
    rep = json.loads(res.stdout[res.stdout.index("{"):])
    for key in ("episodes", "success_rate", "skills", "rejected", "seconds_per_episode", "steps_per_second"):
        assert key in rep
    assert rep["episodes"] == 1
    assert rep["skills"]["Navigate"]["attempts"] == 1
    assert 0.0 <= rep["success_rate"] <= 1.0 and rep["steps_per_second"] > 0


@pytest.mark.slow
def test_preview_writes_pictures_and_sound(tmp_path: Path) -> None:
    import soundfile as sf
    from PIL import Image

    out = tmp_path / "pv"
    res = runner.invoke(app, ["preview", str(small_recipe(tmp_path, "object_relocation.yaml")), "--seed", "4", "--out", str(out)])
    assert res.exit_code == 0, res.output
    lines = res.stdout.strip().splitlines()
    assert len(lines) == 2 and "seed 4: Navigate(" in lines[0] and lines[1].startswith("wrote ")  # a summary line, not the spec
    for name in ("episode.json", "topdown.png", "head_rgb.png", "frames.png", "heard.wav", "spectrogram.png", "acoustic_map.png"):
        assert (out / name).is_file(), name
    from echo_data.dataset.written import MARKER, all_files

    marker = json.loads((out / MARKER).read_text())  # what a later preview into this folder may replace
    assert marker["kind"] == "preview" and set(marker["files"]) == set(all_files(out)) - {MARKER}
    assert not list(tmp_path.glob(".pv.tmp-*"))  # written aside, then swapped in whole
    spec = json.loads((out / "episode.json").read_text())
    assert [c["skill"] for c in spec["chain"]] == ["Navigate", "Pick", "Place"]
    audio, fs = sf.read(out / "heard.wav")
    assert fs == 16000 and audio.shape == (32000, 2)
    assert float(abs(audio).max()) > 1e-3  # the event is audible at the start pose
    rgb = Image.open(out / "head_rgb.png")
    assert rgb.size == (48, 48)
    assert len(set(rgb.convert("RGB").getdata())) >= 2  # a rendered view (floor and wall at least), not a blank frame
    # contact sheet: one 48-px frame (plus a caption strip) per 2 s of the run, 6 to a row
    import re

    from echo_data.recipe import load_recipe

    steps = int(re.search(r" in (\d+) steps ", res.output).group(1))
    every = 2 * load_recipe(small_recipe(tmp_path, "object_relocation.yaml")).robot.control_hz
    n_frames = -(-steps // every)
    sheet = Image.open(out / "frames.png")
    assert sheet.size == (48 * min(n_frames, 6), (48 + 12) * -(-n_frames // 6))
