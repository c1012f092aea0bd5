"""`preview`'s acoustic_map.png: the steady sound level of every event's source over the plan at
ear height, one panel per event, on the one map of `echo_data.viz.topdown`.

The colour scale runs from the recipe's room-noise floor (dB(A), the bed every episode carries)
up to the loudest cell, so a room behind a door that is still above the noise reads as a colour,
not as black; cells below the noise floor are painted a flat grey and named in the legend. Axes
are plan metres, the colour bar dB SPL at the source's drawn level.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

BELOW_FLOOR_RGB = (120, 120, 120)  # cells below the noise floor
SOURCE_MARK = "*"


def level_colours(level: np.ndarray, floor_db: float, top_db: float) -> np.ndarray:
    """(ny, nx) dB (NaN off the floor) -> rgba uint8: inferno from floor_db to top_db, grey below
    the floor, transparent off the floor."""
    from matplotlib import colormaps

    rgba = np.zeros((*level.shape, 4), np.uint8)
    ok = np.isfinite(level)
    x = np.clip((np.where(ok, level, floor_db) - floor_db) / max(top_db - floor_db, 1e-6), 0.0, 1.0)
    rgba[...] = (colormaps["inferno"](x) * 255).astype(np.uint8)
    below = ok & (level < floor_db)
    rgba[below, :3] = BELOW_FLOOR_RGB
    rgba[..., 3] = np.where(ok, 255, 0)
    return rgba


def save_acoustic_maps(
    plan: Any,
    maps: Sequence[tuple[str, tuple[float, float, float], float, np.ndarray]],
    grid_extent: tuple[float, float, float, float],
    floor_db: float,
    out: Path,
    px_per_m: float = 40.0,
) -> None:
    """Write one panel per event: (category, source xyz, level at 1 m dB SPL, level grid (ny, nx)
    dB SPL with NaN off the floor) over `plan`; `grid_extent` = (xmin, xmax, ymin, ymax) of the grid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch

    from echo_data.viz.topdown import TopDownMap

    top = max(float(np.ceil(np.nanmax(g) / 5) * 5) for *_, g in maps)
    floor = min(floor_db, top - 5.0)
    n = len(maps)
    b = plan.bounds
    aspect = (b.ymax - b.ymin) / max(b.xmax - b.xmin, 1e-6)
    fig, axes = plt.subplots(1, n, figsize=(5.5 * n + 1.5, 5.5 * aspect + 1.4), squeeze=False)
    for ax, (category, src, l1m, grid) in zip(axes[0], maps):
        m = TopDownMap(plan, [{"category": category, "source": src}], px_per_m=px_per_m, field=(level_colours(grid, floor, top), grid_extent))
        ax.imshow(m.base, extent=m.metres_extent())
        ax.plot(src[0], src[1], marker=SOURCE_MARK, color="lime", ms=16, mec="black")
        ax.set_title(f"{category} at {l1m:.0f} dB SPL @ 1 m")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal")
    sm = plt.cm.ScalarMappable(norm=Normalize(floor, top), cmap="inferno")
    fig.colorbar(sm, ax=axes[0].tolist(), shrink=0.8, label="steady level at ear height (dB SPL)")
    fig.legend(handles=[Patch(color=(BELOW_FLOOR_RGB[0] / 255, BELOW_FLOOR_RGB[1] / 255, BELOW_FLOOR_RGB[2] / 255), label=f"below the colour floor: the room-noise bed, {floor:.0f} dB(A)")],
               loc="lower center", ncol=1, frameon=False)
    fig.suptitle("sound level of each event's source over the plan (walls, doors, furniture as on the top-down map)")
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
