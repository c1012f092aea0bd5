"""Per-octave-band surface and air absorption, taken from pyroomacoustics' database.

Everything the acoustic scene needs about materials is reduced to arrays over
`BAND_CENTERS` (125 Hz … 8 kHz), so the geometry code can multiply them without
knowing where they came from.
"""

from __future__ import annotations

from functools import cache, lru_cache

import numpy as np
import pyroomacoustics as pra

from echo_data.acoustics.types import BAND_CENTERS

BANDS = np.asarray(BAND_CENTERS, dtype=np.float64)


def _to_bands(coeffs: list[float], freqs: list[float]) -> np.ndarray:
    """Interpolate coefficients given at `freqs` onto BANDS in log-frequency, holding the
    end values (several database entries stop at 4 kHz)."""
    return np.interp(np.log2(BANDS), np.log2(np.asarray(freqs, dtype=np.float64)), np.asarray(coeffs, dtype=np.float64))


@cache
def _absorption_cached(name: str) -> tuple[float, ...]:
    try:
        mat = pra.Material(name)
    except KeyError:
        raise ValueError(f"unknown acoustic material {name!r} (not in pyroomacoustics' materials database)") from None
    ea = mat.energy_absorption
    a = _to_bands(ea["coeffs"], ea["center_freqs"])
    # A perfectly absorbing surface would make log(1 - alpha) infinite in Eyring's formula.
    return tuple(float(v) for v in np.clip(a, 0.0, 0.99))


@lru_cache(maxsize=1)
def _per_floor_area_names() -> frozenset[str]:
    cats = pra.materials_data["absorption"]
    return frozenset(n for c, entries in cats.items() if c.startswith(("Seating", "Audience")) for n in entries)


def per_floor_area(name: str) -> bool:
    """Whether the database gives `name`'s absorption per m^2 of floor it covers (seating and
    audience entries: the coefficient already includes the seats' backs and sides), rather
    than per m^2 of its own surface."""
    return name in _per_floor_area_names()


def absorption(name: str) -> np.ndarray:
    """Energy absorption coefficient per band of a named pyroomacoustics material."""
    return np.asarray(_absorption_cached(name))


@lru_cache(maxsize=1)
def _air_cached() -> tuple[float, ...]:
    air = pra.parameters.Physics().get_air_absorption()  # 20 °C, 50 % RH
    return tuple(float(v) for v in _to_bands(air["coeffs"], air["center_freqs"]))


def air_absorption() -> np.ndarray:
    """Air attenuation per band as an energy coefficient m (1/m): energy falls as exp(-m d)."""
    return np.asarray(_air_cached())


def reflection_amplitude(alpha: np.ndarray, scattering: float) -> np.ndarray:
    """Amplitude factor per band of one *specular* reflection.

    The energy that is neither absorbed (alpha) nor scattered (s) stays specular:
    (1 - alpha)(1 - s). The scattered share is not lost: it feeds the diffuse tail.
    """
    return np.sqrt((1.0 - alpha) * (1.0 - scattering))
