"""The reverberant field moves with the listener: a pure tone's interaural level difference
far beyond the critical distance averages to zero over places and head yaws at every
frequency (it never encodes the tone's pitch), while close to the source it follows the
source's side. In a real room the interaural differences of the diffuse field at one
frequency change within half a wavelength and with head orientation (a diffuse field is a
sum of plane waves with random phases); a single fixed pair of decorrelation filters would
instead give every place and yaw the same frequency-dependent ILD (about ±10 dB)."""

from __future__ import annotations

import numpy as np
import pytest
from support.room_plans import shoebox_plan

from echo_data.acoustics.binaural import binaural_irs
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.room import AcousticScene
from echo_data.recipe import AcousticsConfig

FS = 16000
TONES = (500.0, 700.0, 1000.0, 1500.0, 2000.0, 3000.0, 4000.0)
YAWS = np.deg2rad(np.arange(0.0, 360.0, 30.0))


@pytest.fixture(scope="module")
def scene() -> AcousticScene:
    return AcousticScene(shoebox_plan(6.0, 5.0, "plasterboard", "linoleum_on_concrete", "ceiling_plasterboard"), AcousticsConfig())


def _tone_ild(irs: np.ndarray) -> np.ndarray:
    """(yaws, tones) ILD in dB (left over right) of a steady pure tone: |H_L(f)| / |H_R(f)|."""
    n = 1 << 15
    spec = np.fft.rfft(irs.astype(np.float64), n, axis=1)
    k = np.round(np.asarray(TONES) * n / FS).astype(int)
    mag = np.abs(spec[:, k, :])
    return 20 * np.log10(mag[..., 0] / mag[..., 1])


def test_critical_distance_is_small(scene: AcousticScene) -> None:
    """Premise of the far-field test: receivers 2 m and more away are far beyond r_c."""
    area = scene.acoustics.eq_area[0, 2:5]  # 500 Hz … 2 kHz
    rc = np.sqrt(area / (16 * np.pi))
    assert rc.max() < 0.6


def test_tone_ild_far_from_the_source_averages_to_zero_at_every_frequency(scene: AcousticScene) -> None:
    hrtf = Hrtf.load("kemar", FS)
    src = (0.8, 0.8, 1.0)
    xs, ys = np.meshgrid(np.linspace(3.0, 5.4, 4), np.linspace(2.6, 4.4, 3))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 1.2)])
    assert np.linalg.norm(pts - src, axis=1).min() > 2.5
    ild = np.concatenate([_tone_ild(binaural_irs(r, YAWS, hrtf)) for r in scene.responses(src, pts)])  # (places x yaws, tones)
    assert abs(ild.mean()) < 1.0
    per_tone = ild.mean(axis=0)
    assert np.abs(per_tone).max() < 1.5, per_tone  # no frequency has a side of its own
    # the sign of the ILD is not set by the pitch: at each tone both sides occur about equally
    left_share = (ild > 0).mean(axis=0)
    assert np.all((left_share > 0.3) & (left_share < 0.7)), left_share
    # and the ILD at one place does change with the head's yaw and from place to place
    assert ild.std() > 3.0


def test_tone_ild_near_the_source_follows_its_side(scene: AcousticScene) -> None:
    """Within the critical distance the direct sound wins: at 35 cm the tone's ILD points to
    the source for most tones and places (single tones can still fall into a notch of the
    direct sound's interference with a floor or table reflection, as in a real room)."""
    hrtf = Hrtf.load("kemar", FS)
    src = np.array([3.0, 2.5, 1.2])
    signs = []
    for k, off in enumerate(((-0.35, 0.0), (0.0, 0.35), (0.35, 0.0), (0.0, -0.35))):
        rcv = src + np.array([*off, 0.0])
        to_src = np.arctan2(-off[1], -off[0])  # world azimuth of the source from the head
        yaws = [to_src - np.pi / 2, to_src + np.pi / 2]  # the source on the left, on the right
        ild = _tone_ild(binaural_irs(scene.response(tuple(src), tuple(rcv)), yaws, hrtf))[:, 2:]  # >= 1 kHz
        signs += [np.sign(ild[0]), -np.sign(ild[1])]
        assert ild[0].mean() > 3.0 and ild[1].mean() < -3.0, (k, ild)
    assert (np.concatenate(signs) > 0).mean() >= 0.85


def test_diffuse_field_is_deterministic_per_place_and_differs_between_places() -> None:
    hrtf = Hrtf.load("kemar", FS)
    a = hrtf.diffuse_field(11, [0.0, 0.5])
    np.testing.assert_array_equal(a, hrtf.diffuse_field(11, [0.0, 0.5]))
    b = hrtf.diffuse_field(12, [0.0])
    assert abs(np.corrcoef(a[0, :, 0], b[0, :, 0])[0, 1]) < 0.3
    np.testing.assert_allclose((a.astype(np.float64) ** 2).sum(axis=1).mean(axis=1), 1.0, rtol=1e-5)


def test_diffuse_field_has_the_hrtf_diffuse_coherence() -> None:
    """Averaged over places, the two ears' late signals have the interaural coherence of a
    diffuse field for this head: near 1 at low frequencies (a wavelength much longer than the
    head), falling through zero around 700 Hz and small above 1.5 kHz."""
    hrtf = Hrtf.load("kemar", FS)
    n = 1024
    cross = np.zeros(n // 2 + 1)
    pl, pr = np.zeros(n // 2 + 1), np.zeros(n // 2 + 1)
    for seed in range(60):
        d = np.fft.rfft(hrtf.diffuse_field(seed, [0.3 * seed])[0].astype(np.float64), n, axis=0)
        cross += (d[:, 0] * np.conj(d[:, 1])).real
        pl += np.abs(d[:, 0]) ** 2
        pr += np.abs(d[:, 1]) ** 2
    coh = cross / np.sqrt(pl * pr)
    f = np.fft.rfftfreq(n, 1.0 / FS)
    expect = hrtf.diffuse_coherence(f)
    for lo, hi in ((100, 200), (200, 400), (400, 800), (800, 1600), (1600, 3200), (3200, 6400)):
        m = (f >= lo) & (f < hi)
        assert abs(coh[m].mean() - expect[m].mean()) < 0.15, (lo, coh[m].mean(), expect[m].mean())
    assert coh[(f >= 100) & (f < 200)].mean() > 0.7
    assert abs(coh[f >= 1600].mean()) < 0.15
