"""Video frames of an evaluated episode: what the robot saw, where it went, what it heard.

One frame per control step: the head camera (left), a top-down plan with the path so far, the
robot's heading and each sound source (red while it sounds, green once resolved) (right), and a
strip with the log-mel spectrogram of the last second at both ears (bottom, left ear on top).
The MP4 itself is written by `echo_data.media.write_mp4` with the binaural track.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from echo_data.dataset.schema import IMAGE_COLUMNS, MEL
from echo_data.media import colour_lut, fit_nearest

PANEL = 256  # px, side of the camera and plan panels
STRIP = 128  # px, height of the spectrogram strip
MEL_RANGE_DB = (-100.0, 0.0)  # log-mel floor and full scale (features clip at -100 dB)


class TopDown:
    """The plan drawn once (walls, doors, furniture); the path, robot and sources drawn per frame."""

    def __init__(self, spec: Any, size: int = PANEL) -> None:
        from PIL import Image, ImageDraw

        self.spec = spec
        b = spec.plan.bounds
        self.size = size
        self.scale = (size - 16) / max(b.xmax - b.xmin, b.ymax - b.ymin, 1e-6)
        self.x0, self.y0 = b.xmin, b.ymin
        self.h = b.ymax - b.ymin
        img = Image.new("RGB", (size, size), (250, 250, 247))
        d = ImageDraw.Draw(img)
        for f in spec.plan.furniture:
            r = f.footprint
            (ax, ay), (bx, by) = self.px(r.xmin, r.ymax), self.px(r.xmax, r.ymin)
            d.rectangle([ax, ay, bx, by], fill=(205, 200, 190))
        for w in spec.plan.walls:
            d.line([self.px(*w.a), self.px(*w.b)], fill=(40, 40, 40), width=3)
        for door in spec.plan.doors:
            d.line([self.px(*door.hinge), self.px(*door.free_edge())], fill=(120, 80, 40), width=2)
        self.base = img

    def px(self, x: float, y: float) -> tuple[float, float]:
        """Plan metres -> pixel (north up)."""
        return (8 + (x - self.x0) * self.scale, 8 + (self.h - (y - self.y0)) * self.scale)

    def draw(self, path: Sequence[tuple[float, float]], yaw: float, sounding: Sequence[bool]) -> np.ndarray:
        from PIL import ImageDraw

        img = self.base.copy()
        d = ImageDraw.Draw(img)
        for ev, on in zip(self.spec.events, sounding):
            cx, cy = self.px(ev.source[0], ev.source[1])
            d.ellipse([cx - 5, cy - 5, cx + 5, cy + 5], fill=(220, 30, 30) if on else (30, 160, 60))
        if len(path) > 1:
            d.line([self.px(*p) for p in path], fill=(30, 90, 220), width=2)
        if path:
            x, y = path[-1]
            cx, cy = self.px(x, y)
            d.ellipse([cx - 5, cy - 5, cx + 5, cy + 5], outline=(30, 90, 220), width=2)
            d.line([(cx, cy), self.px(x + 0.5 * math.cos(yaw), y + 0.5 * math.sin(yaw))], fill=(30, 90, 220), width=2)
        return np.asarray(img)


def compose(obs: dict[str, np.ndarray], plan_panel: np.ndarray, label: str = "") -> np.ndarray:
    """One (PANEL + STRIP, 2 * PANEL, 3) uint8 frame from an observation and a drawn plan panel."""
    from PIL import Image, ImageDraw

    frame = np.zeros((PANEL + STRIP, 2 * PANEL, 3), dtype=np.uint8)
    rgb = obs.get(IMAGE_COLUMNS["head_rgb"])
    if rgb is not None:
        frame[:PANEL, :PANEL] = fit_nearest(np.asarray(rgb, dtype=np.uint8), PANEL, PANEL)
    frame[:PANEL, PANEL:] = plan_panel
    mel = obs.get(MEL)
    if mel is not None:
        lo, hi = MEL_RANGE_DB
        both = np.concatenate([mel[::-1, :, 0], mel[::-1, :, 1]], axis=0)  # left ear on top, low bands at the bottom
        idx = np.clip((both - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)
        frame[PANEL:] = fit_nearest(colour_lut("magma")[idx], 2 * PANEL, STRIP)
    if label:
        img = Image.fromarray(frame)
        ImageDraw.Draw(img).text((6, 4), label, fill=(255, 255, 0))
        frame = np.asarray(img)
    return frame
