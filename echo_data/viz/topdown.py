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

from echo_data.target import Target
from echo_data.viz import palette

Point = tuple[float, float]


def target_point(plan: Any, target: str) -> Point | None:
    """Where a chain call's target is on the plan: an object's position, a door's middle, a
    faucet's pivot or a piece of furniture's centre (None if the plan has no such thing, or the
    text is no target: `Target` reads the text, its one owner)."""
    try:
        t = Target.parse(target)
        if t.kind == "door":
            door = plan.doors[t.index]
            edge = door.free_edge()
            return ((door.hinge[0] + edge[0]) / 2, (door.hinge[1] + edge[1]) / 2)
        if t.kind == "faucet":
            return tuple(plan.faucets[t.index].pivot[:2])
        if t.kind == "furniture":
            return tuple(plan.furniture[t.index].center)
    except (IndexError, ValueError):
        return None
    found = [o for o in plan.objects if o.name == t.name]
    return (found[0].position[0], found[0].position[1]) if found else None


def episode_plan(manifest: dict[str, Any], scene_seed: int) -> Any:
    """A stored episode's apartment, regenerated from the manifest's recipe and the episode's
    scene seed (None if impossible: the map is still useful without walls)."""
    try:
        from echo_data.recipe import Recipe
        from echo_data.scene.generate import generate_floorplan_from_seed

        return generate_floorplan_from_seed(Recipe.model_validate(manifest["recipe"]), int(scene_seed))
    except Exception:  # the map is still useful without walls
        return None


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
        field: tuple[np.ndarray, tuple[float, float, float, float]] | None = None,
    ) -> None:
        self.plan = plan
        self.field = field  # (rgba (ny, nx, 4) uint8, row 0 = south; (xmin, xmax, ymin, ymax) metres): painted on the floor
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
        if self.field is not None:  # a quantity over the floor (the acoustic map's levels), under furniture and walls
            self._paint_field(d)
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
        if self.labels:  # room names are drawn last, in `draw`: the start ring and the path covered them
            for f in plan.furniture:
                d.text(self.px(*f.center), "sink" if f.kind == "sink_cabinet" else f.kind, fill=palette.OUTLINE, anchor="mm")

    def _paint_field(self, d: ImageDraw.ImageDraw) -> None:
        assert self.field is not None
        rgba, (xmin, xmax, ymin, ymax) = self.field
        ny, nx = rgba.shape[:2]
        dx, dy = (xmax - xmin) / nx, (ymax - ymin) / ny
        for j in range(ny):
            for i in range(nx):
                if rgba[j, i, 3]:
                    x0 = xmin + i * dx
                    y0 = ymin + j * dy
                    d.rectangle(self.box(x0, y0, x0 + dx, y0 + dy), fill=tuple(int(c) for c in rgba[j, i, :3]))

    def metres_extent(self) -> tuple[float, float, float, float]:
        """(left, right, bottom, top) of the whole picture in plan metres (matplotlib's imshow extent)."""
        m = self.MARGIN / self.scale
        return (self.lo[0] - m, self.lo[0] + (self.width - self.MARGIN) / self.scale, self.top - (self.height - self.MARGIN) / self.scale, self.top + m)

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
        moved: dict[int, Point] | None = None,
        targets: Sequence[tuple[str, Point]] = (),
    ) -> np.ndarray:
        """The map with the sources (`sounding[e]`: still playing; default all; `moved[e]`: where
        source e is now when it is not where it started: in the robot's hand, or where it was put down), the chain's targets (numbered squares, in
        chain order), the start pose, the path so far and, with `yaw`, the robot at its end;
        (height, width, 3) uint8."""
        img = self.base.copy()
        d = ImageDraw.Draw(img)
        s = self._r(0.14, 4.0)
        places: dict[Point, list[str]] = {}  # one square per place, naming every call there in chain order
        target_labels: list[tuple[Point, str, tuple[int, int, int], str]] = []
        for k, (label, p) in enumerate(targets):
            places.setdefault((round(p[0], 2), round(p[1], 2)), []).append(f"{k + 1} {label}")
        for (tx, ty), names in places.items():
            x, y = self.px(tx, ty)
            q = self._r(0.12, 5.0)
            d.rectangle([x - q, y - q, x + q, y + q], outline=palette.TARGET, width=2)
            target_labels.append(((x + q + 3, y + q + 1), ", ".join(names), palette.TARGET, "la"))
        carried = moved or {}
        for e, (category, src) in enumerate(self.events):
            if src is not None and e not in carried:
                self._source(d, self.px(src[0], src[1]), category, sounding is None or sounding[e], s)
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
        for e, (mx, my) in carried.items():  # moved (in the hand, or where it was put down): over the robot
            self._source(d, self.px(mx, my), self.events[e][0], sounding is None or sounding[e], s * 0.8)
        rooms = [(self.px(*r.rect.center), f"{r.kind} {r.index}", palette.TEXT, "mm") for r in self.plan.rooms] if self.labels and self.plan is not None else []
        for at, text, colour, anchor in [*rooms, *target_labels]:  # on top, on a backing: never hidden by a mark or the furniture under it
            left, top, right, bottom = d.textbbox(at, text, anchor=anchor)
            d.rectangle([left - 1, top - 1, right + 1, bottom + 1], fill=palette.BACKGROUND)
            d.text(at, text, fill=colour, anchor=anchor)
        return np.asarray(img)

    @staticmethod
    def _source(d: ImageDraw.ImageDraw, at: Point, category: str, sounding: bool, s: float) -> None:
        """A source: a disc in its category colour while it sounds, a hollow grey ring once silenced."""
        x, y = at
        if sounding:
            d.ellipse([x - s, y - s, x + s, y + s], fill=palette.source(category), outline=(0, 0, 0))
        else:
            d.ellipse([x - s, y - s, x + s, y + s], outline=palette.SILENT, width=2)


