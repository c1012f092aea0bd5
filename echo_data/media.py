"""MP4 files with picture and binaural sound, for people to watch what happened in an episode.

One encoder for the whole project (`echo-data view`, `echo-data evaluate --video`, the LeRobot
export's `--video`). PyAV is used because its wheels carry FFmpeg: no system codec and nothing
downloaded. Two settings (`VideoEncoding`): `PLAYER_VIDEO`, H.264 in yuv420p (what every standard
player opens), and `LEROBOT_VIDEO`, the settings LeRobot's own dataset recorder encodes with. Sound
is stereo AAC with channel 0 = left, as in the dataset's WAVs. The file appears under its name only once it is complete (written to a temporary name in the
same folder, then renamed), so a killed run never leaves a truncated video behind.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

AUDIO_BITRATE = 128_000
"""AAC bit rate for the two channels (transparent enough for listening to cues)."""


@dataclass(frozen=True)
class VideoEncoding:
    """How a video stream is encoded: FFmpeg's encoder, the pixel format, the encoder's options
    (`g`: at most this many frames between keyframes), and the codec name readers report (PyAV's
    `stream.codec.canonical_name`, which LeRobot stores as `video.codec`)."""

    encoder: str
    pix_fmt: str
    options: Mapping[str, str]
    codec: str


PLAYER_VIDEO = VideoEncoding("libx264", "yuv420p", {"crf": "20", "preset": "veryfast"}, "h264")
"""For people: H.264 opens in every standard player; libx264's default GOP (about 250 frames)."""

LEROBOT_VIDEO = VideoEncoding("libsvtav1", "yuv420p", {"g": "2", "crf": "30", "preset": "12"}, "av1")
"""For training loaders, as LeRobot 0.4.4's `encode_video_frames` encodes a recorded episode with
its defaults (the ones `LeRobotDataset` passes): SVT-AV1 at constant quality 30, its fastest
preset, a keyframe every 2 frames (a random frame decodes from at most one frame before it), no
fast-decode tuning. tests/test_export_lerobot.py encodes the same frames with LeRobot's function
and compares the streams."""


@functools.lru_cache(maxsize=8)
def colour_lut(name: str = "magma") -> np.ndarray:
    """256-entry RGB uint8 lookup table of a matplotlib colour map, for drawing spectrograms."""
    import matplotlib

    return (matplotlib.colormaps[name](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)


def fit_nearest(img: np.ndarray, width: int, height: int) -> np.ndarray:
    """Nearest-neighbour resize to (height, width): a video frame shows pixels as pixels."""
    from PIL import Image

    return np.asarray(Image.fromarray(img).resize((width, height), Image.Resampling.NEAREST))


def _even(n: int) -> int:
    """yuv420p (chroma at half resolution) needs even frame sides; frames are padded by one pixel where odd."""
    return n + (n % 2)


def _as_float_stereo(audio: np.ndarray) -> np.ndarray:
    """(n, 2) float32 in [-1, 1] from float or int16 samples; refuses anything that is not stereo."""
    a = np.asarray(audio)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"audio must have shape (n, 2), got {a.shape}")
    if a.dtype == np.int16:
        return (a.astype(np.float32) / 32768.0).astype(np.float32)
    a = a.astype(np.float32)
    if not np.all(np.isfinite(a)):
        raise ValueError("audio contains NaN or inf samples")
    return np.clip(a, -1.0, 1.0)  # AAC input range; callers keep headroom, this guards the encoder


