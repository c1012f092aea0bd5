"""The room's noise floor: a quiet, seeded, binaural background so no window is digital silence.

Spectrum: the shape of the NC-25 noise-criterion curve (octave-band levels 54, 44, 37, 31, 27,
24, 22, 21 dB at 63 Hz … 8 kHz; Beranek's curves for quiet residences, as tabulated in ANSI
S12.2), interpolated in log-frequency as a power spectral density, scaled so that the
A-weighted level (IEC 61672 weighting) equals the setting in dB(A). NC-25 itself is about
35 dB(A); quiet homes at night measure 25–35 dB(A).

The two ears get a diffuse field: their coherence is the HRTF set's diffuse-field coherence
(`Hrtf.diffuse_coherence`). The bed is generated in 50 %-overlapping blocks under
power-complementary sine windows, each block from its own seed, so any stretch can be
rendered on its own (streaming) and gives the same samples as rendering the whole track.
"""

from __future__ import annotations

import math

import numpy as np

from echo_data import seeds
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import P_REF

NC25_BANDS_HZ = (63.0, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0)
NC25_DB = (54.0, 44.0, 37.0, 31.0, 27.0, 24.0, 22.0, 21.0)
_BLOCK_S = 1.0
_KEEP_BLOCKS = 4  # blocks kept for streaming renders (a render spans at most 3 when n <= hop)


def a_weighting_db(f: np.ndarray) -> np.ndarray:
    """IEC 61672 A-weighting (dB) at frequencies f (Hz); -inf at 0 Hz."""
    f2 = np.asarray(f, dtype=np.float64) ** 2
    ra = 12194.0**2 * f2**2 / ((f2 + 20.6**2) * np.sqrt((f2 + 107.7**2) * (f2 + 737.9**2)) * (f2 + 12194.0**2))
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(ra) + 2.0


_SHAPING: dict[tuple[int, int, float, int], tuple[Hrtf, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}


def _shaping(fs: int, n: int, level_dba: float, hrtf: Hrtf) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(amplitude spectrum, interaural coherence, its complement, block window) of a bed: the
    same for every episode of a process (only the seed differs), so computed once."""
    key = (fs, n, level_dba, id(hrtf))
    hit = _SHAPING.get(key)
    if hit is None or hit[0] is not hrtf:
        f = np.fft.rfftfreq(n, 1.0 / fs)
        lf = np.log2(np.maximum(f, 1.0))
        psd_db = np.interp(lf, np.log2(NC25_BANDS_HZ), np.asarray(NC25_DB) - 10 * np.log10(0.707 * np.asarray(NC25_BANDS_HZ)))
        amp = 10.0 ** (psd_db / 20.0)
        amp[0] = 0.0
        # variance of irfft(amp * rfft(white)) = sum over the two-sided spectrum of amp^2 / n
        two_sided = np.full(len(f), 2.0)
        two_sided[0] = 1.0
        if n % 2 == 0:
            two_sided[-1] = 1.0
        wa = 10.0 ** (a_weighting_db(np.maximum(f, 1e-3)) / 10.0)
        var_a = float((two_sided * amp**2 * wa).sum() / n)
        target = (P_REF * 10.0 ** (level_dba / 20.0)) ** 2
        amp = amp * math.sqrt(target / var_a) if level_dba > 0 else amp * 0.0
        rho = np.clip(hrtf.diffuse_coherence(f), -1.0, 1.0)
        window = np.sin(np.pi * (np.arange(n) + 0.5) / n)  # sin^2 + cos^2 = 1 at 50 % overlap
        hit = _SHAPING[key] = (hrtf, amp, rho, np.sqrt(1.0 - rho**2), window)
    return hit[1], hit[2], hit[3], hit[4]


class NoiseFloor:
    """A stationary binaural noise bed of `level_dba` dB(A) in pascals, seeded."""

    def __init__(self, fs: int, level_dba: float, seed: int, hrtf: Hrtf) -> None:
        self.fs = int(fs)
        self.level_dba = float(level_dba)
        self.seed = int(seed) % (1 << 63)
        self.n = 1 << int(math.ceil(math.log2(_BLOCK_S * self.fs)))
        self.hop = self.n // 2
        self.amp, self.rho, self.rho_c, self.window = _shaping(self.fs, self.n, self.level_dba, hrtf)
        self._blocks: dict[int, np.ndarray] = {}

    def _block(self, k: int) -> np.ndarray:
        """Windowed block k (n, 2), covering samples [(k - 1) * hop, (k - 1) * hop + n); the
        last few are kept, so a stream of short renders draws each block once."""
        hit = self._blocks.get(k)
        if hit is None:
            hit = self._blocks[k] = self._draw(k)
            while len(self._blocks) > _KEEP_BLOCKS:
                del self._blocks[min(self._blocks)]
        return hit

    def _draw(self, k: int) -> np.ndarray:
        rng = seeds.derived_rng(seeds.NOISE_FLOOR, self.seed, k + (1 << 40))
        x1 = np.fft.rfft(rng.standard_normal(self.n))
        x2 = np.fft.rfft(rng.standard_normal(self.n))
        left = np.fft.irfft(self.amp * x1, self.n)
        right = np.fft.irfft(self.amp * (self.rho * x1 + self.rho_c * x2), self.n)
        return np.stack([left, right], axis=1) * self.window[:, None]

    def render(self, start: int, n: int) -> np.ndarray:
        """(n, 2) float64 pressure (Pa) for samples [start, start + n)."""
        out = np.zeros((n, 2))
        if n <= 0 or self.level_dba <= 0:
            return out
        k0 = start // self.hop
        k1 = (start + n - 1) // self.hop + 1
        for k in range(k0, k1 + 1):
            b0 = (k - 1) * self.hop
            lo, hi = max(b0, start), min(b0 + self.n, start + n)
            if lo < hi:
                out[lo - start : hi - start] += self._block(k)[lo - b0 : hi - b0]
        return out
