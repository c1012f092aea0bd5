"""Occlusion in a non-convex plan: walls remove the direct path, sound goes through the
doorway, lintels block, closed doors leak with their transmission loss, furniture shadows."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.room_plans import row_plan

from echo_data.acoustics.room import AcousticScene, omni_rir
from echo_data.acoustics.types import SPEED_OF_SOUND
from echo_data.floorplan import Furniture
from echo_data.recipe import AcousticsConfig

FS = 16000
CFG = AcousticsConfig()
DOORWAY_Y = 3.3  # doorway spans y in [2.8, 3.8] of the wall x = 4


def _energy(x: np.ndarray) -> float:
    return float(np.sum(np.asarray(x, dtype=np.float64) ** 2))


@pytest.fixture(scope="module")
def two_rooms() -> AcousticScene:
    return AcousticScene(row_plan((4.0, 4.0), doorway_y=(DOORWAY_Y,)), CFG)


def test_wall_removes_direct_path_sound_arrives_through_doorway(two_rooms: AcousticScene) -> None:
    src, rcv = (2.0, 0.8, 1.2), (6.0, 0.8, 1.2)
    d = 4.0
    resp = two_rooms.response(src, rcv)
    assert resp.arrivals, "sound must still arrive (through the doorway)"
    first = min(a.delay_s for a in resp.arrivals)
    assert first * FS > d / SPEED_OF_SOUND * FS + 1.0
    # nothing may arrive on the blocked straight line
    assert all(abs(a.delay_s - d / SPEED_OF_SOUND) * FS > 1.0 for a in resp.arrivals)
    # The shortest route bends round the 10 cm thick jamb at y = 2.8 (corners at x = 3.95
    # and 4.05): the first arrival takes it, within the 5 cm the secondary source keeps from
    # the jamb and the 1 cm it sits inside each face (≈ 8 cm longer here).
    c0, c1 = np.array([3.95, 2.8, 1.2]), np.array([4.05, 2.8, 1.2])
    route = np.linalg.norm(c0 - src) + 0.1 + np.linalg.norm(np.array(rcv) - c1)
    assert route <= first * SPEED_OF_SOUND < route + 0.12
    # direct-path energy (± 1 ms around d / c) ≥ 40 dB below the free-field direct sound
    h = omni_rir(resp).astype(np.float64)
    i0 = round(d / SPEED_OF_SOUND * FS)
    window = _energy(h[i0 - 16 : i0 + 17])
    free = _energy(omni_rir(two_rooms.free_field(src, rcv)))
    assert window <= free * 1e-4, 10 * np.log10(window / free)
    # while the response as a whole is clearly audible
    assert _energy(h) > free * 0.1


def test_receiver_that_sees_no_image_source_gets_no_direct_path(two_rooms: AcousticScene) -> None:
    """Regression for pyroomacoustics' silent bug (a receiver seeing no image source got the
    unblocked direct path): deep behind the wall every arrival comes via the doorway."""
    src, rcv = (2.0, 0.6, 1.2), (4.6, 0.4, 1.2)
    resp = two_rooms.response(src, rcv)
    jamb = np.array([4.0, 2.8])
    shortest = np.linalg.norm(jamb - src[:2]) + np.linalg.norm(np.array(rcv[:2]) - jamb)
    assert resp.arrivals
    assert min(a.delay_s for a in resp.arrivals) * SPEED_OF_SOUND >= shortest - 0.01
    # The doorway path is an edge diffraction: attenuated, more at high frequencies.
    a0 = resp.arrivals[0]
    assert a0.order == 0 and a0.band_gains[-1] < a0.band_gains[0] < 1.0
    # and it comes from the doorway's direction, not from the source's
    to_door = np.array([jamb[0] - rcv[0], jamb[1] - rcv[1]])
    assert np.dot(a0.direction[:2], to_door / np.linalg.norm(to_door)) > 0.95


def test_line_of_sight_through_doorway_is_unattenuated(two_rooms: AcousticScene) -> None:
    src, rcv = (2.0, 3.3, 1.2), (6.5, 3.2, 1.2)
    d = math.dist(src, rcv)
    resp = two_rooms.response(src, rcv)
    a = resp.arrivals[0]
    assert a.order == 0 and abs(a.delay_s - d / SPEED_OF_SOUND) * FS <= 1.0
    assert abs(a.gain - 1.0 / d) < 1e-12
    assert sum(1 for x in resp.arrivals if x.order == 0) == 1  # no duplicate via the doorway source


def test_lintel_blocks_paths_above_the_door_height(two_rooms: AcousticScene) -> None:
    low = two_rooms.response((2.0, 3.3, 1.9), (6.0, 3.3, 1.9))
    high = two_rooms.response((2.0, 3.3, 2.4), (6.0, 3.3, 2.4))
    assert abs(low.arrivals[0].delay_s * SPEED_OF_SOUND - 4.0) < 1e-9
    assert all(abs(a.delay_s * SPEED_OF_SOUND - 4.0) > 0.02 for a in high.arrivals)
    assert min(a.delay_s for a in high.arrivals) * SPEED_OF_SOUND > 4.0


@pytest.fixture(scope="module")
def door_plan():
    return row_plan((4.0, 4.0), doorway_y=(DOORWAY_Y,), door=True)


@pytest.mark.parametrize("rcv", [(6.0, 0.8, 1.2), (6.5, 3.2, 1.2)])
def test_closed_door_attenuates_but_leaks(door_plan, rcv) -> None:
    src = (2.0, 3.0, 1.2)
    e = {}
    for name, q in (("open", math.pi / 2), ("closed", 0.0)):
        resp = AcousticScene(door_plan, CFG, door_angles={0: q}).response(src, rcv)
        e[name] = _energy(omni_rir(resp))
        if name == "closed":
            assert any(a.order == -1 for a in resp.arrivals)  # the leak path
            assert all(a.gain <= 10 ** (-CFG.closed_door_loss_db / 20) / (a.delay_s * SPEED_OF_SOUND) + 1e-12 for a in resp.arrivals)
    drop = 10 * np.log10(e["closed"] / e["open"])
    assert drop <= -15.0, drop
    assert e["closed"] > 0.0 and drop > -60.0  # not total silence


def test_door_default_angle_and_leaf_at_its_angle(door_plan) -> None:
    """Door.angle (0, closed) is used by default; a half-open leaf passes less than a fully
    open one; the leaf swung to 90° lies along the room-1 side of the wall and passes all."""
    src, rcv = (2.0, 3.3, 1.2), (6.5, 3.3, 1.2)

    def e(angles):
        return _energy(omni_rir(AcousticScene(door_plan, CFG, door_angles=angles).response(src, rcv)))

    assert e(None) == e({0: 0.0})
    e_open = e({0: math.pi / 2})
    e_half = e({0: math.radians(30)})
    e_closed = e({0: 0.0})
    assert e_closed < e_half < e_open
    nodoor = _energy(omni_rir(AcousticScene(row_plan((4.0, 4.0), doorway_y=(DOORWAY_Y,)), CFG).response(src, rcv)))
    assert abs(10 * np.log10(e_open / nodoor)) < 1.0


def test_furniture_occludes_with_frequency_dependent_loss() -> None:
    cab = Furniture(0, "cabinet", 0, (2.0, 2.0), (0.6, 1.6, 1.8), 0.0, "wooden_door", False)
    plan_f = row_plan((4.0,), furniture=(cab,))
    plan_0 = row_plan((4.0,))
    src, rcv = (1.0, 2.0, 1.0), (3.0, 2.0, 1.0)
    a_f = AcousticScene(plan_f, CFG).response(src, rcv).arrivals[0]
    a_0 = AcousticScene(plan_0, CFG).response(src, rcv).arrivals[0]
    assert a_f.order == 0 and a_0.order == 0
    ratio = np.asarray(a_f.band_gains) / np.asarray(a_0.band_gains)
    assert ratio[-1] < ratio[0] < 0.7  # shadowed, deeper at high frequencies
    # a path above the cabinet is untouched
    b_f = AcousticScene(plan_f, CFG).response((1.0, 2.0, 2.2), (3.0, 2.0, 2.2)).arrivals[0]
    b_0 = AcousticScene(plan_0, CFG).response((1.0, 2.0, 2.2), (3.0, 2.0, 2.2)).arrivals[0]
    assert b_f.band_gains == b_0.band_gains


def test_receiver_inside_a_wall_is_heard_at_the_nearest_room_face(two_rooms: AcousticScene) -> None:
    """Grid cells can fall on a wall line; such a point is taken 1 cm inside the nearest room."""
    src = (2.0, 1.0, 1.2)
    in_wall = two_rooms.response(src, (3.98, 1.0, 1.2))
    at_face = two_rooms.response(src, (two_rooms.boxes[0].hi[0] - 0.01, 1.0, 1.2))  # x = 3.94
    assert in_wall.arrivals and in_wall.arrivals == at_face.arrivals
    assert abs(in_wall.arrivals[0].delay_s * SPEED_OF_SOUND - 1.94) < 1e-9


def test_open_leaf_is_a_panel_at_its_angle(door_plan) -> None:
    """Swung to 90° the leaf stands in room 1 along y ≈ 2.78 from x ≈ 4.08 to 5.12: a path
    across it is a transmission path; with the leaf closed (in the doorway) it is free."""
    src, rcv = (4.6, 3.5, 1.2), (4.6, 2.0, 1.2)
    loss = 10 ** (-CFG.closed_door_loss_db / 20)
    open_ = AcousticScene(door_plan, CFG, door_angles={0: math.pi / 2}).response(src, rcv).arrivals[0]
    shut = AcousticScene(door_plan, CFG, door_angles={0: 0.0}).response(src, rcv).arrivals[0]
    assert shut.order == 0 and abs(shut.gain - 1 / 1.5) < 1e-12
    assert open_.order == -1 and abs(open_.gain - loss / 1.5) < 1e-12
    # above the leaf's top edge the path is free again
    over = AcousticScene(door_plan, CFG, door_angles={0: math.pi / 2}).response((4.6, 3.5, 2.3), (4.6, 2.0, 2.3))
    assert over.arrivals[0].order == 0


def test_table_top_reflects_a_source_standing_on_it() -> None:
    """Furniture tops are first-order reflectors: a phone on a table is heard with the
    table's reflection (image mirrored in the top plane), and its floor reflection is shadowed."""
    tab = Furniture(0, "table", 0, (2.0, 2.0), (1.2, 0.8, 0.75), 0.0, "wooden_door", True)
    src, rcv = (2.0, 2.0, 0.80), (3.5, 2.0, 1.2)
    with_t = AcousticScene(row_plan((4.0,), furniture=(tab,)), CFG).response(src, rcv)
    without = AcousticScene(row_plan((4.0,)), CFG).response(src, rcv)
    top_len = math.dist((2.0, 2.0, 2 * 0.75 - 0.80), rcv)
    hits = [a for a in with_t.arrivals if abs(a.delay_s * SPEED_OF_SOUND - top_len) < 1e-9]
    assert len(hits) == 1 and hits[0].order == 1
    assert not any(abs(a.delay_s * SPEED_OF_SOUND - top_len) < 1e-6 for a in without.arrivals)
    floor_len = math.dist((2.0, 2.0, -0.80), rcv)
    fl_t = next(a for a in with_t.arrivals if abs(a.delay_s * SPEED_OF_SOUND - floor_len) < 1e-9)
    fl_0 = next(a for a in without.arrivals if abs(a.delay_s * SPEED_OF_SOUND - floor_len) < 1e-9)
    assert fl_t.band_gains[-1] < 0.5 * fl_0.band_gains[-1]
