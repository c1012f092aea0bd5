"""Calibrated sound levels: what each source emits, and how pressure becomes WAV samples.

Everything the renderer produces is linear in the dry input, and the direct sound at 1 m has
gain 1 (1/r spreading, diffuse-field normalised HRIRs), so a dry signal scaled to pascals at
1 m yields ear signals in pascals. A source's level is its maximum RMS over 125 ms windows
(the F time weighting of a sound level meter, unweighted), in dB re 20 µPa at 1 m.

Source levels (dB SPL at 1 m, drawn per event): `echo_data.categories.SOURCE_LEVELS_DB`, with their
basis; `EpisodeSpec` carries each event's draw.

Full scale: a WAV sample of ±1 is ±`full_scale_db_spl` (default 120 dB SPL, i.e. 20 Pa peak);
the loudest source at 30 cm peaks well below it. A track that would still exceed full scale
is an error (`ClippingError`), never clipped silently.
"""

from __future__ import annotations

import math

import numpy as np

from echo_data.categories import SOURCE_LEVELS_DB
from echo_data.pcm import ClippingError  # one error for "would clip", owned by pcm

P_REF = 20e-6  # Pa, 0 dB SPL
LEVEL_WINDOW_S = 0.125  # F time weighting


def level_db(x: np.ndarray, fs: int, periodic: bool = True) -> float:
    """Maximum RMS over 125 ms windows of a pressure signal (Pa), in dB SPL.

    `periodic`: `x` is one loop period (windows wrap around)."""
    x = np.asarray(x, dtype=np.float64).ravel()
    n = max(1, int(round(LEVEL_WINDOW_S * fs)))
    if periodic and len(x) > 0:
        x = np.concatenate([x, x[: n - 1]] if len(x) >= n else [np.resize(x, 2 * n)])
    if len(x) < n:
        n = len(x)
    c = np.concatenate([[0.0], np.cumsum(x * x)])
    ms = (c[n:] - c[:-n]) / n
    peak = float(ms.max()) if len(ms) else 0.0
    return 10.0 * math.log10(max(peak, 1e-30) / P_REF**2)


def pascal_gain(loop: np.ndarray, fs: int, level: float) -> float:
    """Factor that turns a dry loop (any units) into pascals at 1 m with the given level."""
    return 10.0 ** ((level - level_db(loop, fs)) / 20.0)


def full_scale_pa(full_scale_db_spl: float) -> float:
    """Pressure (Pa) that a WAV sample of 1.0 stands for."""
    return P_REF * 10.0 ** (full_scale_db_spl / 20.0)


def to_full_scale(track_pa: np.ndarray, full_scale_db_spl: float, what: str = "track") -> np.ndarray:
    """float32 samples of a pressure track at the stated calibration; `ClippingError` if any
    sample reaches full scale (16-bit PCM stores at most 32767/32768)."""
    y = np.asarray(track_pa, dtype=np.float64) / full_scale_pa(full_scale_db_spl)
    peak = float(np.abs(y).max()) if y.size else 0.0
    if peak >= 32767.0 / 32768.0:
        over = 20.0 * math.log10(peak)
        raise ClippingError(
            f"{what}: peak {over:+.1f} dBFS at full scale = {full_scale_db_spl:g} dB SPL would clip; "
            "raise acoustics.full_scale_db_spl"
        )
    return y.astype(np.float32)


def calibration_record(full_scale_db_spl: float, noise_floor_dba: float) -> dict[str, object]:
    """What a dataset states about its audio levels (manifest)."""
    return {
        "full_scale_db_spl": float(full_scale_db_spl),
        "full_scale_pa": full_scale_pa(full_scale_db_spl),
        "noise_floor_dba": float(noise_floor_dba),
        "source_levels_db_spl_at_1m": {k: list(v) for k, v in SOURCE_LEVELS_DB.items()},
        "level_definition": "max RMS over 125 ms windows, unweighted, re 20 uPa, free field at 1 m; drawn uniformly per event",
    }
