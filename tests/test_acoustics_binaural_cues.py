"""Binaural cues of `binaural_ir` with both HRTFs: side, ITD size, mirroring, head rotation,
delay and distance law, band gains, diffuse tail; and the shipped KEMAR table itself."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import correlate, resample

from echo_data.acoustics.binaural import band_weights, binaural_ir, binaural_irs
from echo_data.acoustics.hrtf import KEMAR_NPZ, Hrtf
from echo_data.acoustics.types import BAND_CENTERS, SPEED_OF_SOUND, AcousticResponse, Arrival

FS = 16000
L = 4000
KINDS = ("kemar", "sphere")
EAR = (0.0, 0.0, 1.2)


def free_field(src, rcv=EAR, band=(1.0,) * 7, tail=None) -> AcousticResponse:
    """One direct arrival: delay d / c, gain 1 / d, direction receiver -> source."""
    v = np.asarray(src, float) - np.asarray(rcv, float)
    d = float(np.linalg.norm(v))
    arr = Arrival(d / SPEED_OF_SOUND, tuple(v / d), 1.0 / d, tuple(band), 0)
    return AcousticResponse(FS, [arr], np.zeros(L, np.float32) if tail is None else tail, L)


def itd_s(ir: np.ndarray) -> float:
    """Right-ear lag behind the left ear (s), from the broadband cross-correlation, x16 upsampled."""
    up = 16
    x = resample(np.pad(ir.astype(np.float64), ((0, 64), (0, 0))), (len(ir) + 64) * up, axis=0)
    c = correlate(x[:, 1], x[:, 0], mode="full")
    return (int(np.argmax(c)) - (len(x) - 1)) / (FS * up)


def ild_db(ir: np.ndarray) -> float:
    e = (ir.astype(np.float64) ** 2).sum(axis=0)
    return float(10 * np.log10(e[0] / e[1]))


def onset_s(x: np.ndarray) -> float:
    """First crossing of 20 % of the peak magnitude, linearly interpolated (s)."""
    a = np.abs(x.astype(np.float64))
    thr = 0.2 * a.max()
    n = int(np.argmax(a >= thr))
    return (n - 1 + (thr - a[n - 1]) / (a[n] - a[n - 1])) / FS


def polar(az_deg: float, dist: float = 2.0) -> tuple[float, float, float]:
    a = math.radians(az_deg)
    return (EAR[0] + dist * math.cos(a), EAR[1] + dist * math.sin(a), EAR[2])


@pytest.mark.parametrize("kind", KINDS)
def test_source_on_left_arrives_first_and_louder_at_left_ear(kind):
    h = Hrtf.load(kind, FS)
    ir = binaural_ir(free_field(polar(90)), 0.0, h)  # head faces +x, so +y is its left
    assert ir.dtype == np.float32 and ir.shape[1] == 2
    assert itd_s(ir) > 0.4e-3  # right ear lags
    assert onset_s(ir[:, 0]) < onset_s(ir[:, 1])
    assert ild_db(ir) > 5.0
    right = binaural_ir(free_field(polar(-90)), 0.0, h)
    assert itd_s(right) < -0.4e-3 and ild_db(right) < -5.0


@pytest.mark.parametrize("kind", KINDS)
def test_itd_at_90_degrees_is_06_to_08_ms(kind):
    ir = binaural_ir(free_field(polar(90, 3.0)), 0.0, Hrtf.load(kind, FS))
    assert 0.6e-3 <= abs(itd_s(ir)) <= 0.8e-3


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("az", [30.0, 60.0, 120.0])
def test_mirrored_positions_give_mirrored_cues(kind, az):
    h = Hrtf.load(kind, FS)
    a = binaural_ir(free_field(polar(az)), 0.0, h)
    b = binaural_ir(free_field(polar(-az)), 0.0, h)
    assert itd_s(a) == pytest.approx(-itd_s(b), abs=1.0 / (FS * 16))
    assert ild_db(a) == pytest.approx(-ild_db(b), abs=0.05)
    assert ild_db(a) > 1.0  # the cue is there to be mirrored
    np.testing.assert_allclose(a[:, 0], b[:, 1], atol=1e-6 * np.abs(a).max())


@pytest.mark.parametrize("kind", KINDS)
def test_turning_the_head_moves_the_cues(kind):
    h = Hrtf.load(kind, FS)
    resp = free_field(polar(90))
    side = binaural_ir(resp, 0.0, h)
    facing = binaural_ir(resp, math.pi / 2, h)  # nose now points at the source
    away = binaural_ir(resp, math.pi, h)  # source now on the right
    assert itd_s(side) > 0.5e-3 and abs(itd_s(facing)) < 0.07e-3 and abs(ild_db(facing)) < 0.5
    assert itd_s(away) < -0.5e-3 and ild_db(away) < -5.0
    # a world rotation of source and head together changes nothing
    turned = binaural_ir(free_field(polar(90 + 45)), math.radians(45), h)
    np.testing.assert_allclose(turned, side, atol=1e-6 * np.abs(side).max())


def lag_s(x: np.ndarray, ref: np.ndarray) -> float:
    """Delay of x relative to ref (s) from their cross-correlation, x16 upsampled."""
    up = 16
    n = len(x) + len(ref)
    xu = resample(np.pad(x.astype(np.float64), (0, n - len(x))), n * up)
    ru = resample(np.pad(ref.astype(np.float64), (0, n - len(ref))), n * up)
    c = correlate(xu, ru, mode="full")
    return (int(np.argmax(c)) - (len(ru) - 1)) / (FS * up)


@pytest.mark.parametrize("kind", KINDS)
def test_head_centre_arrival_is_distance_over_c_and_level_falls_6db_per_doubling(kind):
    h = Hrtf.load(kind, FS)
    assert 0.0 < h.delay_s < 2e-3
    front = h.hrir(0.0, 0.0)
    irs = {d: binaural_ir(free_field(polar(0, d)), 0.0, h) for d in (1.0, 2.0, 4.0)}
    for d, ir in irs.items():  # the frontal HRIR, moved so that its head-centre latency lands on d / c
        for ch in range(2):
            assert lag_s(ir[:, ch], front[:, ch]) + h.delay_s == pytest.approx(d / SPEED_OF_SOUND, abs=0.2 / FS)
    e = {d: float((ir.astype(np.float64) ** 2).sum()) for d, ir in irs.items()}
    assert 10 * np.log10(e[1.0] / e[2.0]) == pytest.approx(6.02, abs=0.05)
    assert 10 * np.log10(e[2.0] / e[4.0]) == pytest.approx(6.02, abs=0.05)


def test_band_weights_partition_unity_and_unit_gains_pass_the_hrir_through():
    f = np.linspace(0, FS / 2, 999)
    np.testing.assert_allclose(band_weights(f).sum(axis=0), 1.0, atol=1e-12)
    h = Hrtf.load("kemar", FS)
    d = 1.0 / SPEED_OF_SOUND * 7  # 7 m: far from the start, integer-free delay
    resp = AcousticResponse(FS, [Arrival(d, (0.0, 1.0, 0.0), 1.0, (1.0,) * 7, 0)], np.zeros(L, np.float32), L)
    ir = binaural_ir(resp, 0.0, h)
    ref = h.hrir(math.pi / 2, 0.0).astype(np.float64)
    # the rendered IR is the HRIR itself, shifted (by a fractional delay): equal energy and shape
    assert float((ir.astype(np.float64) ** 2).sum()) == pytest.approx(float((ref**2).sum()), rel=0.01)
    c = correlate(ir[:, 0].astype(np.float64), ref[:, 0], mode="valid")
    assert c.max() / np.sqrt((ir[:, 0].astype(np.float64) ** 2).sum() * (ref[:, 0] ** 2).sum()) > 0.98


def _band_level_db(ir: np.ndarray, lo: float, hi: float) -> float:
    spec = np.abs(np.fft.rfft(ir.astype(np.float64), 8192, axis=0)) ** 2
    f = np.fft.rfftfreq(8192, 1.0 / FS)
    return float(10 * np.log10(spec[(f >= lo) & (f < hi)].sum(axis=0).mean()))


def test_per_band_gains_shape_the_spectrum():
    h = Hrtf.load("sphere", FS)
    band = (1.0, 1.0, 1.0, 1.0, 0.1, 0.1, 0.1)  # -20 dB from 2 kHz up
    flat = binaural_ir(free_field(polar(0)), 0.0, h)
    dull = binaural_ir(free_field(polar(0), band=band), 0.0, h)
    assert _band_level_db(dull, 200, 600) - _band_level_db(flat, 200, 600) == pytest.approx(0.0, abs=0.5)
    assert _band_level_db(dull, 2500, 7000) - _band_level_db(flat, 2500, 7000) == pytest.approx(-20.0, abs=1.5)
    assert len(BAND_CENTERS) == len(band)


@pytest.mark.parametrize("kind", KINDS)
def test_diffuse_tail_keeps_its_energy_and_is_decorrelated(kind):
    h = Hrtf.load(kind, FS)
    rng = np.random.default_rng(3)
    tail = (rng.standard_normal(L) * np.exp(-np.arange(L) / 900.0)).astype(np.float32)
    resp = AcousticResponse(FS, [], tail, L)
    ir = binaural_ir(resp, 0.3, h).astype(np.float64)
    e_tail = float((tail.astype(np.float64) ** 2).sum())
    assert (ir**2).sum() / e_tail == pytest.approx(2.0, abs=0.3)  # both ears together
    for ch in range(2):
        assert (ir[:, ch] ** 2).sum() / e_tail == pytest.approx(1.0, abs=0.3)
    rho = np.corrcoef(ir[:, 0], ir[:, 1])[0, 1]
    assert abs(rho) < 0.5  # a mono copy would give 1
    np.testing.assert_array_equal(ir, binaural_ir(resp, 0.3, h))  # deterministic
    turned = binaural_ir(resp, 2.0, h).astype(np.float64)  # the field does not turn with the head
    assert not np.allclose(ir, turned)
    assert (turned**2).sum() / e_tail == pytest.approx(2.0, abs=0.3)


def test_several_yaws_at_once_equal_one_at_a_time():
    h = Hrtf.load("kemar", FS)
    rng = np.random.default_rng(5)
    arrivals = []
    for i in range(12):
        v = rng.standard_normal(3)
        arrivals.append(Arrival(0.004 + 0.0023 * i, tuple(v / np.linalg.norm(v)), 0.3, tuple(rng.uniform(0.2, 1, 7)), 1))
    tail = (rng.standard_normal(L) * np.exp(-np.arange(L) / 600.0) * 0.01).astype(np.float32)
    resp = AcousticResponse(FS, arrivals, tail, L)
    yaws = [0.0, 1.0, -2.5]
    many = binaural_irs(resp, yaws, h)
    for y, ir in zip(yaws, many):
        np.testing.assert_allclose(ir, binaural_ir(resp, y, h), atol=1e-7)


def test_shipped_kemar_table():
    with np.load(KEMAR_NPZ) as z:
        assert z["hrir"].shape == (710, 96, 2) and z["hrir"].dtype == np.float32
        assert int(z["fs"]) == 16000
        assert sorted(set(np.round(z["elevation_deg"]).astype(int))) == list(range(-40, 91, 10))
    assert KEMAR_NPZ.stat().st_size < 600_000
    h = Hrtf.load("kemar", FS)
    e = (h.table.astype(np.float64) ** 2).sum(axis=1)
    assert e.mean() == pytest.approx(1.0, rel=1e-6)  # diffuse-field normalised on load
    # nearest-direction lookup returns the measured direction's response
    k = int(np.argmin(np.abs(np.degrees(np.arctan2(h.directions[:, 1], h.directions[:, 0])) - 90) + np.abs(h.directions[:, 2]) * 100))
    np.testing.assert_array_equal(h.hrir(math.pi / 2, 0.0), h.table[k])



def test_kemar_diffuse_field_average_is_flat_after_equalisation():
    """The shipped responses hold the measuring loudspeaker's low-frequency fall; once diffuse-field
    equalised on load, their average over directions and ears is flat (docs/acoustics.md): within
    1.5 dB of its mean in every third-octave band from 250 Hz to 6.3 kHz."""
    def third_octaves(table: np.ndarray) -> np.ndarray:
        n = 4096
        power = (np.abs(np.fft.rfft(table.astype(np.float64), n, axis=1)) ** 2).mean(axis=(0, 2))
        f = np.fft.rfftfreq(n, 1.0 / FS)
        return np.array([10 * np.log10(power[(f >= fc * 2 ** (-1 / 6)) & (f <= fc * 2 ** (1 / 6))].mean())
                         for fc in 1000.0 * 2.0 ** (np.arange(-6, 9) / 3)])  # 250 Hz .. 6.3 kHz

    with np.load(KEMAR_NPZ) as z:
        raw = third_octaves(z["hrir"])
    flat = third_octaves(Hrtf.load("kemar", FS).table)
    assert raw.max() - raw.min() > 15.0  # the loudspeaker's fall is there before equalisation
    assert np.abs(flat - flat.mean()).max() < 1.5

@pytest.mark.parametrize("kind", KINDS)
def test_other_sample_rates_keep_the_itd(kind):
    fs = 48000
    ir = Hrtf.load(kind, fs).hrir(math.pi / 2, 0.0).astype(np.float64)
    up = 4
    x = resample(np.pad(ir, ((0, 64), (0, 0))), (len(ir) + 64) * up, axis=0)
    lag = (int(np.argmax(correlate(x[:, 1], x[:, 0], mode="full"))) - (len(x) - 1)) / (fs * up)
    assert 0.6e-3 <= lag <= 0.8e-3


def test_sphere_head_shadow_grows_with_frequency():
    """Brown-Duda: the far ear loses highs, not lows; the near ear gains up to +6 dB at high frequency."""
    from echo_data.acoustics.hrtf import sphere_hrir_table

    ir = sphere_hrir_table(np.array([[0.0, 1.0, 0.0]]), FS)[0]  # source at the left ear
    spec = np.abs(np.fft.rfft(ir, 4096, axis=0))
    f = np.fft.rfftfreq(4096, 1.0 / FS)
    lo, hi = (f > 50) & (f < 150), (f > 6000) & (f < 7500)
    ild_lo = 20 * np.log10(spec[lo, 0].mean() / spec[lo, 1].mean())
    ild_hi = 20 * np.log10(spec[hi, 0].mean() / spec[hi, 1].mean())
    assert abs(ild_lo) < 1.0 and ild_hi > 12.0
    assert 20 * np.log10(spec[hi, 0].mean()) == pytest.approx(20 * np.log10(2.0), abs=1.0)
