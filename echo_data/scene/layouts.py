"""Apartment layout families: which axis-aligned rectangles make the rooms, and which of them
form one space.

The plan model stays a set of axis-aligned rectangles (`echo_data.floorplan`), because the
acoustics model every rectangle as a shoebox joined to its neighbours through openings. A room
that is not a rectangle — an L-shaped living room, an open-plan kitchen/living room — is two
rectangles of one space joined by a wide opening (`Layout.joins`): a doorway without a door,
from the floor to the ceiling, as wide as their shared wall less a short return at each end.
The generator cuts it like any doorway, so the SAPIEN walls, the navigation grid, the top-down
maps and the acoustic portals all see the same opening.

Families (recipe key `scene.layouts`):
- `rows`: 2-6 rooms tiled in rows (the generator before the other families, draw for draw);
- `l_shape`: rows of n + 1 rectangles in which the first (or last) rooms of two neighbouring
  rows, of clearly different widths, form one L-shaped living room;
- `corridor`: a hall 1.0-1.4 m wide (HALL_WIDTH) between two rows of rooms;
- `open_plan`: rows of n + 1 rectangles in which two neighbours sharing a long wall form one
  kitchen/living room (the larger part is the living area).

Sizes. Every rectangle other than the hall keeps the recipe's `scene.room_size` side range
(base.yaml: 3.2-5.0 m, i.e. 10-25 m² per rectangle). Against real flats:
- UK Nationally Described Space Standard (DCLG, 2015): a single bedroom at least 7.5 m² and
  2.15 m wide, a double at least 11.5 m² and 2.55 m (one of them 2.75 m) wide: our smallest
  rectangle (3.2 x 3.2 m, 10.2 m²) is above the single and as wide as the double;
- London Housing Design Guide (interim edition, 2010), combined living/kitchen/dining floor
  area of 23-31 m² for 2-6 person homes: an open-plan room or an L-shaped living room here is
  two rectangles, 20-50 m²;
- hall widths: UK Approved Document M vol. 1 (2015) asks 900-1200 mm of clear corridor width
  in dwellings depending on the door width and the approach, DIN 18040-2 (barrier-free
  dwellings) 1.20 m; HALL_WIDTH spans 1.0-1.4 m wall centre to wall centre, i.e. 0.9-1.3 m
  clear with 0.1 m walls, which a 0.64 m robot base still passes.

Everything here is pure and draws only from the rng it is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from echo_data.floorplan import Rect
from echo_data.recipe import Recipe

HALL_WIDTH = (1.0, 1.4)  # m, wall centre to wall centre (sources above)
L_STEP = 1.0  # m, at least this difference in width between the two parts of an L
OPEN_MIN_SHARED = 2.8  # m, shared wall of an open-plan kitchen/living room at least this long
OPENING_RETURN = 0.15  # m, wall left at each end of a wide opening (beyond half a wall thickness)

_ROW_PATTERNS: dict[int, tuple[tuple[int, ...], ...]] = {
    2: ((2,), (1, 1)),
    3: ((3,), (2, 1), (1, 2)),
    4: ((2, 2), (3, 1), (1, 3)),
    5: ((3, 2), (2, 3)),
    6: ((3, 3), (2, 2, 2)),
}
# n + 1 rectangles for n spaces with a joined pair (l_shape needs two rows at least)
_JOINED_PATTERNS: dict[int, tuple[tuple[int, ...], ...]] = {
    3: ((2, 1), (1, 2)),
    4: ((2, 2), (3, 1), (1, 3)),
    5: ((3, 2), (2, 3)),
    6: ((3, 3), (2, 2, 2)),
    7: ((4, 3), (3, 4)),
}


@dataclass(frozen=True)
class Layout:
    """Rectangles of one apartment and how they group into spaces.

    `joins`: pairs of rectangle indices that are one space, joined by a wide opening.
    `kinds`: room kinds fixed by the family (others are assigned by the generator).
    `no_entrance`: rectangles the entrance door must not open into (a narrow hall: a door leaf
    swinging into it would close it, and the robot could not open it there).
    """

    family: str
    rects: list[Rect]
    joins: tuple[tuple[int, int], ...] = ()
    kinds: dict[int, str] = field(default_factory=dict)
    no_entrance: frozenset[int] = frozenset()


def _r2(v: float) -> float:
    return round(float(v), 2)


def _split_length(total: float, k: int, lo: float, hi: float, rng: np.random.Generator) -> list[float]:
    """k lengths in [lo, hi] summing to `total` (assumed feasible), rounded to cm."""
    for _ in range(50):
        w = rng.dirichlet(np.full(k, 4.0)) * total
        if np.all(w >= lo + 0.01) and np.all(w <= hi - 0.01):
            break
    else:
        w = np.full(k, total / k)
    out = [_r2(x) for x in w[:-1]]
    out.append(_r2(total - sum(out)))
    return out


def _tile_rows(pattern: tuple[int, ...], smin: float, smax: float, rng: np.random.Generator, gap: float = 0.0) -> list[Rect] | None:
    """Rows of rooms (k rooms in a row per pattern entry): equal-width rows when the size range
    allows it, else left-aligned rows; `gap` leaves that much space between rows 0 and 1."""
    lo_w = max(k * smin for k in pattern)
    hi_w = min(k * smax for k in pattern)
    rects: list[Rect] = []
    y = 0.0
    common = _r2(rng.uniform(lo_w + 0.02, hi_w - 0.02)) if lo_w + 0.04 <= hi_w else None
    for row, k in enumerate(pattern):
        h = _r2(rng.uniform(smin + 0.01, smax - 0.01))
        total = common if common is not None else _r2(rng.uniform(k * smin + 0.02, k * smax - 0.02))
        x = 0.0
        for w in _split_length(total, k, smin, smax, rng):
            rects.append(Rect(_r2(x), _r2(y), _r2(x + w), _r2(y + h)))
            x += w
        y += h + (gap if row == 0 else 0.0)
    if gap == 0.0:
        xs = sorted({v for r in rects for v in (r.xmin, r.xmax)})
        if any(0.0 < b - a < 0.3 for a, b in zip(xs, xs[1:])):
            return None  # ragged rows whose walls almost line up: a sliver step in a wall
    return rects


def _orient(rects: list[Rect], rng: np.random.Generator) -> list[Rect]:
    """Rows or columns, mirrored east-west or not (two draws)."""
    if rng.random() < 0.5:  # columns instead of rows
        rects = [Rect(r.ymin, r.xmin, r.ymax, r.xmax) for r in rects]
    if rng.random() < 0.5:  # mirror east-west
        xmax = max(r.xmax for r in rects)
        rects = [Rect(_r2(xmax - r.xmax), r.ymin, _r2(xmax - r.xmin), r.ymax) for r in rects]
    return rects


def shared_edge(a: Rect, b: Rect) -> tuple[str, float, float, float] | None:
    """(axis the shared wall runs along, its line, low end, high end) of two touching rectangles."""
    eps = 1e-6
    for axis, (a0, a1, b0, b1, alo, ahi, blo, bhi) in (
        ("x", (a.ymin, a.ymax, b.ymin, b.ymax, a.xmin, a.xmax, b.xmin, b.xmax)),
        ("y", (a.xmin, a.xmax, b.xmin, b.xmax, a.ymin, a.ymax, b.ymin, b.ymax)),
    ):
        for c in (c for c, d in ((a1, b0), (a0, b1)) if abs(c - d) < eps):
            lo, hi = max(alo, blo), min(ahi, bhi)
            if hi - lo > eps:
                return axis, c, lo, hi
    return None


def _rows(recipe: Recipe, rng: np.random.Generator) -> Layout | None:
    n = int(rng.integers(recipe.scene.rooms[0], recipe.scene.rooms[1] + 1))
    smin, smax = recipe.scene.room_size
    patterns = _ROW_PATTERNS[n]
    rects = _tile_rows(patterns[int(rng.integers(len(patterns)))], smin, smax, rng)
    return None if rects is None else Layout("rows", _orient(rects, rng))


def _joined_rows(recipe: Recipe, rng: np.random.Generator, two_rows: bool) -> list[Rect] | None:
    n = int(rng.integers(recipe.scene.rooms[0], recipe.scene.rooms[1] + 1)) + 1
    patterns = _JOINED_PATTERNS[n] if two_rows else _ROW_PATTERNS.get(n, ()) + _JOINED_PATTERNS[n]
    patterns = tuple(dict.fromkeys(patterns))
    return _tile_rows(patterns[int(rng.integers(len(patterns)))], *recipe.scene.room_size, rng)


def _l_shape(recipe: Recipe, rng: np.random.Generator) -> Layout | None:
    rects = _joined_rows(recipe, rng, two_rows=True)
    if rects is None:
        return None
    # first or last rooms of neighbouring rows: flush on the outer side, so their union is an L
    right = max(r.xmax for r in rects)
    cands = []
    for i, a in enumerate(rects):
        for j, b in enumerate(rects):
            if abs(a.ymax - b.ymin) > 1e-6 or abs(a.size[0] - b.size[0]) < L_STEP:
                continue
            if (a.xmin == 0.0 and b.xmin == 0.0) or (a.xmax == right and b.xmax == right):
                cands.append((i, j))
    if not cands:
        return None
    i, j = cands[int(rng.integers(len(cands)))]
    return Layout("l_shape", _orient(rects, rng), joins=((i, j),), kinds={i: "living", j: "living"})


def _open_plan(recipe: Recipe, rng: np.random.Generator) -> Layout | None:
    rects = _joined_rows(recipe, rng, two_rows=False)
    if rects is None:
        return None
    cands = []
    for i in range(len(rects)):
        for j in range(i + 1, len(rects)):
            e = shared_edge(rects[i], rects[j])
            if e is not None and e[3] - e[2] >= OPEN_MIN_SHARED:
                cands.append((i, j))
    if not cands:
        return None
    i, j = cands[int(rng.integers(len(cands)))]
    living, kitchen = (i, j) if rects[i].area >= rects[j].area else (j, i)
    return Layout("open_plan", _orient(rects, rng), joins=((i, j),), kinds={living: "living", kitchen: "kitchen"})


def _corridor(recipe: Recipe, rng: np.random.Generator) -> Layout | None:
    """A hall between two rows of rooms, as long as the longer row. At least two rooms besides
    the hall (one of them must be a kitchen or bathroom for the sink), so a corridor home has
    three spaces even where `scene.rooms` would allow two."""
    lo, hi = recipe.scene.rooms
    n = int(rng.integers(max(lo, 3), max(hi, 3) + 1)) - 1  # rooms besides the hall
    smin, smax = recipe.scene.room_size
    c = _r2(rng.uniform(*HALL_WIDTH))
    k0 = int(rng.integers(1, n))  # rooms on the first side
    pattern = (k0, n - k0)
    rects = _tile_rows(pattern, smin, smax, rng, gap=c)
    if rects is None:
        return None
    h0 = max(r.ymax for r in rects[:k0])
    hall = Rect(0.0, h0, max(r.xmax for r in rects), _r2(h0 + c))
    rects.append(hall)
    k = len(rects) - 1
    return Layout("corridor", _orient(rects, rng), kinds={k: "hall"}, no_entrance=frozenset({k}))


_FAMILIES = {"rows": _rows, "l_shape": _l_shape, "corridor": _corridor, "open_plan": _open_plan}


def draw_family(recipe: Recipe, rng: np.random.Generator) -> str:
    """The layout family of one apartment, each of the recipe's equally likely. Drawn once per
    apartment (the generator's redraws stay in it, so families that need more redraws are not
    rarer); a single family draws nothing, so `layouts: [rows]` keeps the old draws."""
    fams = recipe.scene.layouts
    return fams[0] if len(fams) == 1 else fams[int(rng.integers(len(fams)))]


def draw_layout(recipe: Recipe, family: str, rng: np.random.Generator) -> Layout | None:
    """One apartment's rectangles in `family`, or None (redraw)."""
    return _FAMILIES[family](recipe, rng)


def opening_span(a: Rect, b: Rect, t: float) -> tuple[str, float, float, float]:
    """The wide opening of a joined pair: (axis, wall line, centre along the wall, width)."""
    e = shared_edge(a, b)
    if e is None:
        raise ValueError(f"joined rooms {a} and {b} share no wall")
    axis, c, lo, hi = e
    ret = t / 2.0 + OPENING_RETURN
    return axis, c, _r2((lo + hi) / 2.0), _r2(hi - lo - 2.0 * ret)
