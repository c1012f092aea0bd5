"""Reverberation of generated homes, measured the way rooms are measured: band T30 of RIRs.

Used by `scripts/plot_t30.py` (the picture in docs/) and the furnished-homes test.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy import signal

from echo_data.acoustics.room import AcousticScene, omni_rir
from echo_data.recipe import AcousticsConfig, Recipe
from echo_data.scene.generate import generate_floorplan_from_seed

CORRIDOR_WIDTH = 2.0  # m: a hall narrower than this is a corridor (scene/layouts.HALL_WIDTH: 1.0-1.4 m)


def band_t30(h: np.ndarray, fs: int, fc: float) -> float:
    """T30 (s) of an octave band: Schroeder backward integral, line fit from -5 to -35 dB."""
    sos = signal.butter(3, [fc / np.sqrt(2), min(fc * np.sqrt(2), 0.45 * fs)], btype="band", fs=fs, output="sos")
    x = signal.sosfiltfilt(sos, np.asarray(h, dtype=np.float64))
    edc = np.cumsum((x**2)[::-1])[::-1]
    db = 10 * np.log10(edc / edc[0] + 1e-30)
    i5, i35 = int(np.argmax(db <= -5)), int(np.argmax(db <= -35))
    t = np.arange(len(x)) / fs
    return float(-60.0 / np.polyfit(t[i5:i35], db[i5:i35], 1)[0])


def room_t30s(
    recipe: Recipe,
    seeds: Sequence[int],
    cfg: AcousticsConfig,
    bands: Sequence[float],
    t30: Callable[[np.ndarray, int, float], float] = band_t30,
) -> tuple[np.ndarray, np.ndarray]:
    """(room kinds (n,), T30 (n, bands)) over every room of the plans of `seeds`: an omni RIR
    from a source 2/5 of the way across the room at 1.0 m to a receiver 3/5 across at 1.2 m.

    A hall narrower than CORRIDOR_WIDTH is reported as kind "corridor": the surveys the T30
    targets come from measured living rooms and bedrooms, not corridors (docs/acoustics.md)."""
    kinds, out = [], []
    for seed in seeds:
        plan = generate_floorplan_from_seed(recipe, int(seed))
        scene = AcousticScene(plan, cfg)
        for room in plan.rooms:
            r = room.rect
            src = (r.xmin + 0.4 * (r.xmax - r.xmin), r.ymin + 0.4 * (r.ymax - r.ymin), 1.0)
            rcv = (r.xmin + 0.65 * (r.xmax - r.xmin), r.ymin + 0.6 * (r.ymax - r.ymin), 1.2)
            h = omni_rir(scene.response(src, rcv))
            kinds.append("corridor" if room.kind == "hall" and min(r.size) < CORRIDOR_WIDTH else room.kind)
            out.append([t30(h, cfg.sample_rate, fc) for fc in bands])
    return np.asarray(kinds), np.asarray(out)
