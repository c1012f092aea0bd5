"""16-bit PCM, the episode WAVs' sample format: one place that turns float audio into the
integers written to disk, and refuses to clip.

A float sample x becomes round(x * 32768). Full scale is reached at |q| >= 32767: a track that
gets there would be clipped (flattened peaks, harmonics that were never in the room), so it is
an error naming how much of the track is affected, never a silent `clip`. Features stored next
to a WAV are computed from `dequantise(quantise(x))`, exactly the samples a reader of the WAV
gets (soundfile reads PCM_16 as q / 32768).
"""

from __future__ import annotations

import numpy as np

SCALE = 32768.0
FULL_SCALE = 32767  # |q| at or beyond this is clipped


class ClippingError(ValueError):
    """A track exceeds 16-bit full scale; `str()` says how many samples and the peak."""


def quantise(audio: np.ndarray, what: str = "audio") -> np.ndarray:
    """float audio -> int16 samples, as written to the WAV; raises ClippingError instead of clipping."""
    x = np.asarray(audio, dtype=np.float64)
    if not np.isfinite(x).all():
        raise ClippingError(f"{what}: {int((~np.isfinite(x)).sum())} samples are NaN or infinite")
    q = np.rint(x * SCALE)
    over = np.abs(q) >= FULL_SCALE
    if over.any():
        peak = float(np.abs(x).max())
        raise ClippingError(
            f"{what}: {int(over.sum())} of {x.size} samples ({over.mean():.2%}) reach 16-bit full scale "
            f"(peak {peak:.3f}, {20 * np.log10(peak):+.1f} dBFS); refusing to clip"
        )
    return q.astype(np.int16)


def dequantise(q: np.ndarray) -> np.ndarray:
    """int16 samples -> float32, as any reader of the WAV gets them."""
    return (np.asarray(q, dtype=np.float32) / np.float32(SCALE)).astype(np.float32)


def as_written(audio: np.ndarray, what: str = "audio") -> np.ndarray:
    """The float track exactly as the WAV will hold it (quantised, checked for clipping)."""
    return dequantise(quantise(audio, what))


def clipped_samples(q: np.ndarray) -> int:
    """Samples of an int16 track at full scale: the mark clipping leaves."""
    return int((np.abs(np.asarray(q, dtype=np.int32)) >= FULL_SCALE).sum())
