"""The user's own files: any rate / channel count, deterministic splits, clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from echo_data.recipe import Recipe, SoundsConfig
from echo_data.sounds import PEAK_DBFS, SoundLibrary, SoundLibraryError
from echo_data.sounds.user_folders import crossfade_loop, split_files


def _tone(f: float, seconds: float, sr: int) -> np.ndarray:
    return np.sin(2 * np.pi * f * np.arange(int(seconds * sr)) / sr)


def _write_stereo(path: Path, fl: float, fr: float, seconds: float = 1.0, sr: int = 44100) -> None:
    sf.write(str(path), np.stack([0.5 * _tone(fl, seconds, sr), 0.5 * _tone(fr, seconds, sr)], axis=1), sr)


def _recipe(folders: dict[str, str], builtin: bool = False, fraction: float = 0.3) -> Recipe:
    return Recipe(name="t", sounds=SoundsConfig(builtin=builtin, folders=folders, folder_test_fraction=fraction))


def test_stereo_44k_is_mixed_to_mono_and_resampled(tmp_path: Path) -> None:
    d = tmp_path / "phones"
    d.mkdir()
    _write_stereo(d / "Ring One.wav", 440.0, 1000.0, seconds=1.0)
    _write_stereo(d / "ring2.wav", 700.0, 700.0, seconds=1.5)
    (d / "notes.txt").write_text("not audio, ignored")
    lib = SoundLibrary.from_recipe(_recipe({"phone": "phones"}), recipe_dir=tmp_path)
    items = lib.instances()
    assert [s.category for s in items] == ["phone", "phone"]
    assert {s.split for s in items} == {"train", "test"}  # two files: one of each
    one = next(s for s in items if "ring_one" in s.id)
    assert one.duration == pytest.approx(1.0) and one.source == str(d / "Ring One.wav")
    x = lib.waveform(one.id, 16000)
    assert x.dtype == np.float32 and len(x) == 16000 - 800  # 1 s minus the 50 ms loop crossfade
    assert np.max(np.abs(x)) == pytest.approx(10 ** (PEAK_DBFS["phone"] / 20), rel=1e-3)
    mag = np.abs(np.fft.rfft(x[: 15000] * np.hanning(15000)))
    freqs = np.fft.rfftfreq(15000, 1 / 16000)
    near = (np.abs(freqs - 440) < 20) | (np.abs(freqs - 1000) < 20)
    assert np.sum(mag[~near] ** 2) < 0.01 * np.sum(mag**2)  # only the two channel tones, no aliasing
    a440 = mag[np.argmin(np.abs(freqs - 440))]
    a1000 = mag[np.argmin(np.abs(freqs - 1000))]
    assert a440 / a1000 == pytest.approx(1.0, rel=0.1)  # both channels mixed at equal weight
    y = lib.waveform(one.id, 22050, seconds=3.0)
    assert len(y) == 66150


def test_builtin_plus_folder_and_absolute_path(tmp_path: Path) -> None:
    d = tmp_path / "sinks"
    d.mkdir()
    for i in range(5):
        _write_stereo(d / f"tap{i}.wav", 300.0 + 50 * i, 300.0 + 50 * i, seconds=0.5, sr=22050)
    lib = SoundLibrary.from_recipe(_recipe({"sink": str(d)}, builtin=True, fraction=0.4))
    assert len(lib.instances()) == 118
    user = [s for s in lib.instances("sink") if s.source != "builtin"]
    assert sum(s.split == "test" for s in user) == 2 and sum(s.split == "train" for s in user) == 3
    assert [s.id for s in user] == [s.id for s in SoundLibrary.from_recipe(_recipe({"sink": str(d)}, True, 0.4)).instances("sink")][9:]


def test_split_is_deterministic_and_keeps_one_of_each() -> None:
    files = [Path(f"f{i}.wav") for i in range(10)]
    a = split_files(files, 0.3)
    assert a == split_files(list(reversed(files)), 0.3)
    assert sum(v == "test" for v in a.values()) == 3
    assert set(split_files(files[:2], 0.0).values()) == {"train", "test"}
    assert set(split_files(files[:3], 0.99).values()) == {"train", "test"}
    assert split_files(files[:1], 0.3) == {files[0]: "train"}


def test_unreadable_file_names_the_file(tmp_path: Path) -> None:
    d = tmp_path / "alarms"
    d.mkdir()
    _write_stereo(d / "good.wav", 2000.0, 2000.0, seconds=0.5)
    bad = d / "broken.wav"
    bad.write_bytes(b"RIFF\x00\x00\x00\x00WAVEjunkjunkjunk")
    with pytest.raises(SoundLibraryError) as e:
        SoundLibrary.from_recipe(_recipe({"alarm": "alarms"}), recipe_dir=tmp_path)
    msg = str(e.value)
    assert str(bad) in msg and "\n" not in msg
    silent = tmp_path / "quiet"
    silent.mkdir()
    sf.write(str(silent / "zero.wav"), np.zeros(8000), 8000)
    sf.write(str(silent / "zero2.wav"), np.zeros(8000), 8000)
    with pytest.raises(SoundLibraryError, match="zero.wav: audio file is silent"):  # when the library is loaded, not mid-build
        SoundLibrary.from_recipe(_recipe({"furby": "quiet"}), recipe_dir=tmp_path)
    with pytest.raises(SoundLibraryError, match="missing"):
        SoundLibrary.from_recipe(_recipe({"furby": "missing"}), recipe_dir=tmp_path)
    (tmp_path / "empty").mkdir()
    with pytest.raises(SoundLibraryError, match="no audio files"):
        SoundLibrary.from_recipe(_recipe({"sink": "empty"}), recipe_dir=tmp_path)


def test_crossfaded_file_loop_has_no_click() -> None:
    sr = 16000
    x = _tone(437.25, 1.0, sr)  # 437.25 cycles do not fit 1 s: a plain loop would jump at the seam
    loop = crossfade_loop(x, sr)
    seam = abs(loop[0] - loop[-1])
    assert seam <= np.max(np.abs(np.diff(loop))) * 1.05
    assert abs(x[0] - x[-1]) > 2 * np.max(np.abs(np.diff(x)))  # ...which the plain loop does
