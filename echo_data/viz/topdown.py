"""The one top-down map of an episode: `preview`'s plan picture, `view`'s and `evaluate --video`'s
map panel, and the layout pictures are all drawn here.

The floor plan (rooms, rugs and curtains, furniture, sink, walls, doors with their swing, bells)
is rasterised once; the sound sources (in their category colour while they sound, hollow grey
once resolved), the robot's path, its pose and its start are drawn per frame on a copy, so a
video costs one small copy and a few lines per step. Plan metres map to pixels with north up.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from echo_data.viz import palette

Point = tuple[float, float]


def event_fields(e: Any) -> tuple[str, tuple[float, float, float] | None]:
    """(category, source position) of a SoundEvent or of its record in meta/episodes.parquet."""
    if isinstance(e, dict):
        return e.get("category", ""), e.get("source")
    return e.category, e.source


class TopDownMap:
    """A floor plan drawn once at `px_per_m` (or fitted into a `size` square); `draw` adds what moves.

    `plan` may be None (a dataset whose plan cannot be regenerated): the map then shows the
    sources and the path inside the box of `extent` points. `labels` adds room and furniture
    names and a 1 m scale bar (for pictures, not for small video panels).
    """

    MARGIN = 8  # px around the plan

    def __init__(
        self,
        plan: Any,
        events: Sequence[Any] = (),
        size: int = 256,
        px_per_m: float | None = None,
        labels: bool = False,
        extent: Sequence[Point] = (),
    ) -> None:
        self.plan = plan
        self.events = [event_fields(e) for e in events]
        pts = list(extent)
        if plan is not None:  # the plan's box: the same picture size with or without sources and path
            b = plan.bounds
            pts += [(b.xmin, b.ymin), (b.xmax, b.ymax)]
        else:
            pts += [(s[0], s[1]) for _, s in self.events if s is not None]
        arr = np.array(pts or [(0.0, 0.0)], dtype=np.float64)
        pad = 0.0 if plan is not None else 0.5
        self.lo = arr.min(axis=0) - pad
        hi = arr.max(axis=0) + pad
        span = np.maximum(hi - self.lo, 1e-6)
        bar = 0.8 if labels else 0.0  # metres below the plan for the scale bar
        if px_per_m is None:
            self.scale = (size - 2 * self.MARGIN) / max(span[0], span[1] + bar)
            self.width = self.height = size
        else:
            self.scale = px_per_m
            self.width = int(math.ceil(span[0] * px_per_m)) + 2 * self.MARGIN
            self.height = int(math.ceil((span[1] + bar) * px_per_m)) + 2 * self.MARGIN
        self.top = self.lo[1] + span[1]
        self.labels = labels
        img = Image.new("RGB", (self.width, self.height), palette.BACKGROUND)
        if plan is not None:
            self._draw_plan(ImageDraw.Draw(img))
        if labels:
            self._scale_bar(ImageDraw.Draw(img))
        self.base = img

    # ------------------------------------------------------------ geometry

    def px(self, x: float, y: float) -> Point:
        """Plan metres -> pixel (north up)."""
        return self.MARGIN + (x - self.lo[0]) * self.scale, self.MARGIN + (self.top - y) * self.scale

    def box(self, xmin: float, ymin: float, xmax: float, ymax: float) -> list[float]:
        (a, b), (c, d) = self.px(xmin, ymax), self.px(xmax, ymin)
        return [a, b, max(a, c), max(b, d)]

    def _r(self, metres: float, least: float = 2.0) -> float:
        return max(least, metres * self.scale)

    # ------------------------------------------------------------ the static plan

    def _draw_plan(self, d: ImageDraw.ImageDraw) -> None:
        plan = self.plan
        for r in plan.rooms:
            d.rectangle(self.box(r.rect.xmin, r.rect.ymin, r.rect.xmax, r.rect.ymax), fill=palette.ROOMS.get(r.kind, palette.ROOM_OTHER))
        for fu in plan.furnishings:  # rugs on the floor (outlined), curtains in front of walls (filled)
            fp = fu.footprint
            if fu.kind == "rug":
                d.rectangle(self.box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), outline=palette.RUG, width=1)
            else:
                d.rectangle(self.box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), fill=palette.CURTAIN)
        for f in plan.furniture:
            fp = f.footprint
            d.rectangle(self.box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), fill=palette.FURNITURE.get(f.kind, palette.FURNITURE_OTHER), outline=palette.OUTLINE)
        for fc in plan.faucets:
            fp = plan.furniture[fc.furniture].footprint.expanded(-0.08)
            d.ellipse(self.box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), fill=palette.BASIN, outline=palette.OUTLINE)
            yaw = fc.yaw + fc.angle
            tip = (fc.pivot[0] + fc.lever_length * math.cos(yaw), fc.pivot[1] + fc.lever_length * math.sin(yaw))
            d.line([self.px(fc.pivot[0], fc.pivot[1]), self.px(*tip)], fill=palette.OUTLINE, width=2)
        for w in plan.walls:
            fp = w.footprint
            d.rectangle(self.box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), fill=palette.EXTERIOR_WALL if w.exterior else palette.INTERIOR_WALL)
        for door in plan.doors:
            hx, hy = self.px(*door.hinge)
            rad = door.width * self.scale
            a0, a1 = sorted((-math.degrees(door.leaf_yaw(0.0)), -math.degrees(door.leaf_yaw(door.max_angle))))
            d.arc([hx - rad, hy - rad, hx + rad, hy + rad], a0, a1, fill=palette.DOOR, width=1)
            d.line([(hx, hy), self.px(*door.free_edge())], fill=palette.DOOR, width=max(2, int(self._r(0.05))))
            if door.doorbell is not None:
                bx, by = self.px(door.doorbell[0], door.doorbell[1])
                s = self._r(0.08, 3.0)
                d.polygon([(bx, by - s), (bx + s, by), (bx, by + s), (bx - s, by)], fill=palette.DOOR)
        for o in plan.objects:
            if not o.sounding:  # distractors: small grey dots (sounding ones are the events' sources)
                x, y = self.px(o.position[0], o.position[1])
                s = self._r(0.05, 2.0)
                d.ellipse([x - s, y - s, x + s, y + s], fill=palette.SILENT)
        if self.labels:
            for r in plan.rooms:
                d.text(self.px(*r.rect.center), f"{r.kind} {r.index}", fill=palette.TEXT, anchor="mm")
            for f in plan.furniture:
                d.text(self.px(*f.center), "sink" if f.kind == "sink_cabinet" else f.kind, fill=palette.OUTLINE, anchor="mm")

    def _scale_bar(self, d: ImageDraw.ImageDraw) -> None:
        x0, y0 = self.px(self.lo[0], self.lo[1] - 0.4)
        d.line([(x0, y0), (x0 + self.scale, y0)], fill=(0, 0, 0), width=3)
        d.text((x0 + self.scale / 2, y0 + 4), "1 m", fill=(0, 0, 0), anchor="ma")

    # ------------------------------------------------------------ what moves

    def draw(
        self,
        path: Sequence[Point] = (),
        yaw: float | None = None,
        sounding: Sequence[bool] | None = None,
        start: tuple[float, float, float] | None = None,
    ) -> np.ndarray:
        """The map with the sources (`sounding[e]`: still playing; default all), the start pose,
        the path so far and, with `yaw`, the robot at its end; (height, width, 3) uint8."""
        img = self.base.copy()
        d = ImageDraw.Draw(img)
        s = self._r(0.14, 4.0)
        for e, (category, src) in enumerate(self.events):
            if src is None:
                continue
            x, y = self.px(src[0], src[1])
            if sounding is None or sounding[e]:
                d.ellipse([x - s, y - s, x + s, y + s], fill=palette.source(category), outline=(0, 0, 0))
            else:
                d.ellipse([x - s, y - s, x + s, y + s], outline=palette.SILENT, width=2)
        if start is not None:
            x, y = self.px(start[0], start[1])
            r = self._r(0.3, 5.0)
            d.ellipse([x - r, y - r, x + r, y + r], outline=palette.ROBOT, width=2)
            d.line([(x, y), self.px(start[0] + 0.45 * math.cos(start[2]), start[1] + 0.45 * math.sin(start[2]))], fill=palette.ROBOT, width=2)
        pts = [self.px(*p) for p in path]
        if len(pts) > 1:
            d.line(pts, fill=palette.ROBOT, width=2)
        if pts and yaw is not None:
            x, y = pts[-1]
            r = self._r(0.25, 4.0)
            end = path[-1]
            d.ellipse([x - r, y - r, x + r, y + r], fill=palette.ROBOT)
            d.line([(x, y), self.px(end[0] + 0.5 * math.cos(yaw), end[1] + 0.5 * math.sin(yaw))], fill=(0, 0, 0), width=2)
        return np.asarray(img)


def draw_topdown(
    plan: Any,
    out: Path,
    path: Sequence[Point] | None = None,
    start: tuple[float, float, float] | None = None,
    events: Sequence[Any] = (),
    title: str | None = None,
    px_per_m: float = 80.0,
) -> None:
    """Write a labelled PNG of `plan` with the sources, start pose and path to `out` (folders created)."""
    m = TopDownMap(plan, events, px_per_m=px_per_m, labels=True)
    img = Image.fromarray(m.draw(path or (), sounding=None, start=start))
    if title:
        canvas = Image.new("RGB", (img.width, img.height + 16), palette.BACKGROUND)
        canvas.paste(img, (0, 16))
        ImageDraw.Draw(canvas).text((m.MARGIN, 2), title, fill=(0, 0, 0))
        img = canvas
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    img.save(out)
