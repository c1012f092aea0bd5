"""Signal primitives for synthesising loopable sounds.

Everything here works on one loop period of `n` samples. Events are placed on a circular
timeline (`Loop`) and noise is shaped with a circular FFT filter, so the rendered period is
exactly periodic: playing it back to back has no discontinuity at the loop point.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from math import gcd

import numpy as np
from scipy.signal import resample_poly

# Partials above this fraction of the sample rate are faded out, so no band-limited tone aliases.
NYQUIST_GUARD = 0.45


class Loop:
    """A circular buffer of one loop period; an event that runs past the end wraps to the start."""

    def __init__(self, n: int) -> None:
        self.n = int(n)
        self.buf = np.zeros(self.n, dtype=np.float64)

    def add(self, start: int, sig: np.ndarray) -> None:
        """Mix `sig` in at sample `start` (any integer; taken modulo the period)."""
        pos = int(start) % self.n
        i = 0
        while i < len(sig):
            take = min(self.n - pos, len(sig) - i)
            self.buf[pos : pos + take] += sig[i : i + take]
            i += take
            pos = 0


def seconds_to_samples(t: float, sr: int) -> int:
    return max(1, int(round(t * sr)))


def ramp_envelope(n: int, sr: int, attack: float, release: float) -> np.ndarray:
    """Raised-cosine attack and release around a flat sustain (no clicks at either end)."""
    env = np.ones(n)
    a = min(n // 2, max(1, int(attack * sr)))
    r = min(n - a, max(1, int(release * sr)))
    env[:a] = 0.5 - 0.5 * np.cos(np.pi * np.arange(a) / a)
    if r > 0:
        env[n - r :] = 0.5 + 0.5 * np.cos(np.pi * (np.arange(r) + 1) / r)
    return env


def decay_envelope(n: int, sr: int, tau: float, attack: float = 0.002) -> np.ndarray:
    """Exponential decay with a short raised-cosine attack and a faded last 5 ms (struck sounds)."""
    t = np.arange(n) / sr
    env = np.exp(-t / tau)
    a = min(n, max(1, int(attack * sr)))
    env[:a] *= 0.5 - 0.5 * np.cos(np.pi * np.arange(a) / a)
    tail = min(n - a, int(0.005 * sr))
    if tail > 0:
        env[n - tail :] *= np.linspace(1.0, 0.0, tail)
    return env


def cumulative_phase(freq: np.ndarray | float, n: int, sr: int, phase0: float = 0.0) -> np.ndarray:
    """Oscillator phase (radians) for a constant or per-sample frequency; continuous under glides."""
    f = np.broadcast_to(np.asarray(freq, dtype=np.float64), (n,))
    return phase0 + 2.0 * np.pi * np.concatenate(([0.0], np.cumsum(f[:-1]))) / sr


def _nyquist_gain(f: np.ndarray, sr: int, fundamental: bool = False) -> np.ndarray:
    """1 well below the guard band, fading to 0 at NYQUIST_GUARD * sr.

    A fundamental cannot alias below Nyquist, so it keeps up to 0.49 * sr: a 3.9 kHz alarm beep
    stays audible at an 8 kHz rate instead of vanishing with its overtones.
    """
    if fundamental:
        return np.clip((0.49 * sr - f) / (0.01 * sr), 0.0, 1.0)
    lim = NYQUIST_GUARD * sr
    return np.clip((lim - f) / (0.05 * sr), 0.0, 1.0)


def harmonic_tone(
    f0: np.ndarray | float,
    n: int,
    sr: int,
    amps: Sequence[float] | Callable[[int, np.ndarray], np.ndarray],
    max_harmonics: int = 200,
) -> np.ndarray:
    """Band-limited sum of harmonics k*f0 (f0 may glide); `amps` per harmonic or a function (k, fk)."""
    f = np.broadcast_to(np.asarray(f0, dtype=np.float64), (n,))
    ph = cumulative_phase(f, n, sr)
    kmax = max(1, int(NYQUIST_GUARD * sr / max(1.0, float(f.min()))))
    if not callable(amps):
        kmax = min(kmax, len(amps))
    out = np.zeros(n)
    for k in range(1, min(kmax, max_harmonics) + 1):
        fk = k * f
        a = amps(k, fk) if callable(amps) else amps[k - 1]
        if np.all(a == 0):
            continue
        out += a * _nyquist_gain(fk, sr, fundamental=k == 1) * np.sin(k * ph)
    return out


def partials(
    freqs: Sequence[float],
    amps: Sequence[float],
    taus: Sequence[float],
    n: int,
    sr: int,
    phases: Sequence[float] | np.ndarray | None = None,
    attack: float = 0.002,
) -> np.ndarray:
    """Sum of exponentially decaying sinusoids (bells, bars, resonators); partials near Nyquist dropped."""
    t = np.arange(n) / sr
    out = np.zeros(n)
    for i, (f, a, tau) in enumerate(zip(freqs, amps, taus)):
        if f >= NYQUIST_GUARD * sr:
            continue
        ph = 0.0 if phases is None else phases[i]
        out += a * float(_nyquist_gain(np.asarray(f), sr)) * np.exp(-t / tau) * np.sin(2 * np.pi * f * t + ph)
    a_n = min(n, max(1, int(attack * sr)))
    out[:a_n] *= 0.5 - 0.5 * np.cos(np.pi * np.arange(a_n) / a_n)
    tail = min(n, int(0.005 * sr))
    if tail > 0:
        out[n - tail :] *= np.linspace(1.0, 0.0, tail)
    return out


def circular_noise(n: int, sr: int, rng: np.random.Generator, magnitude: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """White noise shaped by `magnitude(freq_hz)` with a circular FFT filter: exactly n-periodic, unit RMS."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / sr)
    mag = np.asarray(magnitude(f), dtype=np.float64)
    mag[0] = 0.0
    x = np.fft.irfft(spec * mag, n)
    rms = float(np.sqrt(np.mean(x**2)))
    return x / rms if rms > 0 else x


