"""Binaural room impulse responses: an `AcousticResponse` heard by a head with a given yaw.

Each early `Arrival` becomes, per ear, gain x (per-band filter) x HRIR(direction relative to
the head), placed at its delay. The per-band filter is a weighted sum of fixed zero-phase band
basis filters (one per `BAND_CENTERS` entry, triangles in log-frequency that sum to exactly 1),
so the per-arrival work is a 7-term weighted sum of precomputed per-direction kernels rather
than a convolution. Delays are resolved to 1/4 sample (fractional-delay basis filters), and
the HRIRs' own head-centre latency is removed so that an arrival at `delay_s` is centred on
`delay_s` at the head centre (ITD splits around it). The receiver room's diffuse tail goes
to both ears through a diffuse-field realisation of the HRTF drawn per receiver position and
rendered at the head's yaw (`Hrtf.diffuse_field`: level preserved, interaural coherence that
of a diffuse field, interaural differences that change with place and head orientation).
Late energy of a neighbouring room seen through an opening (`ApertureTail`) comes from the
opening's directions.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import scipy.fft as sfft

from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.types import BAND_CENTERS, AcousticResponse, ApertureTail

BAND_TAPS = 63  # length of the zero-phase band basis filters (centre tap 31)
SUBSAMPLE = 4  # arrival delays are rendered to 1/SUBSAMPLE of a sample


def band_weights(freqs: np.ndarray) -> np.ndarray:
    """(n_bands, len(freqs)) interpolation weights: triangles in log2(f) between band centres.

    Below the first centre and above the last the end band's weight is 1; the weights sum to 1
    at every frequency, so unit band gains give an exact pass-through.
    """
    lc = np.log2(np.asarray(BAND_CENTERS))
    lf = np.log2(np.maximum(np.asarray(freqs, dtype=np.float64), 1e-3))
    lf = np.clip(lf, lc[0], lc[-1])
    w = np.zeros((len(lc), len(lf)))
    for b in range(len(lc)):
        if b > 0:
            m = (lf >= lc[b - 1]) & (lf <= lc[b])
            w[b, m] = (lf[m] - lc[b - 1]) / (lc[b] - lc[b - 1])
        if b < len(lc) - 1:
            m = (lf >= lc[b]) & (lf < lc[b + 1])
            w[b, m] = (lc[b + 1] - lf[m]) / (lc[b + 1] - lc[b])
    w[-1, lf >= lc[-1]] = 1.0
    return w


def band_basis(fs: int) -> np.ndarray:
    """(SUBSAMPLE, n_bands, BAND_TAPS) band filters, each delayed by 31 + p / SUBSAMPLE samples.

    Frequency-sampled from `band_weights`, windowed by a Hann window centred on the (fractional)
    delay; the bands of one phase p sum to a windowed fractional-delay sinc.
    """
    n_fft = 4096
    f = np.fft.rfftfreq(n_fft, 1.0 / fs)
    w = band_weights(f)
    centre = (BAND_TAPS - 1) // 2
    n = np.arange(BAND_TAPS)
    out = np.empty((SUBSAMPLE, len(BAND_CENTERS), BAND_TAPS))
    for p in range(SUBSAMPLE):
        d = centre + p / SUBSAMPLE
        ir = np.fft.irfft(w * np.exp(-2j * np.pi * f * d / fs), n_fft, axis=1)[:, :BAND_TAPS]
        win = 0.5 * (1 + np.cos(np.pi * np.clip((n - d) / (centre + 1), -1, 1)))
        out[p] = ir * win
    return out


class _KernelBank:
    """Per HRTF: kernels[direction, phase] = (n_bands, taps, 2) band basis x HRIR, all built at once.

    One batched FFT product over the whole table (tens of ms, tens of MB), kept for the process.
    """

    def __init__(self, hrtf: Hrtf) -> None:
        basis = band_basis(hrtf.fs)  # (P, B, T_b)
        self.taps = BAND_TAPS + hrtf.taps - 1
        n_fft = sfft.next_fast_len(self.taps, real=True)
        fb = sfft.rfft(basis, n_fft, axis=-1)  # (P, B, F)
        fh = sfft.rfft(hrtf.table.astype(np.float64), n_fft, axis=1)  # (D, F, 2)
        n_dirs = hrtf.table.shape[0]
        self.kernels = np.empty((n_dirs, SUBSAMPLE, len(BAND_CENTERS), self.taps, 2), dtype=np.float32)
        for ch in range(2):
            prod = fb[None] * fh[:, None, None, :, ch]  # (D, P, B, F)
            self.kernels[..., ch] = sfft.irfft(prod, n_fft, axis=-1)[..., : self.taps]
        self.rows = self.kernels.reshape(n_dirs * SUBSAMPLE, -1)  # view: one row per (direction, phase)
        self.centre = (BAND_TAPS - 1) // 2 + hrtf.delay_s * hrtf.fs  # samples from kernel start to "the arrival"


_BANKS: weakref.WeakKeyDictionary[Hrtf, _KernelBank] = weakref.WeakKeyDictionary()


def _bank(hrtf: Hrtf) -> _KernelBank:
    """The kernel bank of `hrtf`, built on first use and kept as long as the HRTF lives."""
    bank = _BANKS.get(hrtf)
    if bank is None:
        bank = _BANKS[hrtf] = _KernelBank(hrtf)
    return bank


def head_relative(directions: np.ndarray, head_yaw: float) -> np.ndarray:
    """World-frame unit vectors (n, 3) rotated into the head frame of a head with yaw `head_yaw`."""
    c, s = np.cos(head_yaw), np.sin(head_yaw)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=-1)


def binaural_length(response: AcousticResponse, hrtf: Hrtf) -> int:
    """Samples of the binaural IR of `response`: its length plus the longest rendering kernel."""
    return int(response.length) + max(_bank(hrtf).taps, hrtf.diffuse_taps) - 1


class Binauraliser:
    """The yaw-independent part of rendering one response, computed once: each arrival's kernel
    start, delay phase and band weights, the tail's spectrum and the openings' noise spectra.
    A receiver's RIRs are asked for one head-yaw bin at a time (`RirCache`), so the cache keeps
    one per response and `irs(yaws)` does only the work that depends on the head."""

    def __init__(self, response: AcousticResponse, hrtf: Hrtf) -> None:
        if response.fs != hrtf.fs:
            raise ValueError(f"response at {response.fs} Hz but HRTF at {hrtf.fs} Hz")
        self.field_seed, self.hrtf = response.field_seed, hrtf
        self.length = binaural_length(response, hrtf)
        arrivals = response.arrivals
        self.n_arrivals = len(arrivals)
        if arrivals:
            delay = np.array([a.delay_s for a in arrivals]) * hrtf.fs - _bank(hrtf).centre
            q = np.floor(delay * SUBSAMPLE + 0.5).astype(np.int64)
            self.start, self.phase = np.divmod(q, SUBSAMPLE)
            weights = np.array([a.gain for a in arrivals])[:, None] * np.array(
                [a.band_gains for a in arrivals], dtype=np.float64
            ).reshape(len(arrivals), len(BAND_CENTERS))
            self.w32 = weights.astype(np.float32)
            world = np.array([a.direction for a in arrivals], dtype=np.float64)
            self.world = world / np.linalg.norm(world, axis=1, keepdims=True)
        tail = np.asarray(response.tail, dtype=np.float64)
        self.tail_spec: np.ndarray | None = None
        if tail.size and np.any(tail):
            self.tail_n = min(len(tail) + hrtf.diffuse_taps - 1, self.length)
            self.tail_fft = sfft.next_fast_len(len(tail) + hrtf.diffuse_taps - 1, real=True)
            self.tail_spec = sfft.rfft(tail, self.tail_fft)
        self.apertures = [_Aperture(ap, hrtf) for ap in response.apertures]

    def irs(self, head_yaws: Sequence[float]) -> np.ndarray:
        """(len(head_yaws), length, 2) float32 binaural IRs for these head yaws."""
        hrtf, length = self.hrtf, self.length
        yaws = np.asarray(list(head_yaws), dtype=np.float64)
        n_y = len(yaws)
        out = np.zeros((n_y, length, 2), dtype=np.float32)
        if self.n_arrivals:
            bank = _bank(hrtf)
            T, n_arr, start = bank.taps, self.n_arrivals, self.start
            dirs = hrtf.nearest(np.stack([head_relative(self.world, y) for y in yaws]))  # (n_y, n_arr)
            rows = (dirs * SUBSAMPLE + self.phase[None, :]).ravel()  # row gather on a 2-D view is fast
            sel = np.take(bank.rows, rows, axis=0).reshape(n_y, n_arr, len(BAND_CENTERS), T * 2)
            # band-weighted sum as plain element-wise float32 ops (bit-identical on any CPU, unlike BLAS)
            w32 = self.w32
            contrib = sel[:, :, 0] * w32[None, :, 0, None]
            for b in range(1, len(BAND_CENTERS)):
                contrib += sel[:, :, b] * w32[None, :, b, None]
            contrib = contrib.reshape(n_y, n_arr, T, 2)
            for i in range(n_arr):
                lo, hi = max(int(start[i]), 0), min(int(start[i]) + T, length)
                if lo < hi:
                    out[:, lo:hi] += contrib[:, i, lo - start[i] : hi - start[i]]
        if self.tail_spec is not None:
            dec = hrtf.diffuse_field(self.field_seed, yaws).astype(np.float64)  # (n_y, taps, 2)
            spec = self.tail_spec[None, :, None] * sfft.rfft(dec, self.tail_fft, axis=1)
            out[:, : self.tail_n] += sfft.irfft(spec, self.tail_fft, axis=1)[:, : self.tail_n].astype(np.float32)
        for ap in self.apertures:
            out += ap.render(yaws, length)
        return out


def binaural_irs(response: AcousticResponse, head_yaws: Sequence[float], hrtf: Hrtf) -> np.ndarray:
    """(len(head_yaws), length, 2) float32 binaural IRs of one response for several head yaws.

    The yaw-independent work (delays, band weights, the diffuse tail) is shared (`Binauraliser`).
    """
    return Binauraliser(response, hrtf).irs(head_yaws)


class _Aperture:
    """Late energy through an opening: each of its points' noise through the HRIR of that
    point's direction relative to the head (noise spectra computed once, HRIR spectra looked
    up per direction, `Hrtf.spectra_at`)."""

    def __init__(self, ap: ApertureTail, hrtf: Hrtf) -> None:
        sig = np.asarray(ap.signals, dtype=np.float64)
        self.directions, self.hrtf = ap.directions, hrtf
        self.n = sig.shape[1] + hrtf.taps - 1
        self.n_fft = sfft.next_fast_len(self.n, real=True)
        self.S = sfft.rfft(sig, self.n_fft, axis=1)  # (k, F)

    def render(self, yaws: np.ndarray, length: int) -> np.ndarray:
        """(n_y, length, 2) for these head yaws."""
        out = np.zeros((len(yaws), length, 2), dtype=np.float32)
        n = min(self.n, length)
        for i, yaw in enumerate(yaws):
            idx = self.hrtf.nearest(head_relative(self.directions, float(yaw)))
            H = self.hrtf.spectra_at(idx, self.n_fft)  # (k, F, 2)
            out[i, :n] = sfft.irfft(np.einsum("kf,kfc->fc", self.S, H), self.n_fft, axis=0)[:n]
        return out


def binaural_ir(response: AcousticResponse, head_yaw: float, hrtf: Hrtf) -> np.ndarray:
    """(length, 2) float32 binaural IR (channel 0 = left) of `response` for a head at `head_yaw`.

    `head_yaw` is the world yaw of the nose (counter-clockwise from +x); arrival directions
    are world-frame unit vectors from the receiver towards where the sound comes from.
    """
    return binaural_irs(response, [head_yaw], hrtf)[0]
