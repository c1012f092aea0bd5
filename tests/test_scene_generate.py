"""Procedural apartments: determinism, room tiling, walls, doorways, doors, furniture, clutter."""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pyroomacoustics as pra
import pytest
from scipy import ndimage

from echo_data.floorplan import FloorPlan, Rect
from echo_data.recipe import Recipe
from echo_data.scene.furniture import EDGE_MARGIN, FRONT_REACH, front_zone, object_radius
from echo_data.scene.generate import generate_floorplan
from echo_data.scene.layouts import HALL_WIDTH
from echo_data.scene.nav import NavGrid, interaction_pose
from echo_data.scene.objects import object_size
from echo_data.scene.structure import DOORBELL_BESIDE, DOORBELL_Z, door_operation_zone, door_swing_zone

RECIPES = [
    Recipe(name="small"),
    Recipe(name="big", scene={"rooms": (4, 6), "furniture_per_room": (2, 4)}),
    Recipe(name="wide", scene={"rooms": (2, 3), "room_size": (4.0, 7.0), "door_probability": 1.0}, objects={"distractors": (3, 6)}),
]
SEEDS = range(12)


def _plans() -> list[tuple[Recipe, FloorPlan]]:
    return [(r, generate_floorplan(r, np.random.default_rng(s))) for r in RECIPES for s in SEEDS]


PLANS = _plans()


def _inner(plan: FloorPlan, room: int) -> Rect:
    t = plan.walls[0].thickness
    return plan.rooms[room].rect.expanded(-t / 2.0)


def test_deterministic_per_seed_and_varied_across_seeds() -> None:
    r = RECIPES[1]
    a = generate_floorplan(r, np.random.default_rng(5)).to_dict()
    b = generate_floorplan(r, np.random.default_rng(5)).to_dict()
    assert a == b
    dicts = [generate_floorplan(r, np.random.default_rng(s)).to_dict() for s in range(6)]
    assert len({str(d) for d in dicts}) == 6
    assert len({len(d["rooms"]) for d in dicts}) > 1  # room count varies
    assert FloorPlan.from_dict(a) == generate_floorplan(r, np.random.default_rng(5))


@pytest.mark.parametrize("recipe,plan", PLANS[:: len(SEEDS)] + PLANS[5 :: len(SEEDS)])
def test_rooms_tile_without_overlap_within_size_range(recipe: Recipe, plan: FloorPlan) -> None:
    lo, hi = recipe.scene.rooms
    spaces = len(plan.rooms) - len(plan.open_doorways)  # rooms joined by a wide opening are one
    corridor = plan.extra.get("layout") == "corridor"
    assert lo <= spaces <= (max(hi, 3) if corridor else hi)  # a corridor home has 3 spaces at least
    smin, smax = recipe.scene.room_size
    for r in plan.rooms:
        if corridor and r.kind == "hall":
            assert HALL_WIDTH[0] - 1e-6 <= min(r.rect.size) <= HALL_WIDTH[1] + 1e-6
            continue
        assert smin - 0.02 <= r.rect.size[0] <= smax + 0.02 and smin - 0.02 <= r.rect.size[1] <= smax + 0.02
    for i, a in enumerate(plan.rooms):
        for b in plan.rooms[i + 1 :]:
            assert not a.rect.intersects(b.rect.expanded(-1e-6)), (a.index, b.index)
    kinds = {r.kind for r in plan.rooms}
    assert kinds <= {"living", "kitchen", "bedroom", "bathroom", "hall", "study"}
    assert "kitchen" in kinds or "bathroom" in kinds


def test_room_graph_connected_through_doorways() -> None:
    for _, plan in PLANS:
        adj: dict[int, set[int]] = {r.index: set() for r in plan.rooms}
        for dw in plan.doorways:
            a, b = dw.rooms
            if a >= 0 and b >= 0:
                adj[a].add(b)
                adj[b].add(a)
        seen, todo = {0}, deque([0])
        while todo:
            for n in adj[todo.popleft()] - seen:
                seen.add(n)
                todo.append(n)
        assert seen == set(adj), plan.seed
        # a tree of interior doorways plus one entrance
        assert sum(1 for dw in plan.doorways if -1 in dw.rooms) == 1
        assert len(plan.doorways) == len(plan.rooms)


