"""The built-in library: counts, ids, splits, waveform contract, determinism and seamless loops."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import numpy as np
import pytest

from echo_data.sounds import CATEGORY_COUNTS, PEAK_DBFS, SoundInstance, SoundLibrary, synth

PAPER_COUNTS = {"alarm": (11, 5), "furby": (30, 14), "phone": (19, 9), "sink": (6, 3), "doorbell": (11, 5)}
SR = 16000


@pytest.fixture(scope="module")
def lib() -> SoundLibrary:
    return SoundLibrary.builtin()


def test_counts_match_the_paper(lib: SoundLibrary) -> None:
    assert CATEGORY_COUNTS == PAPER_COUNTS
    assert len(lib.instances()) == 113
    for cat, (n_train, n_test) in PAPER_COUNTS.items():
        assert len(lib.instances(cat, "train")) == n_train
        assert len(lib.instances(cat, "test")) == n_test
        assert len(lib.instances(category=cat)) == n_train + n_test


def test_ids_unique_splits_disjoint_and_stable(lib: SoundLibrary) -> None:
    ids = [s.id for s in lib.instances()]
    assert len(set(ids)) == len(ids)
    train = {s.id for s in lib.instances(split="train")}
    test = {s.id for s in lib.instances(split="test")}
    assert train.isdisjoint(test) and len(train) + len(test) == 113
    assert [s.id for s in SoundLibrary.builtin().instances()] == ids  # stable order
    assert lib.instances("phone", "train")[2].id == "phone-train-03"
    s = lib.get("sink-test-01")
    assert isinstance(s, SoundInstance) and (s.category, s.split, s.source) == ("sink", "test", "builtin")
    assert all(1.0 <= x.duration <= 4.0 for x in lib.instances())
    with pytest.raises(KeyError, match="nope"):
        lib.get("nope")
    with pytest.raises(ValueError, match="category"):
        lib.instances(category="cat")
    with pytest.raises(ValueError, match="split"):
        lib.instances(split="validation")


def test_waveform_contract(lib: SoundLibrary) -> None:
    for s in lib.instances():
        base = lib.waveform(s.id, SR)
        assert base.dtype == np.float32 and base.ndim == 1
        assert len(base) == round(s.duration * SR)
        peak = float(np.max(np.abs(base)))
        assert peak == pytest.approx(10 ** (PEAK_DBFS[s.category] / 20), rel=1e-3)
    x = lib.waveform("phone-train-01", SR, seconds=10.0)
    assert x.shape == (160000,) and x.dtype == np.float32
    assert np.max(np.abs(x)) <= 1.0
    base = lib.waveform("phone-train-01", SR)
    n = len(base)
    np.testing.assert_array_equal(x[n : 2 * n], base)  # later periods are the loop itself
    assert x[0] == 0.0 and abs(x[200]) <= abs(base[200])  # 5 ms fade-in at the onset
    short = lib.waveform("alarm-test-05", SR, seconds=0.25)
    assert len(short) == 4000
    x[:] = 0  # callers may modify what they get; the cache must not change
    assert np.array_equal(lib.waveform("phone-train-01", SR), base)


def test_other_sample_rates_keep_the_sound(lib: SoundLibrary) -> None:
    for iid in ("alarm-train-01", "doorbell-train-02"):
        dur = lib.get(iid).duration
        spec = {}
        for sr in (8000, 16000, 48000):
            x = lib.waveform(iid, sr)
            assert len(x) == round(dur * sr)
            mag = np.abs(np.fft.rfft(x))
            spec[sr] = np.fft.rfftfreq(len(x), 1 / sr)[np.argmax(mag)]
        assert abs(spec[48000] - spec[16000]) < 5.0  # the same dominant pitch
        if spec[16000] < 3500:
            assert abs(spec[8000] - spec[16000]) < 5.0


def _digest(ids: list[str], sr: int, seconds: float | None) -> str:
    lib = SoundLibrary.builtin()
    h = hashlib.sha256()
    for i in ids:
        h.update(lib.waveform(i, sr, seconds).tobytes())
    return h.hexdigest()


def test_deterministic_bytes_across_processes() -> None:
    ids = ["phone-train-04", "furby-test-07", "sink-train-02", "alarm-train-03"]
    here = _digest(ids, 16000, 2.5)
    synth_again = hashlib.sha256(b"".join(synth.render(i, 22050).tobytes() for i in ids)).hexdigest()
    assert synth_again == hashlib.sha256(b"".join(synth.render(i, 22050).tobytes() for i in ids)).hexdigest()
    code = (
        f"import sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); from test_sounds_library import _digest; "
        f"print(_digest({ids!r}, 16000, 2.5))"
    )
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == here
    assert _digest(ids[:1], 16000, 2.5) != _digest(ids[1:2], 16000, 2.5)


def loop_jump_ratio(base: np.ndarray, sr: int) -> float:
    """|x[0] - x[-1]| (the step where the loop wraps) over the largest step within ±5 ms of it."""
    w = int(0.005 * sr)
    around = np.concatenate([base[-w:], base[:w]]).astype(np.float64)
    steps = np.abs(np.diff(around))
    jump = steps[w - 1]
    local = np.delete(steps, w - 1).max()
    return float(jump / local) if local > 0 else (0.0 if jump == 0 else np.inf)


def test_loops_are_seamless(lib: SoundLibrary) -> None:
    worst = max(loop_jump_ratio(lib.waveform(s.id, SR), SR) for s in lib.instances())
    assert worst <= 1.5, worst
    # The check catches a click: the same loops cut short (not at a period) jump at the seam.
    cut = [loop_jump_ratio(lib.waveform(s.id, SR)[: int(0.77 * s.duration * SR)], SR) for s in lib.instances("sink")]
    assert max(cut) > 1.5
