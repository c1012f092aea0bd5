"""Room lights and a sun, randomised per plan within plausible ranges.

Why fixed counts: SAPIEN compiles its shader for a number of point and directional lights, so a
scene with a different count pays the pipeline build again (seconds on lavapipe). Every
textured scene therefore gets the same MAX_ROOM_LIGHTS point lights (rooms beyond it share the
ambient; unused lights are dark) and the same two directional lights. Shadows are off: lavapipe
draws them, but one 1024² directional shadow map made a 128² control step 3x as expensive
(23 vs 7.5 ms measured here), and the flats have no ceiling for a sun to shine in through.

Ranges: ceiling lamps 2700-4500 K (warm-white to neutral domestic LEDs), sun elevation 25-65°,
ambient sky fill 0.2-0.35 of full white. Intensities are in SAPIEN's units (radiance / d²).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from echo_data import seeds
from echo_data.floorplan import FloorPlan

if TYPE_CHECKING:
    import sapien

MAX_ROOM_LIGHTS = 3  # lamps in the largest rooms; each costs about 0.3-0.5 ms per 128² frame on lavapipe
LAMP_KELVIN = (2700.0, 4500.0)
LAMP_POWER = (2.0, 4.5)  # emission at 1 m; a lamp 1.5 m above a table top gives about 1-2
SUN_ELEVATION_DEG = (25.0, 65.0)
SUN_POWER = (0.35, 0.7)
AMBIENT = (0.2, 0.35)
LAMP_BELOW_CEILING = 0.25  # m


def kelvin_rgb(k: float) -> np.ndarray:
    """Approximate linear RGB of a black body at `k` kelvin, normalised to max 1 (2000-7000 K):
    a two-point blend between measured 2700 K (1, 0.66, 0.38) and 6500 K (1, 1, 1) chromaticities."""
    t = float(np.clip((k - 2700.0) / (6500.0 - 2700.0), 0.0, 1.0))
    return np.array([1.0, 0.66 + 0.34 * t, 0.38 + 0.62 * t])


def add_lights(scene: sapien.Scene, plan: FloorPlan, flat: bool = False) -> None:
    """Light `scene`: fixed lights for the flat look, else the plan seed's randomised lights."""
    if flat:
        scene.set_ambient_light([0.45, 0.45, 0.45])
        scene.add_directional_light([0.3, 0.4, -1.0], [0.7, 0.7, 0.65], shadow=False)
        scene.add_directional_light([-0.4, -0.2, -1.0], [0.25, 0.25, 0.3], shadow=False)
        return
    rng = seeds.derived_rng(seeds.LIGHTING, plan.seed)
    scene.set_ambient_light([float(rng.uniform(*AMBIENT))] * 3)
    az = rng.uniform(0.0, 2.0 * np.pi)
    el = np.radians(rng.uniform(*SUN_ELEVATION_DEG))
    sun = -np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    scene.add_directional_light(sun.tolist(), (kelvin_rgb(5500.0) * rng.uniform(*SUN_POWER)).tolist(), shadow=False)
    scene.add_directional_light([-sun[0], -sun[1], -1.0], [0.12, 0.12, 0.14], shadow=False)  # sky bounce
    rooms = sorted(plan.rooms, key=lambda r: -r.rect.size[0] * r.rect.size[1])[:MAX_ROOM_LIGHTS]
    for i in range(MAX_ROOM_LIGHTS):
        if i < len(rooms):
            r = rooms[i]
            pos = [r.rect.center[0], r.rect.center[1], plan.wall_height - LAMP_BELOW_CEILING]
            colour = kelvin_rgb(rng.uniform(*LAMP_KELVIN)) * rng.uniform(*LAMP_POWER)
        else:
            pos, colour = [0.0, 0.0, -10.0], np.zeros(3)
        scene.add_point_light(pos, colour.tolist(), shadow=False)