def test_materials_exist_in_pyroomacoustics() -> None:
    known = {m for group in pra.materials_data["absorption"].values() for m in group}
    for _, plan in PLANS:
        for r in plan.rooms:
            assert {r.floor_material, r.wall_material, r.ceiling_material} <= known
        assert {w.material for w in plan.walls} <= known
        assert {d.material for d in plan.doors} <= known
        assert {f.material for f in plan.furniture} <= known


def test_walls_listed_once_and_doorways_open() -> None:
    for _, plan in PLANS:
        walls = plan.walls
        for i, a in enumerate(walls):
            for b in walls[i + 1 :]:
                if a.axis != b.axis:
                    continue
                fa, fb = a.footprint, b.footprint
                # two parallel segments never overlap with positive area
                assert not fa.expanded(-1e-4).intersects(fb.expanded(-1e-4)), (a, b)
        for dw in plan.doorways:
            half = dw.width / 2.0 - 1e-3
            if dw.axis == "x":
                opening = Rect(dw.center[0] - half, dw.center[1] - 0.01, dw.center[0] + half, dw.center[1] + 0.01)
            else:
                opening = Rect(dw.center[0] - 0.01, dw.center[1] - half, dw.center[0] + 0.01, dw.center[1] + half)
            assert not any(opening.intersects(w.footprint) for w in walls), dw
            assert math.isclose(dw.width, 1.0) or dw.index in plan.open_doorways


def test_doorways_keep_distance_from_corners() -> None:
    for _, plan in PLANS:
        for dw in plan.doorways:
            if dw.index in plan.open_doorways:
                continue  # a wide opening runs to short wall returns (tests/test_scene_layouts.py)
            u = dw.center[0] if dw.axis == "x" else dw.center[1]
            for ri in dw.rooms:
                if ri < 0:
                    continue
                inner = _inner(plan, ri)
                lo, hi = (inner.xmin, inner.xmax) if dw.axis == "x" else (inner.ymin, inner.ymax)
                assert u - dw.width / 2.0 - lo >= 0.3 - 1e-6 and hi - (u + dw.width / 2.0) >= 0.3 - 1e-6


def test_doors_bells_and_hinges() -> None:
    for _, plan in PLANS:
        assert len(plan.doors) >= 1
        belled = [d for d in plan.doors if d.doorbell is not None]
        assert belled
        t = plan.walls[0].thickness
        for d in plan.doors:
            dw = plan.doorways[d.doorway]
            assert d.angle == 0.0
            assert math.radians(100) <= d.max_angle <= math.radians(110)
            assert d.open_threshold <= min(math.radians(60) + 1e-9, 0.7 * d.max_angle + 1e-9)
            assert d.swing_room in dw.rooms
            # the closed leaf covers the opening and its hinge axis is outside the wall face
            across = abs(d.hinge[1] - dw.center[1]) if dw.axis == "x" else abs(d.hinge[0] - dw.center[0])
            assert across >= t / 2.0 + d.thickness / 2.0 + 0.01 - 1e-6
            assert d.width >= dw.width
            # the leaf swings into the swing room
            mid = d.free_edge(math.pi / 2.0)
            assert plan.room_at(*mid) == d.swing_room
            if d.doorbell is not None:
                bx, by, bz = d.doorbell
                assert bz == pytest.approx(DOORBELL_Z)
                u, cu = (bx, dw.center[0]) if dw.axis == "x" else (by, dw.center[1])
                assert abs(u - cu) == pytest.approx(dw.width / 2.0 + DOORBELL_BESIDE, abs=1e-3)
                assert plan.room_at(bx, by) == d.swing_room


def test_door_leaves_never_hit_walls_over_their_range() -> None:
    for _, plan in PLANS:
        boxes = np.array([[*w.footprint.expanded(0.005).__dict__.values()] for w in plan.walls])  # xmin ymin xmax ymax
        for d in plan.doors:
            q = np.linspace(0.0, d.max_angle, 25)[:, None, None]
            yaw = d.closed_yaw + d.open_sign * q
            s = np.linspace(0.0, d.width, 21)[None, :, None]
            side = np.array([-0.5, 0.5])[None, None, :] * d.thickness
            x = (d.hinge[0] + s * np.cos(yaw) - side * np.sin(yaw)).ravel()
            y = (d.hinge[1] + s * np.sin(yaw) + side * np.cos(yaw)).ravel()
            inside = (
                (x[:, None] >= boxes[None, :, 0]) & (x[:, None] <= boxes[None, :, 2])
                & (y[:, None] >= boxes[None, :, 1]) & (y[:, None] <= boxes[None, :, 3])
            )  # fmt: skip
            assert not inside.any(), (plan.seed, d.index)


