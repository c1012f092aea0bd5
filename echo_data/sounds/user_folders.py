"""The user's own sound files: scanning a folder, a stable train/test split, reading and looping.

Any sample rate and channel count is accepted: channels are averaged to mono and the signal is
resampled to the requested rate. A file that cannot be read raises `SoundLibraryError` with a
one-line message naming the file: so does a silent file, a file longer than `MAX_FILE_SECONDS` or one with
NaN or infinite samples (float WAVs can hold them; they would poison every render).
"""

from __future__ import annotations

import re
import zlib
from pathlib import Path

import numpy as np
import soundfile as sf

from echo_data.sounds.dsp import resample

AUDIO_SUFFIXES = (".wav", ".wave", ".flac", ".ogg")
LOOP_CROSSFADE_S = 0.05
# Longest user recording accepted. Events loop their sound, so a ring, an alarm or a running tap
# needs seconds, not hours; a longer file is refused from its header, before any sample is read
# (a 10-hour WAV would take gigabytes in every worker).
MAX_FILE_SECONDS = 60.0
SILENT_PEAK = 1e-6  # a mono peak at or below this (of full scale) is silence: it cannot be levelled to an event's loudness


class SoundLibraryError(ValueError):
    """A sound library problem (unreadable or silent file, missing folder); `str()` is one line."""


def audio_files(folder: Path) -> list[Path]:
    """Audio files directly in `folder` (sorted by name); other files are ignored."""
    if not folder.is_dir():
        raise SoundLibraryError(f"{folder}: not a readable folder")
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in AUDIO_SUFFIXES)


def split_files(files: list[Path], test_fraction: float) -> dict[Path, str]:
    """Deterministic split: order by crc32 of the file name, the first round(fraction * n) are test.

    With two or more files there is at least one of each, so test episodes never reuse a train sound.
    """
    order = sorted(files, key=lambda p: (zlib.crc32(p.name.encode()), p.name))
    n = len(order)
    n_test = int(round(test_fraction * n))
    if n >= 2:
        n_test = min(max(n_test, 1), n - 1)
    return {p: ("test" if i < n_test else "train") for i, p in enumerate(order)}


def file_duration(path: Path) -> float:
    """Length in seconds from the header; raises SoundLibraryError naming the file if unreadable."""
    try:
        info = sf.info(str(path))
    except Exception as e:  # soundfile raises several types for corrupt or foreign files
        raise SoundLibraryError(f"{path}: unreadable audio file ({_reason(e)})") from None
    if info.frames <= 0 or info.samplerate <= 0:
        raise SoundLibraryError(f"{path}: audio file has no samples")
    seconds = info.frames / info.samplerate
    if seconds > MAX_FILE_SECONDS:
        raise SoundLibraryError(f"{path}: {seconds:.0f} s long; sound files may be at most {MAX_FILE_SECONDS:.0f} s (events loop their sound)")
    return seconds


def check_samples(path: Path) -> None:
    """Refuse a file with NaN or infinite samples, or a silent one, when the library is loaded,
    not mid-build inside a worker (read in blocks: memory stays small whatever the file's length)."""
    try:
        start, peak = 0, 0.0
        for block in sf.blocks(str(path), blocksize=1 << 16, dtype="float64", always_2d=True):
            bad = np.flatnonzero(~np.isfinite(block).all(axis=1))
            if bad.size:
                raise SoundLibraryError(f"{path}: samples are NaN or infinite (first at sample {start + int(bad[0])})")
            peak = max(peak, float(np.abs(block.mean(axis=1)).max(initial=0.0)))
            start += len(block)
    except SoundLibraryError:
        raise
    except Exception as e:
        raise SoundLibraryError(f"{path}: unreadable audio file ({_reason(e)})") from None
    if peak <= SILENT_PEAK:
        raise SoundLibraryError(f"{path}: audio file is silent (peak {peak:.1e} of full scale)")


def slug(stem: str) -> str:
    """A file stem made safe for an instance id (lower case, [a-z0-9_] runs joined by '_')."""
    s = re.sub(r"[^a-z0-9]+", "_", stem.lower()).strip("_")
    return s or "file"


def read_mono(path: Path, sr: int) -> np.ndarray:
    """The file as float64 mono at `sr` (channels averaged, polyphase resampling)."""
    try:
        data, file_sr = sf.read(str(path), dtype="float64", always_2d=True)
    except Exception as e:
        raise SoundLibraryError(f"{path}: unreadable audio file ({_reason(e)})") from None
    if data.size == 0:
        raise SoundLibraryError(f"{path}: audio file has no samples")
    bad = np.flatnonzero(~np.isfinite(data).all(axis=1))
    if bad.size:
        raise SoundLibraryError(f"{path}: samples are NaN or infinite (first at sample {int(bad[0])})")
    x = resample(data.mean(axis=1), int(file_sr), int(sr))
    if not np.any(np.abs(x) > SILENT_PEAK):
        raise SoundLibraryError(f"{path}: audio file is silent")
    return x


def crossfade_loop(x: np.ndarray, sr: int) -> np.ndarray:
    """A loop of a recording whose end blends into its start (equal-power crossfade of ≤ 50 ms).

    The returned period is len(x) - F samples; played back to back it runs
    x[F:] (end blended with x[:F]) → x[F:] … so no click appears where it wraps.
    """
    f = min(int(LOOP_CROSSFADE_S * sr), len(x) // 4)
    if f < 2:
        return x.copy()
    body = x[f:].copy()
    w = np.linspace(0.0, 1.0, f, endpoint=False) + 0.5 / f
    body[-f:] = body[-f:] * np.cos(0.5 * np.pi * w) + x[:f] * np.sin(0.5 * np.pi * w)
    return body


def _reason(e: Exception) -> str:
    msg = str(e).strip().splitlines()[0] if str(e).strip() else e.__class__.__name__
    return msg[:160]
