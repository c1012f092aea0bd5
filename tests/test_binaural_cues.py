"""The tiled cue estimators of the spatial-cue benchmark (studies/spatial_cues/binaural_cues.py).

A direct source 60° to the left plays short noise bursts through the KEMAR HRIR; a continuous
interaural-incoherent field (independent noise at each ear, like the late part of a diffuse
field, whose realisation here leans 15 dB to the right) carries most of the energy. The plain
ILD over the second points right; the tiles where one wavefront dominates (high interaural
coherence, Faller & Merimaa 2004) and the onsets (precedence effect) point left, as the direct
sound does. Without the selection (c0 = 0) the tiles' ILD points right too.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
from scipy.signal import fftconvolve

from echo_data.acoustics.hrtf import Hrtf

ROOT = Path(__file__).resolve().parents[1]
FS = 16000
ILD_BAND, ITD_BAND = (500.0, 8000.0), (300.0, 1500.0)


def _cues():
    spec = importlib.util.spec_from_file_location("binaural_cues", ROOT / "studies" / "spatial_cues" / "binaural_cues.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


def _direct(rng: np.random.Generator, hrir: np.ndarray) -> np.ndarray:
    """Three 25 ms noise bursts in one second through `hrir` (taps, 2)."""
    dry = np.zeros(FS)
    for t0 in (0.1, 0.4, 0.7):
        i = int(t0 * FS)
        dry[i : i + int(0.025 * FS)] = rng.standard_normal(int(0.025 * FS))
    return np.stack([fftconvolve(dry, hrir[:, c])[:FS] for c in range(2)], axis=1)


def _scene(seed: int, hrir: np.ndarray) -> np.ndarray:
    rng = np.random.default_rng(seed)
    direct = _direct(rng, hrir)
    burst_power = (direct[:, 1] ** 2).sum() / (3 * 0.025 * FS)  # far (right) ear, during bursts
    field = rng.standard_normal((FS, 2)) * np.array([1.0, 10 ** (15 / 20)])
    return direct * np.sqrt(16.0 / burst_power) + field


def test_coherence_selection_and_onsets_find_the_direct_sound_where_the_plain_ild_does_not() -> None:
    bc = _cues()
    hrir = Hrtf.load("kemar", FS).hrir(np.radians(60.0)).astype(np.float64)  # source on the left
    centres = bc.erb_space(300.0, 7000.0, 20)
    plain, unselected, selected, onset = [], [], [], []
    for seed in range(6):
        x = _scene(seed, hrir)
        t = bc.tiles(x, FS, centres)
        plain.append(10 * np.log10((x[:, 0] ** 2).sum() / (x[:, 1] ** 2).sum()))
        unselected.append(bc.coherence_selected(t, 0.0, ILD_BAND, ITD_BAND))
        selected.append(bc.coherence_selected(t, 0.9, ILD_BAND, ITD_BAND))
        onset.append(bc.onset_weighted(t, ILD_BAND, ITD_BAND, 3.0))
    assert all(v < 0 for v in plain), plain  # the scene is hard: the plain ILD says "right"
    assert all(v[0] < 0 for v in unselected), unselected  # and so do all tiles, unselected
    assert all(v[0] > 0 for v in selected), selected  # coherent tiles: "left", the direct sound
    assert sum(v[1] > 0 for v in selected) >= 5, selected  # left ear leads
    assert all(v[0] > 0 for v in onset), onset


def test_tiles_measure_the_direct_sound_itd_and_follow_the_ears() -> None:
    bc = _cues()
    hrtf = Hrtf.load("kemar", FS)
    centres = bc.erb_space(300.0, 7000.0, 20)
    x = _direct(np.random.default_rng(0), hrtf.hrir(np.radians(60.0)).astype(np.float64))
    ild, itd = bc.coherence_selected(bc.tiles(x, FS, centres), 0.9, ILD_BAND, ITD_BAND)
    # KEMAR at 60°: ITD about 0.5 ms (Woodworth: 0.0875 m / 343 m/s (sin 60° + pi/3) = 0.49 ms)
    assert 300e-6 < itd < 800e-6, itd
    assert ild > 3.0, ild
    ild_m, itd_m = bc.coherence_selected(bc.tiles(x[:, ::-1], FS, centres), 0.9, ILD_BAND, ITD_BAND)
    assert np.isclose(ild_m, -ild) and np.isclose(itd_m, -itd)
