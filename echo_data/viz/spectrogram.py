"""The one spectrogram picture of a binaural track: `preview`'s spectrogram.png and the scrolling
strip of `view` and `evaluate --video` show the same analysis on the same colour scale.

Log-magnitude STFT per ear (40 ms Hann window, 10 ms hop), the left ear above the right, low
frequencies at the bottom of each, the top DB_RANGE dB below the loudest bin of the track.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

DB_RANGE = 80.0  # dB shown below the track's loudest bin
HOP_SECONDS = 0.01
WINDOW_HOPS = 4
GAP_ROWS = 2  # white rows between the ears in the picture


def spectrogram_db(audio: np.ndarray, fs: int) -> tuple[np.ndarray, float]:
    """(2, bins, frames) dB magnitude of each ear (bin 0 = lowest frequency above DC) and the frames per second."""
    from scipy.signal import stft

    hop = max(1, int(round(fs * HOP_SECONDS)))
    x = np.asarray(audio, dtype=np.float64).reshape(len(audio), -1)
    ears = []
    for ch in range(2):
        _, _, z = stft(x[:, min(ch, x.shape[1] - 1)], fs=fs, nperseg=WINDOW_HOPS * hop, noverlap=(WINDOW_HOPS - 1) * hop, boundary=None, padded=False)
        ears.append(20 * np.log10(np.abs(z[1:]) + 1e-6))
    return np.stack(ears), fs / hop


def spectrogram_picture(audio: np.ndarray, fs: int) -> tuple[np.ndarray, float]:
    """(rows, frames, 3) uint8 colour picture (magma) of both ears, and its columns per second."""
    from echo_data.media import colour_lut

    db, cols_per_s = spectrogram_db(audio, fs)
    top = float(db.max()) if db.size else 0.0
    level = np.clip((db - (top - DB_RANGE)) / DB_RANGE, 0, 1)
    rows = np.concatenate([level[0][::-1], np.ones((GAP_ROWS, level.shape[2])), level[1][::-1]])
    return colour_lut("magma")[(rows * 255).astype(np.uint8)], cols_per_s


def scrolling_strip(picture: np.ndarray, cols_per_s: float, now_s: float, width: int, height: int, behind_s: float, ahead_s: float) -> np.ndarray:
    """The part of `picture` from `behind_s` before `now_s` to `ahead_s` after it, fitted into
    (height, width) with a white cursor at `now_s`; outside the track is black."""
    from echo_data.media import fit_nearest

    px_per_s = width / (behind_s + ahead_s)
    cols = np.round((now_s + (np.arange(width) / px_per_s - behind_s)) * cols_per_s).astype(int)
    ok = (cols >= 0) & (cols < picture.shape[1])
    strip = np.zeros((picture.shape[0], width, 3), dtype=np.uint8)
    strip[:, ok] = picture[:, cols[ok]]
    strip = fit_nearest(strip, width, height).copy()
    cursor = int(behind_s * px_per_s)
    strip[:, cursor : cursor + 2] = 255
    return strip


def save_spectrogram(audio: np.ndarray, fs: int, out: Path, title: str) -> None:
    """`spectrogram_picture` with time and frequency axes and its dB scale, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    db, _ = spectrogram_db(audio, fs)
    top = float(db.max()) if db.size else 0.0
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for ear, (ax, name) in enumerate(zip(axes, ("left ear", "right ear"))):
        im = ax.imshow(db[ear], origin="lower", aspect="auto", extent=(0, len(audio) / fs, 0, fs / 2000), vmin=top - DB_RANGE, vmax=top, cmap="magma")
        ax.set_ylabel(f"{name}\nkHz")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title)
    fig.colorbar(im, ax=axes, label="dB re full scale (STFT bin magnitude)")
    fig.savefig(out, dpi=110)
    plt.close(fig)
