"""The LeRobot export's pictures: depth as 8-bit 3-channel PNG cells, and the MP4 files, whose
episodes are encoded one by one with LeRobot's encoding and appended into shared files as LeRobot
v3.0 lays them out (`echo_data.dataset.lerobot` says where; `VideoLayout` carries its path
template, chunk size, file size limit and encoding, read from that module when an export starts)."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from echo_data.dataset.episode_arrays import decode_images
from echo_data.dataset.schema import IMAGE_TYPE
from echo_data.media import ClipJoiner, VideoEncoding, write_mp4


@dataclass(frozen=True)
class VideoLayout:
    """Where and how a video feature's files are written."""

    path: str  # "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    chunks_size: int  # files per chunk folder
    file_limit_mb: float  # a file takes episodes until the next would bring it to this size
    encoding: VideoEncoding


def options(enc: VideoEncoding) -> str:
    """An encoding's options as `name=value` words (`g` is the keyframe interval)."""
    return " ".join(f"{k}={v}" for k, v in sorted(enc.options.items()))


class VideoFiles:
    """The MP4 files of one video feature, laid out as LeRobot v3.0's recorder lays them out: each
    episode encoded alone (so it starts on a keyframe), then appended by stream copy to the open
    file at the file's running end time (its `from_timestamp`); a new file starts when the episode
    would bring the open one to the layout's `file_limit_mb`, and at each new split."""

    def __init__(self, dst: Path, key: str, fps: float, layout: VideoLayout) -> None:
        self.dst, self.key, self.fps, self.layout = dst, key, fps, layout
        self.n_files = 0
        self.joiner: ClipJoiner | None = None

    def add(self, rows: pa.Table) -> dict[str, Any]:
        """Encode the episode `rows` into the open file; return its `videos/{key}/*` record fields."""
        clip = self.dst / "videos" / f".episode-{self.key}.mp4"
        try:
            write_mp4(clip, (f for f in decode_images(rows.column(self.key))), self.fps, encoding=self.layout.encoding)
            if self.joiner is not None and self.joiner.bytes + clip.stat().st_size >= self.layout.file_limit_mb * 2**20:
                self.close()
            k, per = self.n_files, self.layout.chunks_size
            if self.joiner is None:
                self.joiner = ClipJoiner(self.dst / self.layout.path.format(video_key=self.key, chunk_index=k // per, file_index=k % per))
            start, end = self.joiner.append(clip)
        finally:
            clip.unlink(missing_ok=True)
        return {
            f"videos/{self.key}/chunk_index": k // per, f"videos/{self.key}/file_index": k % per,
            f"videos/{self.key}/from_timestamp": start, f"videos/{self.key}/to_timestamp": end,
        }

    def close(self) -> None:
        """Finish the open file; the next episode starts a new one."""
        if self.joiner is not None:
            self.joiner.close()
            self.joiner, self.n_files = None, self.n_files + 1


def depth_image(mm: np.ndarray, range_m: float) -> np.ndarray:
    """(T, H, W) uint16 millimetres -> (T, H, W, 3) uint8: 0..range_m linear to 0..255, clipped."""
    v = np.clip(np.rint(mm.astype(np.float64) * (255.0 / (range_m * 1000.0))), 0, 255).astype(np.uint8)
    return np.repeat(v[..., None], 3, axis=-1)


def png_cells(frames: np.ndarray) -> pa.Array:
    """(T, H, W, 3) uint8 -> an Image-struct column of PNG bytes."""
    from PIL import Image

    cells = []
    for f in frames:
        buf = io.BytesIO()
        Image.fromarray(f).save(buf, format="PNG", compress_level=1)
        cells.append({"bytes": buf.getvalue(), "path": None})
    return pa.array(cells, type=IMAGE_TYPE)
