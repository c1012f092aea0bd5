"""preview's acoustic_map.png colours: the scale starts at the room-noise floor, cells below it are
a named flat grey (not black, which read as silence), cells off the floor are left to the plan."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps

from echo_data.viz.acoustic_map import BELOW_FLOOR_RGB, level_colours


def test_level_colours_mark_below_floor_and_leave_walls() -> None:
    level = np.array([[np.nan, 25.0, 30.0, 55.0, 80.0]])
    rgba = level_colours(level, floor_db=30.0, top_db=80.0)
    assert rgba[0, 0, 3] == 0  # off the floor: transparent, the plan shows through
    assert tuple(rgba[0, 1, :3]) == BELOW_FLOOR_RGB and rgba[0, 1, 3] == 255
    inferno = (colormaps["inferno"]([0.0, 0.5, 1.0]) * 255).astype(np.uint8)
    np.testing.assert_array_equal(rgba[0, 2:, :3], inferno[:, :3])  # floor .. top spans the whole scale
