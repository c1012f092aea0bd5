"""The playback gain of a video's sound track: the dataset's WAVs are calibrated (a sample of
1.0 is `acoustics.full_scale_db_spl`, 120 dB SPL by default), so a room-level episode plays at
about -28 dBFS peak and -47 dBFS RMS, barely audible on a laptop. A video raises it to a
listenable level and says so on screen; the dataset's files never change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TARGET_PEAK_DBFS = -1.0  # headroom left for the AAC encoder
TARGET_RMS_DBFS = -20.0  # about the loudness of spoken-word media (EBU R128 programmes sit near -23 LUFS)


def _dbfs(x: float) -> float:
    return 20.0 * math.log10(max(x, 1e-12))


@dataclass(frozen=True)
class Listening:
    """How a calibrated track is played back: the gain and the levels it comes from."""

    gain_db: float  # whole decibels applied for playback
    peak_dbfs: float  # the track as stored
    rms_dbfs: float
    full_scale_db_spl: float

    def apply(self, track: np.ndarray) -> np.ndarray:
        """The track at the playback gain (float32)."""
        return (np.asarray(track, dtype=np.float32) * np.float32(10.0 ** (self.gain_db / 20.0))).astype(np.float32)

    def note(self) -> str:
        """The on-screen statement of level and calibration."""
        fs = self.full_scale_db_spl
        return (
            f"sound played {self.gain_db:+.0f} dB above the dataset's calibrated WAV (full scale = {fs:g} dB SPL): "
            f"as recorded {fs + self.peak_dbfs:.0f} dB SPL peak, {fs + self.rms_dbfs:.0f} dB SPL RMS"
        )


def listening(track: np.ndarray, full_scale_db_spl: float) -> Listening:
    """The gain (rounded down to whole dB) bringing the track's RMS to TARGET_RMS_DBFS, or its
    peak to TARGET_PEAK_DBFS where that comes first."""
    x = np.asarray(track, dtype=np.float64)
    peak = _dbfs(float(np.abs(x).max())) if x.size else -240.0
    rms = _dbfs(float(np.sqrt(np.mean(x * x)))) if x.size else -240.0
    gain = math.floor(min(TARGET_RMS_DBFS - rms, TARGET_PEAK_DBFS - peak))
    return Listening(float(gain), peak, rms, float(full_scale_db_spl))
