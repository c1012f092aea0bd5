"""The binaural sound a step row refers to, read straight from the episode WAV.

Each step row carries `audio_path` (relative to the dataset root), `audio_sample_rate` and
`audio_offset` (the sample at which the step's observation is taken), so a user can reach
the sound without knowing the layout; this reads only the samples asked for.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np


def binaural_window(root: str | Path, row: Mapping[str, Any], seconds: float = 1.0) -> np.ndarray:
    """The `seconds` of binaural audio heard up to a step: samples [offset - n, offset) of its
    episode WAV as float32 (n, 2), channel 0 = left, zeros before the recording starts (the
    same window the step's spectrogram was computed from when `seconds` is 1).

    `row` is a step row (dict from `datasets`, `StepDataset` or pyarrow) with `audio_path`,
    `audio_sample_rate` and `audio_offset`."""
    import soundfile as sf

    def scalar(v: Any) -> Any:
        return v.item() if hasattr(v, "item") else v

    sr = int(scalar(row["audio_sample_rate"]))
    offset = int(scalar(row["audio_offset"]))
    n = int(round(seconds * sr))
    if n <= 0:
        raise ValueError(f"seconds must be positive, got {seconds}")
    path = Path(root) / str(scalar(row["audio_path"]))
    with sf.SoundFile(path) as f:
        if f.samplerate != sr:
            raise ValueError(f"{path}: sample rate {f.samplerate}, the step row says {sr}")
        lo, hi = max(offset - n, 0), min(offset, f.frames)
        out = np.zeros((n, f.channels), dtype=np.float32)
        if hi > lo:
            f.seek(lo)
            out[n - (offset - lo) : n - (offset - hi)] = f.read(hi - lo, dtype="float32", always_2d=True)
    return out