def smooth_periodic(n: int, sr: int, rng: np.random.Generator, cutoff_hz: float) -> np.ndarray:
    """A slowly varying periodic control signal (unit RMS) with energy below `cutoff_hz`."""
    return circular_noise(n, sr, rng, lambda f: np.exp(-0.5 * (f / cutoff_hz) ** 2))


def shaped_burst(n: int, sr: int, rng: np.random.Generator, lo: float, hi: float) -> np.ndarray:
    """A short band-passed noise burst with a click-free envelope (consonants, hammer clicks)."""
    if n < 4:
        return np.zeros(n)
    f = np.fft.rfftfreq(n, 1.0 / sr)
    spec = np.fft.rfft(rng.standard_normal(n)) * ((f >= lo) & (f <= min(hi, NYQUIST_GUARD * sr)))
    x = np.fft.irfft(spec, n)
    x *= np.hanning(n)
    peak = float(np.max(np.abs(x)))
    return x / peak if peak > 0 else x


def peak_normalise(x: np.ndarray, dbfs: float) -> np.ndarray:
    """Scale so the largest magnitude sits at `dbfs` (a stated, per-category level)."""
    peak = float(np.max(np.abs(x)))
    if peak == 0:
        return x
    return x * (10 ** (dbfs / 20.0) / peak)


def resample(x: np.ndarray, sr_in: int, sr_out: int) -> np.ndarray:
    """Polyphase resampling by the exact rational ratio sr_out / sr_in."""
    if sr_in == sr_out:
        return x
    g = gcd(int(sr_in), int(sr_out))
    return resample_poly(x, sr_out // g, sr_in // g)


def midi_to_hz(m: float) -> float:
    return 440.0 * 2.0 ** ((m - 69.0) / 12.0)