def legend_entries(categories: Sequence[str]) -> list[tuple[str, tuple[int, int, int], str]]:
    """(label, colour, shape) of every mark the map draws: the robot, each source category, a
    silenced source, the other (never sounding) objects, a doorbell's button, a chain target and
    the start pose."""
    return (
        [("robot and path", palette.ROBOT, "disc")]
        + [(c, palette.source(c), "disc") for c in dict.fromkeys(categories)]
        + ([("doorbell button", palette.DOOR, "diamond")] if "doorbell" in categories else [])
        + [("silenced source", palette.SILENT, "ring"), ("other object", palette.SILENT, "dot"), ("chain target (in order)", palette.TARGET, "square"), ("start pose", palette.ROBOT, "ring")]
    )


def draw_legend(d: ImageDraw.ImageDraw, entries: Sequence[tuple[str, tuple[int, int, int], str]], x0: float, y0: float, width: float, text: Any = (0, 0, 0)) -> float:
    """Legend marks and labels in rows from (x0, y0) within `width`; returns the y below them."""
    x, y = x0, y0
    for name, colour, shape in entries:
        w = 11 + int(d.textlength(name)) + 10
        if x + w > x0 + width and x > x0:
            x, y = x0, y + 14
        box = [x, y + 1, x + 8, y + 9]
        if shape == "disc":
            d.ellipse(box, fill=colour, outline=(0, 0, 0))
        elif shape == "diamond":  # as the map draws a door's bell button
            d.polygon([(x + 4, y + 1), (x + 8, y + 5), (x + 4, y + 9), (x, y + 5)], fill=colour)
        elif shape == "dot":  # as the map draws an object that never sounds: small, no outline
            d.ellipse([x + 2, y + 3, x + 6, y + 7], fill=colour)
        elif shape == "ring":
            d.ellipse(box, outline=colour, width=2)
        else:
            d.rectangle(box, outline=colour, width=2)
        d.text((x + 11, y), name, fill=text)
        x += w
    return y + 14


def draw_topdown(
    plan: Any,
    out: Path,
    path: Sequence[Point] | None = None,
    start: tuple[float, float, float] | None = None,
    events: Sequence[Any] = (),
    title: str | None = None,
    px_per_m: float = 80.0,
    chain: Sequence[Any] = (),
) -> None:
    """Write a labelled PNG of `plan` with the sources, the chain's targets (`chain`: SkillCalls),
    start pose and path to `out`, with a legend under it (folders created)."""
    m = TopDownMap(plan, events, px_per_m=px_per_m, labels=True)
    targets = [(c.skill, p) for c in chain if (p := target_point(plan, c.target)) is not None]
    img = Image.fromarray(m.draw(path or (), sounding=None, start=start, targets=targets))
    canvas = Image.new("RGB", (img.width, img.height + 16 + 14 * 6), palette.BACKGROUND)  # room for the title and legend rows
    canvas.paste(img, (0, 16))
    d = ImageDraw.Draw(canvas)
    if title:
        d.text((m.MARGIN, 2), title, fill=(0, 0, 0))
    bottom = draw_legend(d, legend_entries([c for c, _ in m.events]), m.MARGIN, img.height + 18, img.width - 2 * m.MARGIN)
    img = canvas.crop((0, 0, canvas.width, int(bottom) + 4))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    img.save(out)