def test_furniture_inside_rooms_clear_of_doorways_and_each_other() -> None:
    for _, plan in PLANS:
        zones = []
        for dw in plan.doorways:
            if dw.axis == "x":
                zones.append(Rect(dw.center[0] - dw.width / 2, dw.center[1] - 1.2, dw.center[0] + dw.width / 2, dw.center[1] + 1.2))
            else:
                zones.append(Rect(dw.center[0] - 1.2, dw.center[1] - dw.width / 2, dw.center[0] + 1.2, dw.center[1] + dw.width / 2))
        zones += [door_swing_zone(d) for d in plan.doors]
        for f in plan.furniture:
            fp = f.footprint
            inner = _inner(plan, f.room)
            assert inner.contains(fp.xmin, fp.ymin) and inner.contains(fp.xmax, fp.ymax), f
            assert not any(fp.intersects(z) for z in zones), f
            # the front faces the room: the robot stands towards the room centre
            cx, cy = plan.rooms[f.room].rect.center
            assert math.cos(f.yaw) * (cx - f.center[0]) + math.sin(f.yaw) * (cy - f.center[1]) > 0
            assert abs(f.yaw / (math.pi / 2) - round(f.yaw / (math.pi / 2))) < 1e-9
            fz = front_zone(f)
            for g in plan.furniture:
                if g.index != f.index:
                    assert not fp.intersects(g.footprint), (f, g)
                    assert not fz.intersects(g.footprint), (f, g)


def test_heights_and_receptacles() -> None:
    for _, plan in PLANS:
        for f in plan.furniture:
            if f.kind == "table":
                assert f.top_z == pytest.approx(0.75)
            if f.kind == "counter":
                assert f.top_z == pytest.approx(0.9)
            if f.kind in ("shelf", "cabinet"):
                assert 0.6 - 1e-9 <= f.top_z <= 0.8 + 1e-9
            assert f.receptacle == (f.kind in ("table", "counter", "shelf", "cabinet"))
        assert sum(f.receptacle for f in plan.furniture) >= 2


def test_one_sink_cabinet_with_a_running_faucet() -> None:
    for _, plan in PLANS:
        sinks = [f for f in plan.furniture if f.kind == "sink_cabinet"]
        assert len(sinks) == 1 and len(plan.faucets) == 1
        sink, fc = sinks[0], plan.faucets[0]
        assert plan.rooms[sink.room].kind in ("kitchen", "bathroom")
        assert sink.top_z == pytest.approx(0.85)
        assert fc.furniture == sink.index
        assert sink.footprint.contains(fc.pivot[0], fc.pivot[1], margin=0.05)
        assert fc.pivot[2] - 0.01 - sink.top_z >= 0.01  # lever clears the top by >= 1 cm
        assert 0.12 <= fc.lever_length <= 0.15
        assert fc.angle > fc.closed_tolerance and fc.angle <= fc.open_angle
        assert fc.closed_tolerance == pytest.approx(0.1)
        # the pivot is near the back, the spout in front of it, above the top
        n = (math.cos(sink.yaw), math.sin(sink.yaw))
        ahead = (fc.pivot[0] - sink.center[0]) * n[0] + (fc.pivot[1] - sink.center[1]) * n[1]
        half_depth = (abs(n[0]) * sink.size[0] + abs(n[1]) * sink.size[1]) / 2.0
        assert ahead < 0  # back half of the top
        assert 0.3 <= half_depth - ahead <= 0.4  # reachable from the front (CloseSink expert)
        assert (fc.spout[0] - fc.pivot[0]) * n[0] + (fc.spout[1] - fc.pivot[1]) * n[1] > 0.05
        assert fc.spout[2] > sink.top_z


