"""One video frame per control step, the same for a stored episode (`view`) and an evaluated one
(`evaluate --video`): head RGB, head depth and the top-down map side by side, the binaural
spectrogram scrolling past a cursor at the step, and a caption. Picture and sound stay in step:
frame t shows the track at the sample where step t's observation was taken.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw

from echo_data.viz.spectrogram import scrolling_strip, spectrogram_picture
from echo_data.viz.topdown import Point, TopDownMap

PANEL = 256  # side of the image and map panels (pixels)
SPEC_H = 128  # spectrogram strip height
CAPTION_H = 28
WIDTH, HEIGHT = 3 * PANEL, PANEL + SPEC_H + CAPTION_H
SPEC_SECONDS = 4.0  # spectrogram history shown left of the cursor
SPEC_AHEAD = 1.0  # and ahead of it
DEPTH_RANGE_M = 6.0  # depth colour scale: 0 m .. this


def fit_panel(img: np.ndarray) -> np.ndarray:
    """A camera image scaled into a PANEL x PANEL square without distortion."""
    from echo_data.media import fit_nearest

    h, w = img.shape[:2]
    s = PANEL / max(h, w)
    fitted = fit_nearest(img, max(1, round(w * s)), max(1, round(h * s)))
    out = np.zeros((PANEL, PANEL, 3), dtype=np.uint8)
    y, x = (PANEL - fitted.shape[0]) // 2, (PANEL - fitted.shape[1]) // 2
    out[y : y + fitted.shape[0], x : x + fitted.shape[1]] = fitted
    return out


def depth_colours(depth_m: np.ndarray) -> np.ndarray:
    """Depth in metres as turbo colours over 0 .. DEPTH_RANGE_M."""
    from echo_data.media import colour_lut

    return colour_lut("turbo")[np.clip(np.asarray(depth_m, dtype=np.float64) / DEPTH_RANGE_M * 255, 0, 255).astype(np.uint8)]


class EpisodeFrames:
    """Composes the frames of one episode from its map and its whole binaural track."""

    def __init__(self, topdown: TopDownMap, audio: np.ndarray, fs: int) -> None:
        self.map = topdown
        self.fs = fs
        self.picture, self.cols_per_s = spectrogram_picture(audio, fs)
        if topdown.width != PANEL or topdown.height != PANEL:
            raise ValueError(f"the map panel must be {PANEL} x {PANEL} px, got {topdown.width} x {topdown.height}")

    def frame(
        self,
        rgb: np.ndarray | None,
        depth_m: np.ndarray | None,
        path: Sequence[Point],
        yaw: float,
        sample: int,
        caption: str,
        sounding: Sequence[bool] | None = None,
    ) -> np.ndarray:
        """(HEIGHT, WIDTH, 3) uint8: the step whose observation was taken at `sample` of the track."""
        canvas = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)
        if rgb is not None:
            canvas[:PANEL, :PANEL] = fit_panel(np.asarray(rgb, dtype=np.uint8))
        if depth_m is not None:
            canvas[:PANEL, PANEL : 2 * PANEL] = fit_panel(depth_colours(depth_m))
        canvas[:PANEL, 2 * PANEL :] = self.map.draw(path, yaw, sounding)
        canvas[PANEL : PANEL + SPEC_H] = scrolling_strip(self.picture, self.cols_per_s, sample / self.fs, WIDTH, SPEC_H, SPEC_SECONDS, SPEC_AHEAD)
        img = Image.fromarray(canvas)
        ImageDraw.Draw(img).text((8, PANEL + SPEC_H + 8), caption, fill=(255, 255, 255))
        return np.asarray(img)
