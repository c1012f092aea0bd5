"""Statistical late reverberation: room absorption, coupled-room energy decay, tail synthesis.

Model (stated so it can be checked):
- Each room i has Eyring's equivalent absorption area per band,
  A_i = -S ln(1 - ā) + 4 m V, from its wall/floor/ceiling materials, furniture surfaces
  (upholstered sofas and beds by the floor area they cover, as seating is tabulated), soft
  furnishings (rugs replace floor, curtains wall absorption over their area), door panels
  and open doorways (an opening absorbs everything that hits it) and air absorption m;
  alone it decays with T = 24 ln10 V / (c A) (Eyring). The furnishings enter the late
  field only: the image sources keep the room's surface materials.
- Rooms exchange diffuse energy through their doorways (area S_ij times transmission τ_ij:
  1 open; closed leaf 10^(-closed_door_loss_db/10); partly open by the open share of the
  aperture). The diffuse energy per room follows the coupled-room balance
  (4 V_i / c) dE_i/dt = -A_i E_i + Σ_j S_ij τ_ij E_j, excited at t = 0 in the source room
  with the classical amount 16 π (1 - ā_s) (units where the direct sound at r metres has
  energy 1/r²). Its time integral is the steady reverberant level P = M⁻¹ b (16π/R in a
  single room), so source room > adjacent > far room; an adjacent room builds up and then
  decays with the coupled modes (double slope), a single room with Eyring's T.
- Near a doorway a receiver sees the neighbouring room's diffuse field through the opening:
  its diffuse energy is (1 - Σ h) E_room + Σ h E_neighbour, h = Ω / 4π × transmission, Ω the
  solid angle of the opening. On the doorway plane h = 1/2 from both sides, so the level is
  continuous from room to room. The neighbour's share is not isotropic: it is rendered from
  points spread over the opening (`types.ApertureTail`), so late sound that comes through a
  doorway is heard from the doorway.
- The tail of a response is band-split noise whose per-sample energy follows that E(t) from
  emission (so the late level falls with distance, as in Barron's revised theory), gated
  on at the first arrival in the receiver's room and weighted by the share of energy already
  scattered, 1 - (1 - s)^k with k = c t / mean free path the number of reflections so far;
  beyond the image-source order all energy counts as diffuse. This avoids counting the
  specular early reflections (kept by the image sources with the factor (1 - s) per
  reflection) twice.
- Noise is deterministic: a per-scene bank of independent band noises, read at an offset
  drawn from a hash of the quantised source and receiver positions.
"""

from __future__ import annotations

import hashlib
import math
from functools import lru_cache

import numpy as np

from echo_data import seeds
from echo_data.acoustics.geometry import RoomBox
from echo_data.acoustics.materials import BANDS, absorption, air_absorption, per_floor_area
from echo_data.acoustics.types import SPEED_OF_SOUND
from echo_data.floorplan import FloorPlan

_LN10 = math.log(10.0)


@lru_cache(maxsize=16)
def band_masks(n_fft: int, fs: int, power: bool) -> np.ndarray:
    """Octave-band masks (bands, n_fft//2+1) on an rfft grid around BANDS.

    Neighbouring bands cross over on a raised cosine half an octave wide centred on the band
    edge (the geometric mean of two centres), so that each band keeps its own decay inside
    its octave: amplitude-complementary (sum = 1, used for specular arrivals, so unit band
    gains give a clean impulse) or power-complementary (sum of squares = 1, used to split
    noise without changing its power).
    """
    f = np.fft.rfftfreq(n_fft, 1.0 / fs)
    lf = np.log2(np.maximum(f, 1e-3))
    lb = np.log2(BANDS)
    edges = 0.5 * (lb[:-1] + lb[1:])
    m = np.ones((len(BANDS), len(f)))
    for b in range(len(BANDS)):
        if b > 0:
            m[b] *= np.sin(0.5 * np.pi * np.clip((lf - edges[b - 1] + 0.25) / 0.5, 0.0, 1.0))
        if b + 1 < len(BANDS):
            m[b] *= np.cos(0.5 * np.pi * np.clip((lf - edges[b] + 0.25) / 0.5, 0.0, 1.0))
    out = m if power else m**2
    out.setflags(write=False)  # cached: shared by all callers
    return out


