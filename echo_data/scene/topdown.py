"""Top-down picture of a floor plan (matplotlib, Agg): for previews, debugging and papers.

Shows rooms with their kind, walls, doorways, door leaves with swing arcs, doorbells,
furniture, sink + faucet, objects (sounding targets highlighted), the start pose, the expert
path and a scale bar.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib import patches  # noqa: E402

from echo_data.scene.floorplan import FloorPlan  # noqa: E402

ROOM_COLOURS = {
    "living": "#f3e6c8",
    "kitchen": "#dcefd8",
    "bedroom": "#dde4f5",
    "bathroom": "#d6eef2",
    "hall": "#eeeeee",
    "study": "#f2dde8",
}
FURNITURE_COLOURS = {
    "table": "#b08850",
    "counter": "#9a9a8a",
    "shelf": "#8c6a44",
    "cabinet": "#a67c52",
    "sofa": "#7a8fb0",
    "bed": "#c0a0b8",
    "sink_cabinet": "#e8e8f0",
}
TARGET_COLOURS = {"phone": "#d62728", "alarm": "#ff7f0e", "furby": "#9467bd", "doorbell": "#e377c2", "sink": "#1f77b4"}


def _event_fields(e: Any) -> tuple[str, str, tuple[float, float, float] | None]:
    """(category, target, source) of a SoundEvent or a plain dict."""
    if isinstance(e, dict):
        return e.get("category", ""), e.get("target", ""), e.get("source")
    return e.category, e.target, e.source


def draw_topdown(
    plan: FloorPlan,
    out: Path,
    path: Sequence[tuple[float, float]] | None = None,
    start: tuple[float, float, float] | None = None,
    events: Sequence[Any] = (),
    title: str | None = None,
) -> None:
    """Write a PNG of `plan` to `out` (parent folders are created)."""
    b = plan.bounds
    w, h = b.xmax - b.xmin, b.ymax - b.ymin
    scale = 1.1
    fig, ax = plt.subplots(figsize=(max(4.0, w * scale + 1.2), max(4.0, h * scale + 1.4)), dpi=110)
    ax.set_aspect("equal")
    ax.set_xlim(b.xmin - 0.6, b.xmax + 0.6)
    ax.set_ylim(b.ymin - 1.0, b.ymax + 0.6)
    ax.axis("off")

    for r in plan.rooms:
        ax.add_patch(patches.Rectangle((r.rect.xmin, r.rect.ymin), *r.rect.size, color=ROOM_COLOURS.get(r.kind, "#f5f5f5"), zorder=0))
        cx, cy = r.rect.center
        ax.text(cx, cy, f"{r.kind} {r.index}", ha="center", va="center", fontsize=10, color="#555555", alpha=0.8, zorder=1, style="italic")

    for fu in plan.furnishings:  # rugs on the floor, curtains in front of walls (visual, absorbing)
        fp = fu.footprint
        if fu.kind == "rug":
            ax.add_patch(patches.Rectangle((fp.xmin, fp.ymin), *fp.size, facecolor="#d9c7a3", edgecolor="#a08a60", lw=0.6, ls="--", alpha=0.7, zorder=2))
        else:
            ax.add_patch(patches.Rectangle((fp.xmin, fp.ymin), *fp.size, facecolor="#3c8d3c", edgecolor="#3c8d3c", lw=2.0, zorder=6))

    for wseg in plan.walls:
        fp = wseg.footprint
        ax.add_patch(patches.Rectangle((fp.xmin, fp.ymin), *fp.size, color="#222222" if wseg.exterior else "#444444", zorder=5))

    targets = {_event_fields(e)[1]: _event_fields(e)[0] for e in events}

    for d in plan.doors:
        edge = d.free_edge(d.angle)
        ax.plot([d.hinge[0], edge[0]], [d.hinge[1], edge[1]], color="#8b5a2b", lw=3.5, solid_capstyle="butt", zorder=6)
        t0 = math.degrees(d.leaf_yaw(0.0))
        t1 = math.degrees(d.leaf_yaw(d.max_angle))
        ax.add_patch(
            patches.Arc(d.hinge, 2 * d.width, 2 * d.width, theta1=min(t0, t1), theta2=max(t0, t1), color="#8b5a2b", lw=0.8, ls="--", zorder=6)
        )
        tgt = f"door:{d.index}"
        if d.doorbell is not None:
            ring = TARGET_COLOURS["doorbell"] if tgt in targets else "#666666"
            ax.plot(d.doorbell[0], d.doorbell[1], marker="*", ms=13 if tgt in targets else 9, color=ring, mec="k", mew=0.5, zorder=9)
        ax.text(d.hinge[0], d.hinge[1], f" d{d.index}", fontsize=6, color="#8b5a2b", zorder=9)

    for f in plan.furniture:
        fp = f.footprint
        ax.add_patch(
            patches.Rectangle((fp.xmin, fp.ymin), *fp.size, facecolor=FURNITURE_COLOURS.get(f.kind, "#999999"), edgecolor="#333333", lw=0.7, zorder=3)
        )
        # a tick on the front side
        fx, fy = math.cos(f.yaw), math.sin(f.yaw)
        hx, hy = fp.size[0] / 2 * abs(fx), fp.size[1] / 2 * abs(fy)
        ax.plot([f.center[0] + fx * hx * 0.6, f.center[0] + fx * (hx + 0.0)], [f.center[1] + fy * hy * 0.6, f.center[1] + fy * hy], color="#333333", lw=0.7, zorder=4)
        label = "sink" if f.kind == "sink_cabinet" else f.kind
        ax.text(*f.center, f"{label}\n#{f.index}", ha="center", va="center", fontsize=6, zorder=4)

    for fc in plan.faucets:
        sink = plan.furniture[fc.furniture]
        fp = sink.footprint.expanded(-0.08)
        ax.add_patch(patches.Ellipse(sink.center, fp.size[0], fp.size[1], facecolor="#b9d7ee", edgecolor="#4a6f8a", lw=0.6, zorder=4))
        yaw = fc.yaw + fc.angle
        tip = (fc.pivot[0] + fc.lever_length * math.cos(yaw), fc.pivot[1] + fc.lever_length * math.sin(yaw))
        ax.plot([fc.pivot[0], tip[0]], [fc.pivot[1], tip[1]], color="#333333", lw=2, zorder=8)
        running = fc.angle > fc.closed_tolerance
        ax.plot(fc.spout[0], fc.spout[1], "o", ms=7 if running else 4, color=TARGET_COLOURS["sink"] if running else "#777777", zorder=8)

    for o in plan.objects:
        colour = TARGET_COLOURS.get(o.category, "#d62728") if o.sounding else "#9a9a9a"
        ax.plot(o.position[0], o.position[1], "o", ms=8 if o.sounding else 5, color=colour, mec="k", mew=0.6, zorder=10)
        if o.sounding:
            ax.text(o.position[0] + 0.1, o.position[1] + 0.1, o.category, fontsize=8, color=colour, weight="bold", zorder=11)

    for e in events:
        cat, tgt, src = _event_fields(e)
        if src is not None:
            ax.plot(src[0], src[1], marker="o", ms=16, mfc="none", mec=TARGET_COLOURS.get(cat, "k"), mew=1.5, zorder=11)

    if path:
        xs, ys = zip(*path)
        ax.plot(xs, ys, "-", color="#2ca02c", lw=1.8, zorder=12)
        ax.plot(xs[-1], ys[-1], "x", color="#2ca02c", ms=8, zorder=12)

    if start is not None:
        x, y, yaw = start
        ax.add_patch(patches.Circle((x, y), 0.3, facecolor="#2ca02c", alpha=0.35, zorder=12))
        ax.arrow(x, y, 0.45 * math.cos(yaw), 0.45 * math.sin(yaw), width=0.04, color="#1a6e1a", zorder=13, length_includes_head=True)
        ax.text(x, y - 0.45, "start", ha="center", fontsize=7, color="#1a6e1a", zorder=13)

    # scale bar: 1 m
    sx, sy = b.xmin, b.ymin - 0.6
    ax.plot([sx, sx + 1.0], [sy, sy], color="k", lw=3)
    ax.text(sx + 0.5, sy - 0.25, "1 m", ha="center", fontsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
