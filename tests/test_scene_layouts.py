"""Layout families (scene/layouts.py): an L-shaped room, a corridor, an open-plan kitchen/living
room beside rows; the wide opening that joins one space is seen, walked and heard as open; room
sizes stay in the stated ranges; `layouts: [rows]` reproduces the old generator draw for draw."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from rows_layout_digests import FIXTURE, RECIPES, ROOT, as_before, compute

from echo_data.acoustics.room import AcousticScene
from echo_data.acoustics.types import SPEED_OF_SOUND
from echo_data.floorplan import FloorPlan
from echo_data.recipe import AcousticsConfig, Recipe, RecipeError, load_recipe
from echo_data.scene.generate import generate_floorplan_from_seed
from echo_data.scene.layouts import HALL_WIDTH, L_STEP, OPEN_MIN_SHARED
from echo_data.scene.nav import NavGrid
from echo_data.scene.surfaces import WET_ROOMS, is_soft

FAMILIES = ("l_shape", "corridor", "open_plan")
SEEDS = range(15)


def _recipe(family: str, **scene: object) -> Recipe:
    return Recipe(name="t", scene={"rooms": (2, 4), "layouts": (family,), **scene})  # type: ignore[arg-type]


PLANS = {f: [generate_floorplan_from_seed(_recipe(f), s) for s in SEEDS] for f in FAMILIES}


def _opening(plan: FloorPlan) -> tuple[int, int, object]:
    (i,) = plan.open_doorways
    dw = plan.doorways[i]
    return dw.rooms[0], dw.rooms[1], dw


@pytest.mark.parametrize("family", FAMILIES)
def test_family_shapes(family: str) -> None:
    for plan in PLANS[family]:
        assert plan.extra["layout"] == family
        kinds = [r.kind for r in plan.rooms]
        if family == "corridor":
            assert not plan.open_doorways
            (hall,) = [r for r in plan.rooms if r.kind == "hall"]
            assert HALL_WIDTH[0] - 1e-6 <= min(hall.rect.size) <= HALL_WIDTH[1] + 1e-6
            # rooms open off the hall; no leaf swings into it and the entrance is elsewhere
            assert sum(hall.index in dw.rooms for dw in plan.doorways) >= 2
            assert all(d.swing_room != hall.index for d in plan.doors)
            entrance = plan.doorways[plan.extra["entrance_doorway"]]
            assert hall.index not in entrance.rooms
            continue
        a, b, dw = _opening(plan)
        ra, rb = plan.rooms[a].rect, plan.rooms[b].rect
        if family == "l_shape":
            assert kinds[a] == kinds[b] == "living"
            # flush on one outer side, widths (across the shared wall) clearly different: an L
            w = (lambda r: r.size[0]) if dw.axis == "x" else (lambda r: r.size[1])
            assert abs(w(ra) - w(rb)) >= L_STEP - 1e-6
            assert plan.rooms[a].floor_material == plan.rooms[b].floor_material
        else:
            assert sorted((kinds[a], kinds[b])) == ["kitchen", "living"]
            assert dw.width >= OPEN_MIN_SHARED - 2 * (0.05 + 0.15) - 1e-6
        assert plan.space_of(a) == plan.space_of(b) == min(a, b)
        assert plan.rooms[a].wall_material == plan.rooms[b].wall_material
        assert not any(d.doorway == dw.index for d in plan.doors)  # no leaf in a wide opening
        assert dw.width >= 2.0 and dw.height == pytest.approx(plan.wall_height)


@pytest.mark.parametrize("family", ("l_shape", "open_plan"))
def test_wide_opening_is_walkable_and_acoustically_open(family: str) -> None:
    for plan in PLANS[family][:4]:
        a, b, dw = _opening(plan)
        # no wall body in the opening (the SAPIEN build makes exactly the plan's walls; a
        # floor-to-ceiling opening gets no lintel: tests/test_scene_build.py)
        n = (0.0, 1.0) if dw.axis == "x" else (1.0, 0.0)
        along = (1.0, 0.0) if dw.axis == "x" else (0.0, 1.0)
        for k in np.linspace(-0.45, 0.45, 7):
            x, y = dw.center[0] + along[0] * k * dw.width, dw.center[1] + along[1] * k * dw.width
            assert not any(w.footprint.contains(x, y) for w in plan.walls)
        # a base passes across the opening without any door to open
        grid = NavGrid.from_plan(plan)
        side = [1.0 if plan.rooms[r].rect.center[1 if dw.axis == "x" else 0] > (dw.center[1] if dw.axis == "x" else dw.center[0]) else -1.0 for r in (a, b)]
        p = [(dw.center[0] + n[0] * s * 1.0, dw.center[1] + n[1] * s * 1.0) for s in side]
        assert grid.plan_path(p[0], p[1]) is not None
        # sound crosses it on the straight line, with no door loss: the direct path
        scene = AcousticScene(plan, AcousticsConfig())
        src, rcv = np.array([*p[0], 1.2]), np.array([*p[1], 1.2])
        first = scene.response(tuple(src), tuple(rcv)).arrivals[0]
        d = float(np.linalg.norm(src - rcv))
        assert first.order == 0 and first.delay_s == pytest.approx(d / SPEED_OF_SOUND, abs=1e-5)
        assert first.gain == pytest.approx(1.0 / d, rel=0.05)
        box = scene.boxes[a]
        (op,) = [o for o in box.openings if o.doorway == dw.index]
        assert op.openness == 1.0 and not op.closed


def test_room_sizes_in_range() -> None:
    for family, plans in PLANS.items():
        for plan in plans:
            for r in plan.rooms:
                if r.kind == "hall" and family == "corridor":
                    continue
                assert min(r.rect.size) >= 3.2 - 0.02 and max(r.rect.size) <= 5.0 + 0.02, (family, r)


def test_deterministic_per_seed() -> None:
    for f in FAMILIES:
        assert generate_floorplan_from_seed(_recipe(f), 7).to_dict() == PLANS[f][7].to_dict()


def test_wet_rooms_get_hard_floors() -> None:
    carpets = ("carpet_cotton", "carpet_thin")
    r = Recipe(name="t", scene={"rooms": (3, 6), "floor_materials": carpets})  # type: ignore[arg-type]
    seen = 0
    for s in range(20):
        for room in generate_floorplan_from_seed(r, s).rooms:
            if room.kind in WET_ROOMS:
                seen += 1
                assert not is_soft(room.floor_material) and room.floor_material in r.scene.wet_floor_materials
            else:
                assert room.floor_material in carpets
    assert seen >= 20
    # and a bathroom always has a door (shut: its ring stays out of the other rooms' T30,
    # tests/test_acoustics_furnished.py)
    baths = 0
    for s in range(30):
        plan = generate_floorplan_from_seed(r, s)
        doored = {d.doorway for d in plan.doors}
        for dw in plan.doorways:
            if any(i >= 0 and plan.rooms[i].kind == "bathroom" for i in dw.rooms):
                baths += 1
                assert dw.index in doored, (s, dw)
    assert baths >= 10
    # null keeps the drawn floor: wet rooms carpeted as before the key existed
    old = Recipe(name="t", scene={"rooms": (3, 6), "floor_materials": carpets, "wet_floor_materials": None})  # type: ignore[arg-type]
    assert all(is_soft(room.floor_material) for room in generate_floorplan_from_seed(old, 0).rooms)


def test_rows_reproduce_the_old_generator() -> None:
    """Plans and episodes of quickstart and bc_navigate with `layouts: [rows]` (and the old wet
    floors) equal the digests the generator gave before the layout families existed."""
    ref = json.loads(FIXTURE.read_text())
    for name in RECIPES:
        assert compute(as_before(load_recipe(ROOT / name))) == ref[name], name
    # bc_navigate as shipped asks for exactly that (its ablation numbers must stay reproducible)
    bc = load_recipe(ROOT / "studies/navigation_ablation/recipes/bc_navigate.yaml")
    assert bc.scene.layouts == ("rows",) and bc.scene.wet_floor_materials is None and not bc.objects.size_variants


def test_default_draws_every_family() -> None:
    r = Recipe(name="t")
    fams = {generate_floorplan_from_seed(r, s).extra.get("layout", "rows") for s in range(40)}
    assert fams == {"rows", *FAMILIES}


@pytest.mark.parametrize("bad", [[], ["rows", "rows"], ["spiral"]])
def test_bad_layouts_one_line(tmp_path, bad) -> None:  # type: ignore[no-untyped-def]
    p = tmp_path / "r.yaml"
    p.write_text(f"name: x\nscene:\n  layouts: {json.dumps(bad)}\n")
    with pytest.raises(RecipeError) as e:
        load_recipe(p)
    msg = str(e.value)
    assert "\n" not in msg and "scene.layouts" in msg and str(p) in msg


def test_hall_is_wide_enough_for_the_base() -> None:
    """A 0.64 m base (nav radius 0.32) drives along every generated hall."""
    for plan in PLANS["corridor"]:
        (hall,) = [r for r in plan.rooms if r.kind == "hall"]
        grid = NavGrid.from_plan(plan)
        r = hall.rect
        long_x = r.size[0] >= r.size[1]
        c = r.center
        a = (r.xmin + 0.5, c[1]) if long_x else (c[0], r.ymin + 0.5)
        b = (r.xmax - 0.5, c[1]) if long_x else (c[0], r.ymax - 0.5)
        path = grid.plan_path(a, b)
        if path is None:  # furniture may stand at a dead end; the middle stretch must be open
            a = (r.xmin + 0.35 * r.size[0], c[1]) if long_x else (c[0], r.ymin + 0.35 * r.size[1])
            b = (r.xmin + 0.65 * r.size[0], c[1]) if long_x else (c[0], r.ymin + 0.65 * r.size[1])
            path = grid.plan_path(a, b)
        assert path is not None and math.isfinite(len(path))
