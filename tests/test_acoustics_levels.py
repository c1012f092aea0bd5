"""Calibrated levels: source levels in dB SPL at 1 m, a stated full scale with no clipping, and
a room noise bed at its stated A-weighted level (IEC 61672 weighting)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import fftconvolve

from echo_data.acoustics.binaural import binaural_irs
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import (
    P_REF,
    ClippingError,
    full_scale_pa,
    level_db,
    pascal_gain,
    to_full_scale,
)
from echo_data.acoustics.noise import NoiseFloor, a_weighting_db
from echo_data.acoustics.types import SPEED_OF_SOUND, AcousticResponse, Arrival
from echo_data.categories import SOURCE_LEVELS_DB, source_level_db
from echo_data.sounds.library import SoundLibrary

FS = 16000


def _dba(x: np.ndarray) -> float:
    """A-weighted level (dB re 20 µPa) of a pressure signal, averaged over its channels."""
    X = np.fft.rfft(np.asarray(x, dtype=np.float64), axis=0)
    f = np.fft.rfftfreq(len(x), 1.0 / FS)
    w = 10.0 ** (a_weighting_db(np.maximum(f, 1e-3)) / 10.0)
    power = 2.0 * (np.abs(X) ** 2 * w[:, None]).sum(axis=0) / len(x) ** 2
    return float(10 * np.log10(power.mean() / P_REF**2))


@pytest.mark.parametrize("setting", [25.0, 30.0, 35.0])
def test_noise_floor_level_within_one_db_of_its_setting(setting: float) -> None:
    bed = NoiseFloor(FS, setting, 7, Hrtf.load("kemar", FS))
    x = bed.render(12345, 4 * FS)
    assert _dba(x) == pytest.approx(setting, abs=1.0)
    # also after 16-bit quantisation at the default calibration (full scale = 120 dB SPL; its
    # quantisation noise, about 19 dB SPL, adds 1 dB to a 25 dB(A) bed)
    if setting >= 30.0:
        q = np.round(to_full_scale(x, 120.0) * 32768.0) / 32768.0 * full_scale_pa(120.0)
        assert _dba(q) == pytest.approx(setting, abs=1.0)
    # the ears hear a diffuse field: coherent at low frequencies, not a mono copy
    assert 0.3 < np.corrcoef(x[:, 0], x[:, 1])[0, 1] < 0.99


def test_noise_floor_streams_and_turns_off() -> None:
    bed = NoiseFloor(FS, 30.0, 3, Hrtf.load("kemar", FS))
    whole = bed.render(0, 3 * FS)
    parts = np.concatenate([bed.render(0, 7001), bed.render(7001, 3 * FS - 7001)])
    np.testing.assert_array_equal(whole, parts)
    assert not NoiseFloor(FS, 0.0, 3, Hrtf.load("kemar", FS)).render(0, FS).any()
    assert not np.array_equal(whole, NoiseFloor(FS, 30.0, 4, Hrtf.load("kemar", FS)).render(0, 3 * FS))


def test_source_levels_are_drawn_in_their_stated_ranges() -> None:
    for cat, (lo, hi) in SOURCE_LEVELS_DB.items():
        got = [source_level_db(cat, seed, e) for seed in range(40) for e in range(2)]
        assert lo <= min(got) and max(got) <= hi and max(got) - min(got) > 0.5 * (hi - lo)
        assert source_level_db(cat, 5, 1) == source_level_db(cat, 5, 1)
    with pytest.raises(ValueError, match="no source level"):
        source_level_db("trumpet", 0, 0)


def test_a_calibrated_source_at_one_metre_has_its_level_at_the_ears() -> None:
    """Free field, 1 m: averaged over head yaws the ears receive the stated level (the HRTF is
    diffuse-field normalised); ±2 dB for the horizontal-plane average of the head's gain."""
    lib = SoundLibrary.builtin()
    hrtf = Hrtf.load("kemar", FS)
    arr = Arrival(1.0 / SPEED_OF_SOUND, (1.0, 0.0, 0.0), 1.0, (1.0,) * 7, 0)
    irs = binaural_irs(AcousticResponse(FS, [arr], np.zeros(4000, np.float32), 4000), np.deg2rad(np.arange(0, 360, 15)), hrtf)
    for cat in ("phone", "doorbell", "sink"):
        loop = lib.waveform(lib.instances(cat, "train")[0].id, FS)
        dry = loop * pascal_gain(loop, FS, 70.0)
        assert level_db(dry, FS) == pytest.approx(70.0, abs=1e-6)
        x = np.tile(dry, 2).astype(np.float64)
        ears = fftconvolve(x[None, :, None], irs.astype(np.float64), axes=1)  # (yaws, n, 2)
        seg = ears[:, len(dry) : 2 * len(dry)]  # one loop period in steady state
        mean_level = 10 * np.log10(np.mean([10 ** (level_db(e[:, c], FS) / 10) for e in seg for c in (0, 1)]))
        assert mean_level == pytest.approx(70.0, abs=2.0), cat


def test_a_track_that_would_clip_is_an_error_not_clipped() -> None:
    fs_pa = full_scale_pa(120.0)
    ok = to_full_scale(np.array([[0.5 * fs_pa, -0.9 * fs_pa]]), 120.0)
    np.testing.assert_allclose(ok, [[0.5, -0.9]], rtol=1e-6)
    assert ok.dtype == np.float32
    with pytest.raises(ClippingError, match="full scale = 120 dB SPL"):
        to_full_scale(np.array([[0.2, 1.01 * fs_pa]]), 120.0, what="episode x")
