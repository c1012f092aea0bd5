"""Per-step audio features of the binaural track: SoundSpaces-style spectrogram and log-mel.

Both look at the last second of audio heard before a step's sample offset (zero-padded
before the episode start) and share one STFT: n_fft 512, hop 160, window 400 (periodic
Hann, centred in the 512 frame), frames centred with zero padding (librosa's
`pad_mode="constant"`, pinned so results do not change with librosa's default).

- spectrogram: per channel |STFT| (257 x 101 at 16 kHz), 4 x 4 mean pooling with zero-padded
  edges (65 x 26), log1p, channels last -> (65, 26, 2), as SoundSpaces feeds its audio encoder.
- log-mel: power |STFT|^2 through librosa's Slaney mel filterbank (cached), in dB re 1 with a
  -100 dB floor (absolute, so levels are comparable across steps) -> (n_mels, 101, 2).
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.fft as sfft
from scipy.signal import get_window

N_FFT = 512
HOP = 160
WIN = 400
POOL = 4
MEL_FLOOR = 1e-10  # power floor: -100 dB
_CHUNK = 32  # steps per batched STFT (bounds memory)


@functools.lru_cache(maxsize=1)
def _window() -> np.ndarray:
    """The analysis window: periodic Hann of WIN samples centred in N_FFT (float64, as librosa builds it)."""
    w = np.zeros(N_FFT)
    w[(N_FFT - WIN) // 2 : (N_FFT - WIN) // 2 + WIN] = get_window("hann", WIN, fftbins=True)
    w.setflags(write=False)
    return w


def _frame_mag(frames: np.ndarray) -> np.ndarray:
    """|rfft| of windowed frames: (..., k, N_FFT) float32 -> (..., 257, k) float32.

    The arithmetic of `librosa.stft` (float32 samples times the float64 window, `scipy.fft.rfft`
    in float64, rounded to complex64, magnitude in float32), one frame at a time: a frame's
    magnitudes do not depend on which other frames are analysed with it.
    """
    spec = sfft.rfft(_window() * np.asarray(frames, dtype=np.float32), axis=-1).astype(np.complex64)
    return np.abs(spec).swapaxes(-1, -2)


def _stft_mag(x: np.ndarray) -> np.ndarray:
    """|STFT| over the last axis: (..., samples) -> (..., 257, frames) float32 (centred frames, zero-padded)."""
    x = np.asarray(x, dtype=np.float32)
    pad = [(0, 0)] * (x.ndim - 1) + [(N_FFT // 2, N_FFT // 2)]
    padded = np.pad(x, pad)
    frames = np.lib.stride_tricks.sliding_window_view(padded, N_FFT, axis=-1)[..., ::HOP, :]
    return _frame_mag(frames)


def _pool(mag: np.ndarray) -> np.ndarray:
    """4 x 4 mean pooling of the last two axes, zero-padding the ragged edges (zeros count).

    Summed in a fixed order (the four time bins, then the four frequency bins, each left to
    right) as explicit float32 adds: the values numpy's two-axis `mean` gives on this machine,
    several times faster, and the same on any CPU.
    """
    *lead, f, t = mag.shape
    fp, tp = -(-f // POOL) * POOL, -(-t // POOL) * POOL
    padded = np.zeros((*lead, fp, tp), dtype=np.float32)
    padded[..., :f, :t] = mag
    v = padded.reshape(*lead, fp // POOL, POOL, tp // POOL, POOL)
    s = v[..., 0]
    for k in range(1, POOL):
        s = s + v[..., k]
    out = s[..., 0, :]
    for k in range(1, POOL):
        out = out + s[..., k, :]
    return out / np.float32(POOL * POOL)


def _hz_to_mel(f: np.ndarray) -> np.ndarray:
    """Slaney's mel scale (Auditory Toolbox): linear, 3 mel per 200 Hz, below 1 kHz; logarithmic
    above, 27 mel per factor 6.4 (the scale librosa uses with htk=False)."""
    f = np.asarray(f, dtype=np.float64)
    lin = f / _MEL_SP
    return np.where(f >= 1000.0, 1000.0 / _MEL_SP + np.log(np.maximum(f, 1e-300) / 1000.0) / _MEL_LOGSTEP, lin)


def _mel_to_hz(m: np.ndarray) -> np.ndarray:
    m = np.asarray(m, dtype=np.float64)
    lin = _MEL_SP * m
    return np.where(m >= 1000.0 / _MEL_SP, 1000.0 * np.exp(_MEL_LOGSTEP * (m - 1000.0 / _MEL_SP)), lin)


_MEL_SP = 200.0 / 3
_MEL_LOGSTEP = float(np.log(6.4) / 27.0)


@functools.lru_cache(maxsize=16)
def mel_filterbank(fs: int, n_mels: int) -> np.ndarray:
    """(n_mels, 257) Slaney-normalised mel filterbank for the shared STFT (cached), float32:
    triangles between band edges equally spaced in mel from 0 Hz to fs/2, each of unit area
    (scaled by 2 / its width in Hz), as `librosa.filters.mel(sr=fs, n_fft=512, n_mels=n_mels)`
    gives (a test checks it) without importing librosa in every worker."""
    freqs = np.fft.rfftfreq(N_FFT, 1.0 / fs)
    edges = _mel_to_hz(np.linspace(_hz_to_mel(np.array(0.0)), _hz_to_mel(np.array(fs / 2.0)), n_mels + 2))
    width = np.diff(edges)
    ramps = np.subtract.outer(edges, freqs)
    fb = np.zeros((n_mels, len(freqs)), dtype=np.float32)
    for b in range(n_mels):
        fb[b] = np.maximum(0.0, np.minimum(-ramps[b] / width[b], ramps[b + 2] / width[b + 1]))
    fb *= (2.0 / (edges[2 : n_mels + 2] - edges[:n_mels]))[:, None]
    fb.setflags(write=False)
    return fb


def _spectrogram_from_mag(mag: np.ndarray) -> np.ndarray:
    """(..., 2, 257, T) magnitudes -> (..., F', T', 2) float32 SoundSpaces spectrogram."""
    return np.moveaxis(np.log1p(_pool(mag)), -3, -1).astype(np.float32)


@functools.lru_cache(maxsize=16)
def _mel_taps(fs: int, n_mels: int) -> tuple[np.ndarray, np.ndarray]:
    """Each band's non-zero filterbank bins in ascending order, padded to one width:
    (bins (n_mels, W) int, weights (n_mels, W) float64, 0 where padded)."""
    fb = mel_filterbank(fs, n_mels).astype(np.float64)
    nz = [np.flatnonzero(row) for row in fb]
    width = max((len(k) for k in nz), default=0)
    bins = np.zeros((n_mels, width), dtype=np.int64)
    weights = np.zeros((n_mels, width))
    for b, k in enumerate(nz):
        bins[b, : len(k)] = k
        weights[b, : len(k)] = fb[b, k]
    return bins, weights


def _mel_from_mag(mag: np.ndarray, fs: int, n_mels: int) -> np.ndarray:
    """(..., 2, 257, T) magnitudes -> (..., n_mels, T, 2) float32 log-mel (dB).

    The filterbank is applied as element-wise multiply-adds over each band's non-zero bins in
    ascending order (not BLAS; padding adds exact zeros), so the bytes do not depend on the CPU,
    the batch size or which frames are analysed together.
    """
    *lead, f, t = mag.shape
    power = np.ascontiguousarray(np.moveaxis(np.square(mag, dtype=np.float64), -2, 0))  # (257, ..., T)
    bins, weights = _mel_taps(fs, n_mels)
    extra = (1,) * (power.ndim - 1)
    mel = np.zeros((n_mels, *power.shape[1:]))
    for j in range(bins.shape[1]):
        mel += weights[:, j].reshape(n_mels, *extra) * power[bins[:, j]]
    db = 10.0 * np.log10(np.maximum(mel, MEL_FLOOR))  # (n_mels, ..., 2, T)
    return np.ascontiguousarray(np.moveaxis(db, (0, -2), (-3, -1)), dtype=np.float32)


def soundspaces_spectrogram(x2: np.ndarray, fs: int = 16000) -> np.ndarray:
    """(65, 26, 2) float32 for 1 s of binaural audio (samples, 2) at 16 kHz (channel 0 = left).

    The STFT is defined in samples (SoundSpaces' recipe), so `fs` does not change it; other
    lengths or rates give (65, ceil((1 + n // 160) / 4), 2).
    """
    x2 = np.asarray(x2)
    if x2.ndim != 2 or x2.shape[1] != 2:
        raise ValueError(f"expected (samples, 2) binaural audio, got shape {x2.shape}")
    return _spectrogram_from_mag(_stft_mag(x2.T))


def log_mel(x2: np.ndarray, fs: int, n_mels: int) -> np.ndarray:
    """(n_mels, 101, 2) float32 log-mel of the last second of `x2` (samples, 2), zero-padded in front."""
    x2 = np.asarray(x2)
    last = np.zeros((fs, 2), dtype=np.float32)
    n = min(len(x2), fs)
    if n:
        last[fs - n :] = x2[len(x2) - n :]
    return _mel_from_mag(_stft_mag(last.T), fs, n_mels)


def last_second(track: np.ndarray, offset: int, fs: int) -> np.ndarray:
    """Samples [offset - fs, offset) of `track` (n, 2), zeros where they fall before 0 or past the end."""
    out = np.zeros((fs, 2), dtype=np.float32)
    lo, hi = max(int(offset) - fs, 0), min(int(offset), len(track))
    if hi > lo:
        out[fs - (int(offset) - lo) : fs - (int(offset) - hi)] = track[lo:hi]
    return out


def _frame_layout(fs: int) -> tuple[np.ndarray, np.ndarray]:
    """Start of each frame of a one-second window relative to the window's first sample, and
    which frames lie wholly inside the window (their samples are the track's own, so a frame at
    the same track position is the same in every window; the others see the window's zero padding)."""
    rel = HOP * np.arange(1 + fs // HOP) - N_FFT // 2
    return rel, (rel >= 0) & (rel + N_FFT <= fs)


def _edge_frames(windows: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """(k, 2, fs) windows -> (k, 2, len(rel), N_FFT) frames starting at `rel`, zero-padded outside the window."""
    pad = N_FFT // 2
    padded = np.pad(windows, [(0, 0), (0, 0), (pad, pad)])
    return np.stack([padded[..., r + pad : r + pad + N_FFT] for r in rel], axis=2)


def _windows(track: np.ndarray, offsets: np.ndarray, fs: int) -> np.ndarray:
    """(k, 2, fs) float32: the second before each offset (zeros outside the track)."""
    return np.stack([last_second(track, o, fs).T for o in offsets])


def _track_frames(track: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(2, len(starts), N_FFT) float32 frames of `track` (n, 2) starting at `starts` (zeros outside it)."""
    lo = int(min(starts.min(), 0))
    hi = int(max(starts.max() + N_FFT, len(track)))
    z = np.zeros((2, hi - lo), dtype=np.float32)
    z[:, -lo : -lo + len(track)] = np.asarray(track, dtype=np.float32).T
    view = np.lib.stride_tricks.sliding_window_view(z, N_FFT, axis=-1)
    return view[:, starts - lo]


def _assemble(inner: np.ndarray, mag_i: np.ndarray, mel_i: np.ndarray, mag_e: np.ndarray, mel_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interior frames (k, 2, 257, I) / (k, n_mels, I, 2) and edge frames -> the windows' features."""
    k, _, f, _ = mag_i.shape
    t = len(inner)
    mag = np.empty((k, 2, f, t), dtype=np.float32)
    mag[..., inner], mag[..., ~inner] = mag_i, mag_e
    mel = np.empty((k, mel_i.shape[1], t, 2), dtype=np.float32)
    mel[:, :, inner], mel[:, :, ~inner] = mel_i, mel_e
    return _spectrogram_from_mag(mag), mel


def _features(track: np.ndarray, offsets: np.ndarray, fs: int, n_mels: int) -> tuple[np.ndarray, np.ndarray]:
    """Features of the windows before `offsets`: each interior frame analysed once for all of them."""
    rel, inner = _frame_layout(fs)
    starts = offsets[:, None] - fs + rel[None, inner]
    uniq, inv = np.unique(starts, return_inverse=True)
    mag_u = _frame_mag(_track_frames(track, uniq))  # (2, 257, U)
    mel_u = _mel_from_mag(mag_u, fs, n_mels)  # (n_mels, U, 2)
    inv = inv.reshape(starts.shape)
    mag_e = _frame_mag(_edge_frames(_windows(track, offsets, fs), rel[~inner]))
    return _assemble(inner, np.moveaxis(mag_u[:, :, inv], 2, 0), np.moveaxis(mel_u[:, inv], 1, 0), mag_e, _mel_from_mag(mag_e, fs, n_mels))


def step_features(
    track: np.ndarray, offsets: np.ndarray, fs: int = 16000, n_mels: int = 64
) -> tuple[np.ndarray, np.ndarray]:
    """Per step (spectrogram (n_steps, 65, 26, 2), mel (n_steps, n_mels, 101, 2)), float32.

    Step i sees the second of audio before `offsets[i]` (zero-padded at the episode start).
    """
    offsets = np.asarray(offsets, dtype=np.int64).ravel()
    track = np.asarray(track)
    specs, mels = [], []
    for c0 in range(0, len(offsets), _CHUNK):
        s, m = _features(track, offsets[c0 : c0 + _CHUNK], fs, n_mels)
        specs.append(s)
        mels.append(m)
    if not specs:
        frames = 1 + fs // HOP
        return (
            np.zeros((0, -(-(N_FFT // 2 + 1) // POOL), -(-frames // POOL), 2), dtype=np.float32),
            np.zeros((0, n_mels, frames, 2), dtype=np.float32),
        )
    return np.concatenate(specs), np.concatenate(mels)


class FeatureStream:
    """Per-step features of a track that grows one control step at a time (the environment's ears).

    A step adds `hop` samples; the interior frames of the window that lay wholly inside the
    previous window are kept (in window order, with their start in the track) and only the new
    ones and the window's four edge frames are analysed. Every frame is computed by the same
    functions as `step_features`, so the result is bit for bit the batch result on the finished track.
    Kept frames are stored frame-major ((frames, 2, 257) magnitudes, (frames, n_mels, 2) log-mel),
    so carrying them from one window to the next copies whole rows, not strided columns.
    """

    def __init__(self, fs: int, n_mels: int) -> None:
        self.fs, self.n_mels = int(fs), int(n_mels)
        self._rel, self._inner = _frame_layout(self.fs)
        self._inner_rel = self._rel[self._inner]
        self._inner_at = np.flatnonzero(self._inner)  # columns of the interior frames in the window
        self._edge_at = np.flatnonzero(~self._inner)
        self._edge_rel = self._rel[~self._inner]
        n_frames, n_bins = len(self._rel), N_FFT // 2 + 1
        self._starts = np.zeros(0, dtype=np.int64)  # track start of each kept interior frame
        self._mag = np.zeros((n_frames, 2, n_bins), dtype=np.float32)  # the last window's frames, in order
        self._mel = np.zeros((n_frames, self.n_mels, 2), dtype=np.float32)
        self.reused = 0  # interior frames taken from the previous window (all calls)

    def features(self, window: np.ndarray, offset: int) -> tuple[np.ndarray, np.ndarray]:
        """(spectrogram (65, 26, 2), mel (n_mels, 101, 2)) of `window` (fs, 2): the second of the
        track before sample `offset` (zeros before the track's start)."""
        w = np.ascontiguousarray(np.asarray(window, dtype=np.float32).T)  # (2, fs)
        starts = int(offset) - self.fs + self._inner_rel
        mag, mel = np.empty_like(self._mag), np.empty_like(self._mel)
        # interior frames the last window analysed: same track samples, same values
        pos = np.searchsorted(self._starts, starts)
        old = pos < len(self._starts)
        old[old] = self._starts[pos[old]] == starts[old]
        cols, src = self._inner_at[old], self._inner_at[pos[old]]
        mag[cols] = self._mag[src]
        mel[cols] = self._mel[src]
        self.reused += len(cols)
        new = np.flatnonzero(~old)
        view = np.lib.stride_tricks.sliding_window_view(w, N_FFT, axis=-1)
        frames = np.concatenate([view[:, self._inner_rel[new]], self._edges(w)], axis=1)
        m = _frame_mag(frames)  # (2, 257, new + edges)
        ml = _mel_from_mag(m, self.fs, self.n_mels)  # (n_mels, new + edges, 2)
        at = np.concatenate([self._inner_at[new], self._edge_at])
        mag[at], mel[at] = m.transpose(2, 0, 1), ml.transpose(1, 0, 2)
        self._starts, self._mag, self._mel = starts, mag, mel
        return _spectrogram_from_mag(mag.transpose(1, 2, 0)), np.ascontiguousarray(mel.transpose(1, 0, 2))

    def _edges(self, w: np.ndarray) -> np.ndarray:
        """(2, E, N_FFT) frames of the window that reach past it (zeros outside), as `_edge_frames`."""
        out = np.zeros((2, len(self._edge_rel), N_FFT), dtype=np.float32)
        for e, r in enumerate(self._edge_rel):
            lo, hi = max(int(r), 0), min(int(r) + N_FFT, self.fs)
            out[:, e, lo - r : hi - r] = w[:, lo:hi]
        return out