class RoomAcoustics:
    """Per-room absorption, decay times and the coupled-room energy balance of a plan."""

    def __init__(self, plan: FloorPlan, boxes: list[RoomBox], door_loss_db: float):
        nb, nr = len(BANDS), len(boxes)
        m_air = air_absorption()
        tau_closed = 10.0 ** (-door_loss_db / 10.0)
        self.transfer_share: dict[tuple[int, int], float] = {}  # (box, doorway) -> transmission
        self.volume = np.zeros(nr)
        self.surface = np.zeros(nr)
        self.alpha_sum = np.zeros((nr, nb))  # Σ S α
        self.transfer = np.zeros((nr, nr, nb))  # S_ij τ_ij
        self.tau_closed = tau_closed
        for i, box in enumerate(boxes):
            sx, sy, sz = box.size
            self.volume[i] = sx * sy * sz
            room = box.room
            walls = 2.0 * (sx + sy) * sz
            floor = ceil = sx * sy
            a = floor * absorption(room.floor_material) + ceil * absorption(room.ceiling_material)
            surf = walls + floor + ceil
            for op in box.openings:
                area = (op.u1 - op.u0) * op.height
                walls -= area
                if op.closed or op.openness < 1.0:
                    panel = np.maximum(absorption(op.door_material or "wooden_door"), tau_closed)
                else:
                    panel = np.ones(nb)
                share = op.openness
                a = a + area * (share + (1.0 - share) * panel)
                if op.other_room >= 0:
                    self.transfer[i, op.other_room] += area * (share + (1.0 - share) * tau_closed)
                self.transfer_share[(i, op.doorway)] = share + (1.0 - share) * tau_closed
            a = a + walls * absorption(room.wall_material)
            for f in plan.furniture:
                if f.room != room.index:
                    continue
                fx, fy, fz = f.size
                exposed = fx * fy + 2.0 * (fx + fy) * fz
                # upholstery (seating coefficients) absorbs per m^2 of floor it covers
                a = a + (fx * fy if per_floor_area(f.material) else exposed) * absorption(f.material)
                surf += exposed
            floor_alpha = absorption(room.floor_material)
            wall_alpha = absorption(room.wall_material)
            for fu in plan.furnishings:
                if fu.room != room.index:
                    continue
                # a rug covers floor, a curtain hangs in front of wall: it replaces their absorption
                under = floor_alpha if fu.kind == "rug" else wall_alpha
                a = a + fu.area * (absorption(fu.material) - under)
            self.surface[i] = surf
            self.alpha_sum[i] = a
        self.mean_alpha = np.clip(self.alpha_sum / self.surface[:, None], 1e-6, 0.99)
        # Eyring equivalent absorption area incl. air
        self.eq_area = -self.surface[:, None] * np.log1p(-self.mean_alpha) + 4.0 * m_air[None] * self.volume[:, None]
        self.t60 = 24.0 * _LN10 * self.volume[:, None] / (SPEED_OF_SOUND * self.eq_area)
        self.mean_free_path = 4.0 * self.volume / self.surface
        self._levels: dict[int, np.ndarray] = {}

    def _rhs(self, source_room: int) -> np.ndarray:
        """Diffuse energy injected by a unit source (rooms, bands)."""
        b = np.zeros(self.eq_area.shape)
        b[source_room] = 16.0 * math.pi * (1.0 - self.mean_alpha[source_room])
        return b

    def _matrix(self, b: int) -> np.ndarray:
        return np.diag(self.eq_area[:, b]) - self.transfer[:, :, b]

    def levels(self, source_room: int) -> np.ndarray:
        """Steady reverberant energy per room and band (rooms, bands) for a unit source."""
        if source_room not in self._levels:
            rhs = self._rhs(source_room)
            out = np.stack([np.linalg.solve(self._matrix(b), rhs[:, b]) for b in range(rhs.shape[1])], axis=1)
            self._levels[source_room] = np.maximum(out, 0.0)
        return self._levels[source_room]

    def energy_envelopes(self, source_room: int, fs: int, length: int) -> np.ndarray:
        """Diffuse energy per sample (rooms, bands, length) after an impulse at t = 0.

        Solves (4V/c) dE/dt = -M E by the eigenvectors of the symmetric D^½ M D^½
        (D = c / 4V; M is symmetric because S_ij τ_ij = S_ji τ_ji), so every mode decays.
        Scaled so that the sum over samples equals `levels`.
        """
        t = np.arange(length) / fs
        d = SPEED_OF_SOUND / (4.0 * self.volume)
        sq = np.sqrt(d)
        rhs = self._rhs(source_room)
        out = np.zeros((len(self.volume), rhs.shape[1], length))
        for b in range(rhs.shape[1]):
            lam, q = np.linalg.eigh(sq[:, None] * self._matrix(b) * sq[None, :])
            left = sq[:, None] * q  # (rooms, modes)
            coef = q.T @ (sq * rhs[:, b]) / fs  # (modes,)
            out[:, b] = left @ (coef[:, None] * np.exp(-np.maximum(lam, 1e-9)[:, None] * t[None]))
        return np.maximum(out, 0.0)


class NoiseBank:
    """Independent band-limited unit noises, fixed per scene, read at seeded offsets."""

    def __init__(self, fs: int, length: int, seed: int):
        n = 1 << int(math.ceil(math.log2(4 * length + 1)))
        rng = seeds.derived_rng(seeds.TAIL_NOISE, seed % (1 << 32))
        masks = band_masks(n, fs, power=True)
        white = rng.standard_normal((len(BANDS), n))
        self.bands = np.fft.irfft(np.fft.rfft(white, axis=1) * masks, n=n, axis=1)
        self.length = length
        self.span = n - length

    def segment(self, key: tuple[int, ...]) -> np.ndarray:
        """The (bands, length) noise for an integer key (e.g. quantised positions)."""
        h = hashlib.blake2b(np.asarray(key, dtype=np.int64).tobytes(), digest_size=8).digest()
        o = int.from_bytes(h, "little") % self.span
        return self.bands[:, o : o + self.length]


def scattered_share(t: np.ndarray, mfp: float, scattering: float, order: int) -> np.ndarray:
    """Share of the diffuse energy not yet represented by specular image sources at times t."""
    k = SPEED_OF_SOUND * t / mfp
    return 1.0 - (1.0 - scattering) ** k * np.clip(order + 1.0 - k, 0.0, 1.0)
