"""The MP4 writer: a standard container with H.264 picture and two-channel AAC sound."""

from pathlib import Path

import numpy as np
import pytest

from echo_data.media import probe_mp4, write_mp4


def _frames(n: int, h: int = 64, w: int = 96):
    for i in range(n):
        img = np.zeros((h, w, 3), np.uint8)
        img[:, : (i * 3) % w] = (200, 40, 40)
        yield img


def test_mp4_has_picture_and_stereo_sound(tmp_path: Path) -> None:
    sr, fps, n = 16_000, 10, 30
    t = np.arange(int(sr * n / fps)) / sr
    audio = np.stack([0.3 * np.sin(2 * np.pi * 440 * t), 0.1 * np.sin(2 * np.pi * 660 * t)], 1)
    out = tmp_path / "ep.mp4"
    write_mp4(out, _frames(n), fps=fps, audio=audio.astype(np.float32), sample_rate=sr)
    info = probe_mp4(out)
    assert info["streams"].count("video") == 1 and info["streams"].count("audio") == 1
    assert info["video_frames"] == n
    assert (info["width"], info["height"]) == (96, 64)
    assert info["audio_channels"] == 2 and info["audio_rate"] == sr
    assert info["duration_s"] == pytest.approx(n / fps, abs=0.15)
    assert not list(tmp_path.glob(".*tmp*")), "temporary file left behind"


def test_left_channel_stays_left(tmp_path: Path) -> None:
    """Channel 0 is the left ear in the dataset; the MP4 must keep that order."""
    import av

    sr = 16_000
    audio = np.zeros((sr, 2), np.float32)
    audio[:, 0] = 0.5 * np.sin(2 * np.pi * 500 * np.arange(sr) / sr)
    out = tmp_path / "left.mp4"
    write_mp4(out, _frames(10), fps=10, audio=audio, sample_rate=sr)
    with av.open(str(out)) as c:
        decoded = np.concatenate([f.to_ndarray() for f in c.decode(audio=0)], axis=1)
    left, right = np.sqrt(np.mean(decoded[0] ** 2)), np.sqrt(np.mean(decoded[1] ** 2))
    assert left > 0.2 and right < 0.02 * left


def test_odd_sizes_and_bad_input(tmp_path: Path) -> None:
    write_mp4(tmp_path / "odd.mp4", _frames(3, 33, 47), fps=5)
    info = probe_mp4(tmp_path / "odd.mp4")
    assert (info["width"], info["height"]) == (48, 34) and info["audio_channels"] == 0
    with pytest.raises(ValueError):
        write_mp4(tmp_path / "bad.mp4", _frames(2), fps=5, audio=np.zeros((10, 1)))
    assert not (tmp_path / "bad.mp4").exists()
