"""`torchvision.io.VideoReader` (pyav backend) for the LeRobot environment: torchvision 0.26+
dropped its video decoder, ledataset 0.4.4 still decodes through it; scripts/setup_lerobot.sh
installs this file as `torchvision.io._echo_pyav_reader` and exports the class as
`torchvision.io.VideoReader`. Semantics as torchvision documented them: iterate a stream's
frames as {"data": (C, H, W) uint8 tensor, "pts": seconds}; `seek(t, keyframes_only)` moves to
the key frame at or before t (pyav seeks key frames only, which is what callers ask for)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import av
import torch


class VideoReader:
    def __init__(self, path: str, stream: str = "video", num_threads: int = 0) -> None:
        if stream != "video":
            raise ValueError("the stand-in reads video streams only")
        self.container = av.open(str(path))
        self._stream = self.container.streams.video[0]
        self._frames: Iterator[Any] = self.container.decode(self._stream)

    def seek(self, time_s: float, keyframes_only: bool = False) -> VideoReader:
        tb = self._stream.time_base
        self.container.seek(int(time_s / tb) if tb else 0, stream=self._stream, backward=True, any_frame=False)
        self._frames = self.container.decode(self._stream)
        return self

    def __iter__(self) -> VideoReader:
        return self

    def __next__(self) -> dict[str, Any]:
        frame = next(self._frames)
        data = torch.from_numpy(frame.to_ndarray(format="rgb24")).permute(2, 0, 1).contiguous()
        return {"data": data, "pts": float(frame.pts * frame.time_base)}

    def get_metadata(self) -> dict[str, Any]:
        s = self._stream
        return {"video": {"fps": [float(s.average_rate or 0)], "duration": [float(s.duration * s.time_base) if s.duration else 0.0]}}
