"""The hand-over between the geometric acoustics (room model, paths) and the binaural renderer.

`echo_data.acoustics.room` turns a `FloorPlan` into `AcousticResponse`s (what arrives at an
omnidirectional point receiver, and from which directions); `echo_data.acoustics.binaural`
turns a response plus a head yaw into a two-ear impulse response with the HRTF.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Octave-band centre frequencies (Hz) used for per-band gains; matches pyroomacoustics' default.
BAND_CENTERS: tuple[float, ...] = (125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0)
SPEED_OF_SOUND = 343.0


@dataclass(frozen=True)
class Arrival:
    """One specular path (direct sound or an image source) reaching the receiver."""

    delay_s: float  # propagation time, path length / SPEED_OF_SOUND
    direction: tuple[float, float, float]  # unit vector, world frame, from the receiver towards the arrival
    gain: float  # broadband amplitude including 1/r spreading (and any door/leak loss)
    band_gains: tuple[float, ...]  # per BAND_CENTERS multiplier (wall/air absorption), 1.0 = none
    order: int  # 0 = direct path, n = n reflections; -1 = leak path through a closed door


@dataclass
class AcousticResponse:
    """The response from one source to one receiver position, independent of head orientation."""

    fs: int
    arrivals: list[Arrival]  # early, directional part
    tail: np.ndarray  # (n,) float32 diffuse late part, aligned to t = 0 (zeros before it starts)
    length: int  # samples of the full response (RIR length)
