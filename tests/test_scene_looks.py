"""Looks of surfaces and objects: they follow the acoustic material, are deterministic, and carry
texture a flat render lacks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from echo_data.acoustics.materials import absorption
from echo_data.recipe import load_recipe
from echo_data.scene import textures
from echo_data.scene.furniture import UPHOLSTERY
from echo_data.scene.generate import generate_floorplan_from_seed
from echo_data.scene.soft_furnishings import CURTAIN_MATERIALS, RUG_MATERIALS
from echo_data.scene.surfaces import _MATERIAL_LOOKS, furniture_look, surface_look

RECIPE = load_recipe(Path(__file__).resolve().parents[1] / "recipes" / "multi_event.yaml")
SOFT, HARD = ("carpet", "fabric"), ("tiles", "concrete", "brick", "wood")


def test_soft_furnishings_look_soft() -> None:
    for m in RUG_MATERIALS:
        assert surface_look(m).pattern == "carpet", m
    for m in CURTAIN_MATERIALS:
        assert surface_look(m).pattern == "fabric", m
    for kind, m in UPHOLSTERY.items():
        assert furniture_look(kind, m).pattern == "fabric", kind


def test_what_looks_soft_absorbs_like_it() -> None:
    """Porous coverings absorb far more above 1 kHz than hard surfaces (Vorländer's tables, as
    tabulated in pyroomacoustics): every material drawn as carpet or cloth absorbs, on average
    over the 1-8 kHz bands, more than twice what any material drawn hard does."""
    high = {m: float(absorption(m)[3:].mean()) for m in _MATERIAL_LOOKS}
    soft = [high[m] for m, look in _MATERIAL_LOOKS.items() if look[0] in SOFT]
    hard = [high[m] for m, look in _MATERIAL_LOOKS.items() if look[0] in HARD]
    assert soft and hard and min(soft) > 2.0 * max(hard)


def test_room_styles_differ() -> None:
    paints: dict[str, set] = {}
    for seed in range(25):
        plan = generate_floorplan_from_seed(RECIPE, seed)
        for r in plan.rooms:
            look = surface_look(r.floor_material, r.kind, plan.seed, r.index)
            if r.floor_material == "linoleum_on_concrete":
                assert look.pattern == ("tiles" if r.kind in ("kitchen", "bathroom") else "wood"), r.kind
            paints.setdefault(r.kind, set()).add(surface_look("plasterboard", r.kind, plan.seed, r.index).colour)
    assert paints["kitchen"].isdisjoint(paints["bathroom"])


def test_textures_are_pure_and_varied() -> None:
    a = textures._detail("wood", 1)
    assert np.array_equal(a, textures._detail("wood", 1))
    assert not np.array_equal(a, textures._detail("wood", 2))
    for p in textures.PATTERNS:
        t = textures.texture_rgba(p, 0, (0.5, 0.5, 0.5))
        assert t.shape == (textures.SIZE, textures.SIZE, 4) and t.dtype == np.uint8
        if p != "plain":
            assert t[..., :3].std() > 2.0, p  # a pattern, not a flat colour


@pytest.mark.slow
def test_textured_render_has_detail_flat_lacks() -> None:
    """Same room, same camera: the textured look has far more fine detail (pixel-to-pixel change)."""
    import math

    import sapien

    from echo_data.scene.build import build_statics
    from echo_data.scene.lighting import add_lights
    from echo_data.world import keep_render_alive

    keep_render_alive()
    plan = generate_floorplan_from_seed(RECIPE, 3)
    r = plan.rooms[0]
    detail = {}
    for flat in (True, False):
        scene = sapien.Scene()
        add_lights(scene, plan, flat=flat)
        build_statics(scene, plan, flat=flat)
        cam = scene.add_camera("c", 64, 64, math.radians(70), 0.02, 20.0)
        cam.entity.set_pose(sapien.Pose([r.rect.center[0], r.rect.center[1], 1.1], [0.9, 0.0, 0.44, 0.0]))
        scene.update_render()
        cam.take_picture()
        img = cam.get_picture("Color")[..., :3].astype(np.float64)
        detail[flat] = float(np.abs(np.diff(img, axis=1)).mean() + np.abs(np.diff(img, axis=0)).mean())
    assert detail[False] > 2.0 * detail[True]