def test_distractors_rest_on_receptacles_within_edges() -> None:
    n_total = 0
    for recipe, plan in PLANS:
        lo, hi = recipe.objects.distractors
        assert len(plan.objects) <= hi
        n_total += len(plan.objects)
        for o in plan.objects:
            assert not o.sounding and o.category in recipe.objects.distractor_shapes
            f = plan.furniture[o.receptacle]
            assert f.receptacle
            r = object_radius(o.category, o.scale)
            fp = f.footprint
            assert fp.contains(o.position[0], o.position[1], margin=EDGE_MARGIN + r - 1e-6)
            assert o.position[2] == pytest.approx(f.top_z + object_size(o.category, o.scale)[2] / 2.0, abs=1e-4)
            # front-reachable: centre within FRONT_REACH of the front edge
            n = (round(math.cos(f.yaw)), round(math.sin(f.yaw)))
            half_depth = (abs(n[0]) * f.size[0] + abs(n[1]) * f.size[1]) / 2.0
            depth_in = half_depth - ((o.position[0] - f.center[0]) * n[0] + (o.position[1] - f.center[1]) * n[1])
            assert depth_in <= FRONT_REACH + 1e-6
        for i, a in enumerate(plan.objects):
            for b in plan.objects[i + 1 :]:
                d = math.hypot(a.position[0] - b.position[0], a.position[1] - b.position[1])
                assert d >= object_radius(a.category, a.scale) + object_radius(b.category, b.scale)
    assert n_total > len(PLANS)  # clutter really gets placed


def test_robot_can_reach_every_piece_with_doors_open() -> None:
    """With all doors open, one free region holds every interaction pose (>= 0.9 m corridors)."""
    for _, plan in PLANS[::3]:
        grid = NavGrid.from_plan(plan, door_angles={d.index: d.max_angle for d in plan.doors})
        labels, _ = ndimage.label(grid.free)
        comps = set()
        for f in plan.furniture:
            x, y, _ = interaction_pose(plan, f"furniture:{f.index}", grid=grid)
            comps.add(int(labels[grid.cell(x, y)]))
        for o in plan.objects:
            x, y, _ = interaction_pose(plan, o.name, grid=grid)
            comps.add(int(labels[grid.cell(x, y)]))
        x, y, _ = interaction_pose(plan, "faucet:0", grid=grid)
        comps.add(int(labels[grid.cell(x, y)]))
        assert len(comps) == 1 and 0 not in comps, plan.seed


def test_belled_doors_leave_room_to_open_them() -> None:
    """The robot holds the handle and drives its base about the hinge to past the open
    threshold; some stance in front of the handle must keep the base on free floor."""
    n_doors = 0
    for _, plan in PLANS[::2]:
        grid = NavGrid.from_plan(plan)
        for d in plan.doors:
            if d.doorbell is None:
                continue
            n_doors += 1
            zone = door_operation_zone(d)
            assert not any(zone.intersects(f.footprint) for f in plan.furniture), (plan.seed, d.index)
            u = np.array([math.cos(d.closed_yaw), math.sin(d.closed_yaw)])
            n = d.open_sign * np.array([-u[1], u[0]])
            hinge = np.array(d.hinge)
            ok = False
            for dist in (0.88, 0.95):
                for shift in (-0.3, -0.15, 0.0):
                    p0 = (d.width - 0.07 + shift) * u + dist * n
                    free = True
                    for q in np.linspace(0.0, d.open_threshold + 0.12, 12):
                        c, s = math.cos(d.open_sign * q), math.sin(d.open_sign * q)
                        p = hinge + np.array([c * p0[0] - s * p0[1], s * p0[0] + c * p0[1]])
                        free &= grid.is_free(float(p[0]), float(p[1]))
                    ok |= free
            assert ok, (plan.seed, d.index)
    assert n_doors >= len(PLANS) // 2


def test_bare_rooms_still_get_a_sink_and_two_receptacles() -> None:
    r = Recipe(name="bare", scene={"furniture_per_room": (0, 0)})
    for s in range(4):
        plan = generate_floorplan(r, np.random.default_rng(s))
        kinds = [f.kind for f in plan.furniture]
        assert kinds.count("sink_cabinet") == 1
        assert sum(f.receptacle for f in plan.furniture) >= 2
        assert len(plan.furniture) <= 3
