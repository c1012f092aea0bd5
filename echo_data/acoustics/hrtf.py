"""Head-related impulse responses: measured MIT KEMAR (shipped npz) or a spherical-head model.

Head frame (used by everything that asks for an HRIR): x = nose, y = left ear, z = up;
azimuth counter-clockwise from the nose (90 deg = left), elevation up from the horizontal
plane; channel 0 = left ear. Both kinds are tabulated on a fixed set of directions so the
binaural renderer can precompute per-direction kernels; `hrir()` returns the nearest entry
(KEMAR: 710 measured directions, elevations -40..90 deg, so lower sources get the -40 deg row;
sphere: a 5 deg grid over the whole sphere).

Both tables are diffuse-field power normalised (mean energy over directions and ears = 1), so
the early (HRIR-filtered) and late (diffuse-field) parts of a binaural response, and the two
kinds, have comparable levels; the KEMAR set is also diffuse-field equalised (flat average
over directions, see `_diffuse_equalise`), so calibrated levels hold across frequency.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
import scipy.fft as sfft
from scipy.signal import resample_poly
from scipy.spatial import cKDTree

from echo_data import seeds
from echo_data.acoustics.types import SPEED_OF_SOUND

KEMAR_NPZ = Path(__file__).resolve().parents[2] / "assets" / "hrtf" / "mit_kemar.npz"

HEAD_RADIUS = 0.0875  # m, Brown & Duda's average adult head
_SPHERE_ALPHA_MIN = 0.1  # Brown & Duda head-shadow: strongest high-frequency cut ...
_SPHERE_THETA_MIN = np.deg2rad(150.0)  # ... at this angle from the ear axis
_SPHERE_LEAD = 8  # samples of lead before the earliest ear delay (room for fractional-delay ringing)
_SPHERE_TAPS = 64
_DIFFUSE_SPREAD_S = 0.010  # decorrelation filters spread the directions' HRIRs over 10 ms
_DIFFUSE_WAVES = 128  # plane waves per diffuse-field realisation
_KEEP_DRAWS = 32  # diffuse-field realisations kept per table (one per receiver cell)
_EQ_EXTRA_TAPS = 96  # the diffuse-field equaliser lengthens KEMAR HRIRs by this much


def direction_vectors(azimuth_rad: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray:
    """Unit vectors (n, 3) in the head frame for azimuth/elevation in radians."""
    az = np.asarray(azimuth_rad, dtype=np.float64)
    el = np.asarray(elevation_rad, dtype=np.float64)
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)


class Hrtf:
    """A tabulated HRTF at one sample rate: `table[k]` is the (taps, 2) HRIR for `directions[k]`."""

    def __init__(self, kind: str, fs: int, table: np.ndarray, directions: np.ndarray, delay_s: float) -> None:
        self.kind = kind
        self.fs = int(fs)
        self.table = np.ascontiguousarray(table, dtype=np.float32)  # (n_dirs, taps, 2)
        self.directions = np.ascontiguousarray(directions, dtype=np.float64)  # (n_dirs, 3) unit
        self.delay_s = float(delay_s)  # head-centre latency inside every HRIR: the frontal response's onset
        self._spec: tuple[np.ndarray, int] | None = None
        self._draws: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        self._padded: dict[tuple[int, int], np.ndarray] = {}  # (n_fft, direction) -> HRIR spectrum
        self._tree = cKDTree(self.directions)  # Euclidean nearest on the unit sphere = largest dot product
        self.table.setflags(write=False)
        self.directions.setflags(write=False)

    @property
    def taps(self) -> int:
        return int(self.table.shape[1])

    @staticmethod
    def load(kind: Literal["kemar", "sphere"], fs: int) -> Hrtf:
        """The HRTF of `kind` at sample rate `fs` (memoised: one table per process)."""
        return _load(str(kind), int(fs))

    def nearest(self, vectors: np.ndarray) -> np.ndarray:
        """Index of the tabulated direction nearest to each head-frame vector (..., 3)."""
        v = np.asarray(vectors, dtype=np.float64)
        v = v / np.linalg.norm(v, axis=-1, keepdims=True)
        return self._tree.query(v)[1]

    def spectra_at(self, idx: np.ndarray, n_fft: int) -> np.ndarray:
        """(len(idx), n_fft // 2 + 1, 2) complex128: `scipy.fft.rfft` of the HRIRs of directions
        `idx`, zero-padded to `n_fft`; each direction's is computed once and kept (the openings
        of a scene are heard from a few directions at many head yaws)."""
        keys = [(int(n_fft), int(i)) for i in np.asarray(idx).ravel()]
        todo = sorted({k[1] for k in keys if k not in self._padded})
        if todo:
            spec = sfft.rfft(self.table[todo].astype(np.float64), n_fft, axis=1)
            for i, row in zip(todo, spec):
                self._padded[(int(n_fft), i)] = row
        return np.stack([self._padded[k] for k in keys])

    def hrir(self, azimuth_rad: float, elevation_rad: float = 0.0) -> np.ndarray:
        """(taps, 2) float32 HRIR for a head-relative direction (nearest tabulated one)."""
        k = int(self.nearest(direction_vectors(np.array(azimuth_rad), np.array(elevation_rad))))
        return self.table[k].copy()

    @property
    def diffuse_taps(self) -> int:
        """Length of the decorrelation filters of `diffuse_field`."""
        return int(round(_DIFFUSE_SPREAD_S * self.fs)) + self.taps

    def diffuse_field(self, seed: int, head_yaws: Sequence[float] | np.ndarray) -> np.ndarray:
        """(len(head_yaws), diffuse_taps, 2) float32 filter pairs: a mono diffuse tail -> two ears.

        A diffuse field at one place is a sum of plane waves from all directions with random
        phases. Here `_DIFFUSE_WAVES` world-frame directions (uniform on the sphere), signs and
        delays (0-10 ms) are drawn from `seed` (one seed per receiver position), and each wave
        reaches each ear through the HRIR of its direction relative to a head at that world
        yaw. So the interaural differences at one frequency change from place to place and
        as the head turns, averaging to zero, while their statistics (the interaural
        coherence: high at low frequencies, low above ~1 kHz) are those of the HRTF set's
        diffuse field. One gain for both ears sets the mean ear energy to 1 (the level of the
        tail is preserved; a realisation keeps its own small broadband left/right imbalance).
        """
        z, phi, rho, phase = self._diffuse_draw(int(seed))
        spec_table, n_fft = self._spectra()
        out = np.empty((len(head_yaws), self.diffuse_taps, 2), dtype=np.float32)
        for i, yaw in enumerate(head_yaws):
            rel = phi - float(yaw)  # world azimuth -> head azimuth
            idx = self.nearest(np.stack([rho * np.cos(rel), rho * np.sin(rel), z], axis=-1))
            spec = np.einsum("kf,kfc->fc", phase, spec_table[idx])
            ir = np.fft.irfft(spec, n_fft, axis=0)[: self.diffuse_taps]
            out[i] = ir / np.sqrt((ir**2).sum(axis=0).mean())
        return out

    def _diffuse_draw(self, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The yaw-independent part of a realisation: directions (z, azimuth, horizontal radius) and
        each wave's sign x delay as a phase per frequency. The last few are kept: a receiver's
        RIRs are asked for one head-yaw bin at a time."""
        hit = self._draws.get(seed)
        if hit is None:
            rng = seeds.derived_rng(seeds.DIFFUSE_NOISE, seed % (1 << 63))
            z = rng.uniform(-1.0, 1.0, _DIFFUSE_WAVES)
            phi = rng.uniform(0.0, 2 * np.pi, _DIFFUSE_WAVES)
            signs = rng.choice(np.array([-1.0, 1.0]), size=_DIFFUSE_WAVES)
            spread = int(round(_DIFFUSE_SPREAD_S * self.fs))
            delays = rng.integers(0, spread, size=_DIFFUSE_WAVES)
            spec_table, n_fft = self._spectra()
            f = np.arange(spec_table.shape[1])
            phase = signs[:, None] * np.exp(-2j * np.pi * f[None, :] * delays[:, None] / n_fft)  # (K, F)
            hit = self._draws[seed] = (z, phi, np.sqrt(1.0 - z * z), phase)
            while len(self._draws) > _KEEP_DRAWS:
                del self._draws[next(iter(self._draws))]
        return hit

    def diffuse_coherence(self, freqs: np.ndarray) -> np.ndarray:
        """Real interaural coherence of a diffuse field at `freqs` (Hz): the cross-spectrum of the
        two ears summed over all tabulated directions, over the geometric mean of their powers
        (near 1 at low frequencies, falling to about 0 above ~1.5 kHz)."""
        spec, n_fft = self._spectra()
        cross = (spec[..., 0] * np.conj(spec[..., 1])).sum(axis=0).real
        power = np.sqrt((np.abs(spec[..., 0]) ** 2).sum(axis=0) * (np.abs(spec[..., 1]) ** 2).sum(axis=0))
        grid = np.fft.rfftfreq(n_fft, 1.0 / self.fs)
        return np.interp(np.asarray(freqs, dtype=np.float64), grid, cross / np.maximum(power, 1e-30))

    def _spectra(self) -> tuple[np.ndarray, int]:
        """rfft of every tabulated HRIR, zero-padded for the diffuse filters (cached)."""
        if self._spec is None:
            n_fft = 1 << int(np.ceil(np.log2(self.diffuse_taps)))
            self._spec = (np.fft.rfft(self.table.astype(np.float64), n_fft, axis=1), n_fft)
        return self._spec