def write_mp4(
    path: Path,
    frames: Iterable[np.ndarray],
    fps: float,
    audio: np.ndarray | None = None,
    sample_rate: int = 16_000,
    encoding: VideoEncoding = PLAYER_VIDEO,
) -> None:
    """Encode RGB frames ((H, W, 3) uint8, all the same size) and optional stereo audio to `path`
    with `encoding` (a training loader that seeks to random frames decodes from the keyframe
    before each one, so datasets use `LEROBOT_VIDEO`'s short GOP).

    The audio is placed from time 0 alongside the first frame; a track longer or shorter than the
    video is kept as it is (players end at the longer stream).
    """
    import av  # imported here: the core pipeline does not need FFmpeg loaded

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.mp4")
    rate = Fraction(fps).limit_denominator(1000)
    try:
        with av.open(str(tmp), mode="w", format="mp4") as container:
            vstream: av.VideoStream | None = None
            astream = None
            if audio is not None:
                astream = container.add_stream("aac", rate=int(sample_rate))
                astream.layout = "stereo"
                astream.bit_rate = AUDIO_BITRATE
            n_frames = 0
            for frame in frames:
                img = np.asarray(frame)
                if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
                    raise ValueError(f"frames must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
                if vstream is None:
                    new = container.add_stream(encoding.encoder, rate=rate, options=dict(encoding.options))
                    if not isinstance(new, av.VideoStream):  # typed by the encoder's name; ours are video encoders
                        raise ValueError(f"{encoding.encoder} is not a video encoder")
                    vstream = new
                    vstream.width, vstream.height = _even(img.shape[1]), _even(img.shape[0])
                    vstream.pix_fmt = encoding.pix_fmt
                if img.shape[0] != vstream.height or img.shape[1] != vstream.width:
                    pad = np.zeros((vstream.height, vstream.width, 3), np.uint8)
                    h, w = min(img.shape[0], vstream.height), min(img.shape[1], vstream.width)
                    pad[:h, :w] = img[:h, :w]
                    img = pad
                vf = av.VideoFrame.from_ndarray(np.ascontiguousarray(img), format="rgb24")
                vf.pts = n_frames
                for packet in vstream.encode(vf):
                    container.mux(packet)
                n_frames += 1
            if vstream is None:
                raise ValueError("no frames to write")
            for packet in vstream.encode():
                container.mux(packet)
            if astream is not None and audio is not None:
                samples = _as_float_stereo(audio)
                chunk = 1024  # AAC frame size
                for start in range(0, len(samples), chunk):
                    block = np.ascontiguousarray(samples[start : start + chunk].T)  # planar (2, n)
                    af = av.AudioFrame.from_ndarray(block, format="fltp", layout="stereo")
                    af.sample_rate = int(sample_rate)
                    af.pts = start
                    for packet in astream.encode(af):
                        container.mux(packet)
                for packet in astream.encode():
                    container.mux(packet)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


class ClipJoiner:
    """One MP4 at `path` made of separately encoded clips placed back to back by stream copy (no
    re-encoding, as FFmpeg's concat demuxer joins files): each clip keeps its own first keyframe,
    so a clip decodes alone from its start time. Clips must share codec, size and frame rate (one
    `VideoEncoding`, one fps). The caller owns atomicity (the LeRobot export writes into a
    temporary folder)."""

    def __init__(self, path: Path) -> None:
        import av

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._out = av.open(str(self.path), mode="w", format="mp4")
        self._stream: Any = None
        self._offset = 0  # in the clips' time base
        self._time_base: Fraction | None = None
        self.bytes = 0  # the clips' sizes added up (the joined file is about this big)

    def append(self, clip: Path) -> tuple[float, float]:
        """Add the video of `clip` at the end; return its (start, end) in seconds in the joined file."""
        import av

        with av.open(str(clip)) as src:
            s = src.streams.video[0]
            if self._stream is None:
                self._stream, self._time_base = self._out.add_stream_from_template(s, opaque=True), s.time_base
            elif s.time_base != self._time_base:
                raise ValueError(f"{clip}: time base {s.time_base}, the joined clips have {self._time_base}")
            if s.duration is None or s.time_base is None:
                raise ValueError(f"{clip}: the video stream states no duration")
            for packet in src.demux(s):
                if packet.dts is None:  # the demuxer's end-of-stream marker
                    continue
                packet.pts = None if packet.pts is None else packet.pts + self._offset
                packet.dts += self._offset
                packet.stream = self._stream
                self._out.mux(packet)
            start = self._offset
            self._offset += int(s.duration)
            tb = s.time_base
        self.bytes += Path(clip).stat().st_size
        return float(start * tb), float(self._offset * tb)

    def close(self) -> None:
        self._out.close()


def probe_mp4(path: Path) -> dict:
    """What a player sees in `path`: frame count, size, rate, duration and the audio's layout."""
    import av

    with av.open(str(path)) as container:
        info: dict = {"video_frames": 0, "audio_channels": 0, "audio_rate": 0}
        video = next((s for s in container.streams if s.type == "video"), None)
        audio = next((s for s in container.streams if s.type == "audio"), None)
        if video is not None:
            vctx: Any = video.codec_context  # a VideoCodecContext (PyAV types the generic base)
            info["width"], info["height"] = vctx.width, vctx.height
            info["fps"] = float(video.average_rate) if video.average_rate else 0.0
        if audio is not None:
            actx: Any = audio.codec_context  # an AudioCodecContext
            info["audio_channels"] = actx.channels
            info["audio_rate"] = actx.sample_rate
        info["duration_s"] = float(container.duration) / 1e6 if container.duration else 0.0
        info["streams"] = [s.type for s in container.streams]
        if video is not None:
            info["video_frames"] = sum(1 for _ in container.decode(video=0))
        return info
