"""Measures that the library's instances are distinct within a category and separable across them.

Two feature groups per instance, both computed on one loop at 16 kHz (25 ms windows, 10 ms hop,
framed circularly because the loop wraps):
- spectral: the log-mel spectrogram (64 bands, dB, floored 80 dB under the loudest bin),
  summarised by each band's mean and standard deviation over time (128 numbers, dB);
- rhythm: the modulation spectrum of the frame level (dB) in 7 octave bands 0.25-32 Hz (dB).
Distance between two instances: sqrt(D_spec^2 + D_rhythm^2), each the RMS of its group's
difference (dB). Run `python -m echo_data.sounds.measure` for the figures.
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np

from echo_data.sounds.library import SoundLibrary

SR = 16000
N_FFT, WIN, HOP, N_MELS = 512, 400, 160, 64


@lru_cache(maxsize=1)
def _mel_basis() -> np.ndarray:
    import librosa

    return librosa.filters.mel(sr=SR, n_fft=N_FFT, n_mels=N_MELS, fmin=50.0, fmax=SR / 2)


MOD_BANDS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
N_SPEC = 2 * N_MELS


def features(x: np.ndarray) -> np.ndarray:
    """[per-band mean (64), per-band std (64) of log-mel dB, modulation level in 7 bands (dB)] of one loop."""
    x = np.asarray(x, dtype=np.float64)
    n_frames = max(2, len(x) // HOP)
    idx = np.arange(n_frames)[:, None] * HOP + np.arange(WIN)[None, :]
    frames = x[idx % len(x)] * np.hanning(WIN)  # the loop wraps, so frame it circularly
    power = np.abs(np.fft.rfft(frames, N_FFT)) ** 2
    db = 10 * np.log10(power @ _mel_basis().T + 1e-12)
    db = np.maximum(db, db.max() - 80.0)
    level = 10 * np.log10(power.sum(axis=1) + 1e-12)
    level = np.maximum(level, level.max() - 60.0)
    mod = np.abs(np.fft.rfft(level - level.mean())) / n_frames
    fm = np.fft.rfftfreq(n_frames, HOP / SR)
    rhythm = [20 * np.log10(np.sqrt(np.sum(mod[(fm >= a) & (fm < b)] ** 2)) + 1e-2) for a, b in zip(MOD_BANDS[:-1], MOD_BANDS[1:])]
    return np.concatenate([db.mean(axis=0), db.std(axis=0), rhythm])


def distance_matrix(f: np.ndarray) -> np.ndarray:
    """Pairwise sqrt(D_spec^2 + D_rhythm^2) between rows of a feature table (dB)."""
    def rms(a: np.ndarray) -> np.ndarray:
        return np.sqrt(((a[:, None, :] - a[None, :, :]) ** 2).mean(axis=2))

    return np.sqrt(rms(f[:, :N_SPEC]) ** 2 + rms(f[:, N_SPEC:]) ** 2)


def feature_table(lib: SoundLibrary) -> tuple[list[str], list[str], np.ndarray]:
    """(ids, categories, features) for every instance of `lib`."""
    items = lib.instances()
    feats = np.stack([features(lib.waveform(s.id, SR)) for s in items])
    return [s.id for s in items], [s.category for s in items], feats


def report(lib: SoundLibrary) -> dict[str, object]:
    """Within-category minimum pairwise distance, leave-one-out 1-NN accuracy and train→test 1-NN accuracy."""
    ids, cats, f = feature_table(lib)
    d = distance_matrix(f)
    cat_arr = np.array(cats)
    within: dict[str, dict[str, object]] = {}
    for c in dict.fromkeys(cats):
        m = np.where(cat_arr == c)[0]
        sub = d[np.ix_(m, m)] + np.diag(np.full(len(m), np.inf))
        i, j = np.unravel_index(np.argmin(sub), sub.shape)
        within[c] = {"min_pair_db": round(float(sub[i, j]), 3), "closest_pair": [ids[m[i]], ids[m[j]]],
                     "median_pair_db": round(float(np.median(sub[np.isfinite(sub)])), 3)}
    dd = d + np.diag(np.full(len(ids), np.inf))
    nn = cat_arr[np.argmin(dd, axis=1)]
    loo = float(np.mean(nn == cat_arr))
    splits = np.array([lib.get(i).split for i in ids])
    train, test = splits == "train", splits == "test"
    # 1-NN from train instances only: how well test sounds are recognised from the train set.
    pred = cat_arr[train][np.argmin(d[np.ix_(test, train)], axis=1)]
    return {
        "within_category": within,
        "loo_1nn_accuracy": round(loo, 4),
        "loo_1nn_errors": [(ids[i], str(nn[i])) for i in np.where(nn != cat_arr)[0]],
        "nn_train_to_test_accuracy": round(float(np.mean(pred == cat_arr[test])), 4),
    }


if __name__ == "__main__":
    print(json.dumps(report(SoundLibrary.builtin()), indent=1))