@functools.lru_cache(maxsize=8)
def _load(kind: str, fs: int) -> Hrtf:
    if kind == "kemar":
        return _kemar(fs)
    if kind == "sphere":
        return _sphere(fs)
    raise ValueError(f"unknown HRTF kind {kind!r} (use 'kemar' or 'sphere')")


def _diffuse_normalise(table: np.ndarray) -> np.ndarray:
    return table / np.sqrt((table.astype(np.float64) ** 2).sum(axis=1).mean())


def _kemar(fs: int) -> Hrtf:
    """MIT KEMAR from the converted npz (16 kHz), resampled when another rate is asked for."""
    if not KEMAR_NPZ.is_file():
        raise FileNotFoundError(f"{KEMAR_NPZ} is missing; regenerate it with scripts/convert_kemar.py")
    with np.load(KEMAR_NPZ) as z:
        table = z["hrir"].astype(np.float64)
        az = np.deg2rad(z["azimuth_deg"].astype(np.float64))
        el = np.deg2rad(z["elevation_deg"].astype(np.float64))
        fs_data = int(z["fs"])
    if fs != fs_data:
        g = int(np.gcd(fs, fs_data))
        table = resample_poly(table, fs // g, fs_data // g, axis=1)
    table = _diffuse_normalise(_diffuse_equalise(table, fs))
    front = int(np.argmin(np.abs(np.angle(np.exp(1j * az))) + np.abs(el)))
    return Hrtf("kemar", fs, table, direction_vectors(az, el), _onset_s(table[front], fs))


def _diffuse_equalise(table: np.ndarray, fs: int) -> np.ndarray:
    """Divide every HRIR by the set's diffuse-field magnitude response (minimum phase).

    The MIT KEMAR "full" responses include the measuring loudspeaker's response: averaged over
    all directions and both ears they are 14-20 dB down at 100-500 Hz and +3 dB at 2-3 kHz.
    A head barely changes sound pressure at low frequencies, so the diffuse-field average
    of a head's HRTFs is close to flat there; equalising it (the processing of MIT's own
    "diffuse" set) makes calibrated levels hold across frequency. The correction is the
    1/3-octave-smoothed inverse average, limited to ±20 dB and held below 100 Hz, realised
    as a minimum-phase filter (no pre-ringing, onsets kept), `_EQ_EXTRA_TAPS` longer.
    """
    n_fft = 4096
    taps = table.shape[1]
    spec = np.fft.rfft(table, n_fft, axis=1)
    power = (np.abs(spec) ** 2).mean(axis=(0, 2))
    f = np.fft.rfftfreq(n_fft, 1.0 / fs)
    fc = np.maximum(f, 100.0)
    c = np.concatenate([[0.0], np.cumsum(power)])
    lo = np.searchsorted(f, fc * 2 ** (-1 / 6))
    hi = np.maximum(np.searchsorted(f, fc * 2 ** (1 / 6), side="right"), lo + 1)
    smooth = (c[hi] - c[lo]) / (hi - lo)
    gain_db = np.clip(-10.0 * np.log10(smooth / smooth.max()), 0.0, 40.0)
    gain_db = np.minimum(gain_db, gain_db.min() + 20.0)
    cep = np.fft.irfft(np.log(10.0 ** (gain_db / 20.0)), n_fft)
    cep[1 : n_fft // 2] *= 2.0
    cep[n_fft // 2 + 1 :] = 0.0
    eq = np.exp(np.fft.rfft(cep, n_fft))  # minimum phase with that magnitude
    out = np.fft.irfft(spec * eq[None, :, None], n_fft, axis=1)[:, : taps + _EQ_EXTRA_TAPS]
    fade = np.cos(0.5 * np.pi * np.arange(1, 33) / 32) ** 2
    out[:, -32:] *= fade[None, :, None]
    return out


def _onset_s(ir2: np.ndarray, fs: int) -> float:
    """Mean over both ears of the first crossing of 20 % of the peak (sub-sample, linear)."""
    times = []
    for c in range(ir2.shape[1]):
        x = np.abs(ir2[:, c])
        thr = 0.2 * x.max()
        n = int(np.argmax(x >= thr))
        frac = 0.0 if n == 0 else (thr - x[n - 1]) / (x[n] - x[n - 1])
        times.append((n - 1 + frac) / fs if n else 0.0)
    return float(np.mean(times))


def _sphere_directions() -> np.ndarray:
    """A regular grid: elevation every 5 deg, azimuth every ~5 deg scaled by cos(elevation)."""
    vecs = []
    for el in np.deg2rad(np.arange(-90.0, 90.1, 5.0)):
        n = max(1, int(round(72 * np.cos(el))))
        az = np.arange(n) * (2 * np.pi / n)
        vecs.append(direction_vectors(az, np.full(n, el)))
    return np.concatenate(vecs)


def sphere_hrir_table(vectors: np.ndarray, fs: int, taps: int = _SPHERE_TAPS) -> np.ndarray:
    """Brown & Duda (1998) spherical-head HRIRs (n, taps, 2) for head-frame unit vectors.

    Per ear: Woodworth's delay around a rigid sphere of radius 8.75 cm, and the one-pole /
    one-zero head-shadow filter (1 + j a w / 2w0) / (1 + j w / 2w0), w0 = c / r, whose
    high-frequency gain a goes from 2 (+6 dB) facing the ear to 0.1 at 150 deg from it.
    Realised by frequency sampling on a long grid, truncated to `taps` with a short taper.
    """
    vectors = np.atleast_2d(np.asarray(vectors, dtype=np.float64))
    n_fft = 1024
    w = 2 * np.pi * np.fft.rfftfreq(n_fft, 1.0 / fs)
    w0 = SPEED_OF_SOUND / HEAD_RADIUS
    out = np.empty((len(vectors), taps, 2))
    taper = np.ones(taps)
    taper[-16:] = 0.5 * (1 + np.cos(np.linspace(0, np.pi, 16)))
    for ear, axis in ((0, np.array([0.0, 1.0, 0.0])), (1, np.array([0.0, -1.0, 0.0]))):
        theta = np.arccos(np.clip(vectors @ axis, -1.0, 1.0))  # angle from this ear's axis
        alpha = (1 + _SPHERE_ALPHA_MIN / 2) + (1 - _SPHERE_ALPHA_MIN / 2) * np.cos(theta / _SPHERE_THETA_MIN * np.pi)
        delay = np.where(
            theta < np.pi / 2, -np.cos(theta), theta - np.pi / 2
        ) * HEAD_RADIUS / SPEED_OF_SOUND  # Woodworth, relative to the head centre
        delay = delay + HEAD_RADIUS / SPEED_OF_SOUND + _SPHERE_LEAD / fs
        shadow = (1 + 1j * alpha[:, None] * w / (2 * w0)) / (1 + 1j * w / (2 * w0))
        spec = shadow * np.exp(-1j * w * delay[:, None])
        out[:, :, ear] = np.fft.irfft(spec, n_fft, axis=1)[:, :taps] * taper
    return out


def _sphere(fs: int) -> Hrtf:
    dirs = _sphere_directions()
    table = _diffuse_normalise(sphere_hrir_table(dirs, fs))
    front = int(np.argmax(dirs[:, 0]))
    return Hrtf("sphere", fs, table, dirs, _onset_s(table[front], fs))
