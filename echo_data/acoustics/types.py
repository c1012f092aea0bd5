"""The hand-over between the geometric acoustics (room model, paths) and the binaural renderer.

`echo_data.acoustics.room` turns a `FloorPlan` into `AcousticResponse`s (what arrives at an
omnidirectional point receiver, and from which directions); `echo_data.acoustics.binaural`
turns a response plus a head yaw into a two-ear impulse response with the HRTF.
"""

from __future__ import annotations

from dataclasses import dataclass, field

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


@dataclass(frozen=True)
class ApertureTail:
    """Late energy of a neighbouring room heard through an opening: an extended source.

    `signals[k]` (independent noises under the neighbour's decay envelope) arrives from world
    direction `directions[k]` (points spread over the opening as seen from the receiver).
    """

    directions: np.ndarray  # (k, 3) unit vectors, world frame, receiver -> point in the opening
    signals: np.ndarray  # (k, n) float32, aligned to t = 0


@dataclass
class AcousticResponse:
    """The response from one source to one receiver position, independent of head orientation."""

    fs: int
    arrivals: list[Arrival]  # early, directional part
    tail: np.ndarray  # (n,) float32 diffuse late part of the receiver's own room, aligned to t = 0
    length: int  # samples of the full response (RIR length)
    # seed of this receiver position's diffuse-field realisation (plane-wave directions,
    # signs, delays): a diffuse field differs from place to place, see `hrtf.Hrtf.diffuse_field`
    field_seed: int = 0
    apertures: list[ApertureTail] = field(default_factory=list)  # directional late parts through openings
