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

import librosa
import numpy as np

N_FFT = 512
HOP = 160
WIN = 400
POOL = 4
MEL_FLOOR = 1e-10  # power floor: -100 dB
_CHUNK = 32  # steps per batched STFT (bounds memory)


def _stft_mag(x: np.ndarray) -> np.ndarray:
    """|STFT| over the last axis: (..., samples) -> (..., 257, frames) float32."""
    spec = librosa.stft(
        np.ascontiguousarray(x, dtype=np.float32),
        n_fft=N_FFT,
        hop_length=HOP,
        win_length=WIN,
        window="hann",
        center=True,
        pad_mode="constant",
    )
    return np.abs(spec)


def _pool(mag: np.ndarray) -> np.ndarray:
    """4 x 4 mean pooling of the last two axes, zero-padding the ragged edges (zeros count)."""
    *lead, f, t = mag.shape
    fp, tp = -(-f // POOL) * POOL, -(-t // POOL) * POOL
    padded = np.zeros((*lead, fp, tp), dtype=np.float32)
    padded[..., :f, :t] = mag
    return padded.reshape(*lead, fp // POOL, POOL, tp // POOL, POOL).mean(axis=(-3, -1))


@functools.lru_cache(maxsize=16)
def mel_filterbank(fs: int, n_mels: int) -> np.ndarray:
    """(n_mels, 257) Slaney-normalised mel filterbank for the shared STFT (cached)."""
    fb = librosa.filters.mel(sr=fs, n_fft=N_FFT, n_mels=n_mels)
    fb.setflags(write=False)
    return fb


def _spectrogram_from_mag(mag: np.ndarray) -> np.ndarray:
    """(..., 2, 257, T) magnitudes -> (..., F', T', 2) float32 SoundSpaces spectrogram."""
    return np.moveaxis(np.log1p(_pool(mag)), -3, -1).astype(np.float32)


def _mel_from_mag(mag: np.ndarray, fs: int, n_mels: int) -> np.ndarray:
    """(..., 2, 257, T) magnitudes -> (..., n_mels, T, 2) float32 log-mel (dB).

    The filterbank is applied as element-wise multiply-adds over each band's non-zero bins in
    a fixed order (not BLAS), so the bytes do not depend on the CPU or on the batch size.
    """
    *lead, f, t = mag.shape
    power = np.ascontiguousarray(np.moveaxis(np.square(mag, dtype=np.float64), -2, 0))  # (257, ..., T)
    fb = mel_filterbank(fs, n_mels).astype(np.float64)
    mel = np.zeros((n_mels, *lead, t))
    for b in range(n_mels):
        for k in np.flatnonzero(fb[b]):
            mel[b] += fb[b, k] * power[k]
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


def step_features(
    track: np.ndarray, offsets: np.ndarray, fs: int = 16000, n_mels: int = 64
) -> tuple[np.ndarray, np.ndarray]:
    """Per step (spectrogram (n_steps, 65, 26, 2), mel (n_steps, n_mels, 101, 2)), float32.

    Step i sees the second of audio before `offsets[i]` (zero-padded at the episode start).
    """
    offsets = np.asarray(offsets, dtype=np.int64).ravel()
    specs, mels = [], []
    for c0 in range(0, len(offsets), _CHUNK):
        windows = np.stack([last_second(track, o, fs).T for o in offsets[c0 : c0 + _CHUNK]])  # (k, 2, fs)
        mag = _stft_mag(windows)  # (k, 2, 257, T)
        specs.append(_spectrogram_from_mag(mag))
        mels.append(_mel_from_mag(mag, fs, n_mels))
    if not specs:
        frames = 1 + fs // HOP
        return (
            np.zeros((0, -(-(N_FFT // 2 + 1) // POOL), -(-frames // POOL), 2), dtype=np.float32),
            np.zeros((0, n_mels, frames, 2), dtype=np.float32),
        )
    return np.concatenate(specs), np.concatenate(mels)
