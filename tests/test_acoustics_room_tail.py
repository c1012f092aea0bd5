"""Late reverberation: band T30 against Sabine/Eyring in shoeboxes, energy ordering across
rooms, onset after the first arrival, deterministic bytes."""

from __future__ import annotations

import numpy as np
import pyroomacoustics as pra
import pytest
from support.room_plans import H, band_t30, row_plan, shoebox_plan

from echo_data.acoustics.room import AcousticScene, omni_rir
from echo_data.acoustics.types import BAND_CENTERS, SPEED_OF_SOUND
from echo_data.recipe import AcousticsConfig

FS = 16000


def _alpha(name: str) -> np.ndarray:
    """Database absorption at 125 Hz … 4 kHz, read independently of the product code."""
    m = pra.Material(name).energy_absorption
    return np.asarray(m["coeffs"][:6], dtype=np.float64)


def _expected_t60(sx: float, sy: float, wall: str, floor: str, ceiling: str) -> tuple[np.ndarray, np.ndarray]:
    """Sabine and Eyring T60 (125 Hz … 4 kHz) of a closed shoebox, with air absorption."""
    V = sx * sy * H
    s_wall, s_fc = 2 * (sx + sy) * H, sx * sy
    S = s_wall + 2 * s_fc
    A = s_wall * _alpha(wall) + s_fc * (_alpha(floor) + _alpha(ceiling))
    air = pra.parameters.Physics().get_air_absorption()["coeffs"][:6]
    m4V = 4 * np.asarray(air) * V
    k = 24 * np.log(10) / SPEED_OF_SOUND
    sabine = k * V / (A + m4V)
    eyring = k * V / (-S * np.log(1 - A / S) + m4V)
    return sabine, eyring


@pytest.mark.parametrize(
    "room",
    [
        (5.0, 4.0, "plasterboard", "linoleum_on_concrete", "ceiling_plasterboard"),
        (7.0, 5.5, "brickwork", "carpet_cotton", "ceiling_plasterboard"),
    ],
)
def test_band_t30_matches_sabine_eyring(room) -> None:
    sx, sy, wall, floor, ceiling = room
    scene = AcousticScene(shoebox_plan(sx, sy, wall, floor, ceiling), AcousticsConfig(rir_seconds=2.0, scattering=0.3))
    lo = scene.boxes[0].lo
    sabine, eyring = _expected_t60(sx, sy, wall, floor, ceiling)
    for src, rcv in (((1.2, 1.0, 1.1), (sx - 1.3, sy - 0.9, 1.5)), ((sx / 2, 0.8, 1.6), (0.9, sy - 1.2, 1.2))):
        h = omni_rir(scene.response(tuple(lo + src), tuple(lo + rcv)))
        t30 = np.asarray([band_t30(h, fc) for fc in BAND_CENTERS[:6]])
        for b in range(6):
            lo_t, hi_t = min(sabine[b], eyring[b]), max(sabine[b], eyring[b])
            assert 0.75 * lo_t <= t30[b] <= 1.25 * hi_t, (BAND_CENTERS[b], t30[b], sabine[b], eyring[b])


@pytest.fixture(scope="module")
def three_rooms() -> AcousticScene:
    return AcousticScene(row_plan((4.0, 4.0, 4.0), doorway_y=(3.0, 1.0)), AcousticsConfig())


def test_energy_ordering_source_adjacent_far(three_rooms: AcousticScene) -> None:
    src = (1.5, 1.5, 1.0)
    rcv = np.array([(x, y, 1.2) for x0 in (0.0, 4.0, 8.0) for x, y in ((x0 + 1.0, 1.0), (x0 + 2.0, 2.5), (x0 + 3.0, 3.2))])
    resp = three_rooms.responses(src, rcv)
    e = np.asarray([np.sum(omni_rir(r).astype(np.float64) ** 2) for r in resp]).reshape(3, 3)
    tail = np.asarray([np.sum(r.tail.astype(np.float64) ** 2) for r in resp]).reshape(3, 3)
    assert e[0].min() > e[1].max() and e[1].min() > e[2].max(), e
    assert tail[0].min() > tail[1].max() > 0 and tail[1].min() > tail[2].max() > 0, tail


def test_tail_starts_at_the_first_arrival(three_rooms: AcousticScene) -> None:
    for rcv in ((3.0, 2.0, 1.2), (6.0, 0.5, 1.2), (10.5, 3.5, 1.2)):
        r = three_rooms.response((1.5, 1.5, 1.0), rcv)
        first = min(a.delay_s for a in r.arrivals)
        i = int(np.floor(first * FS))
        assert not r.tail[:i].any() and r.tail[i : i + 400].any()
        assert r.tail.dtype == np.float32 and r.tail.shape == (r.length,) == (8000,)


def test_deterministic_bytes_independent_of_global_state() -> None:
    plan = row_plan((4.0, 4.0, 4.0), doorway_y=(3.0, 1.0))
    src, rcv = (1.5, 1.5, 1.0), np.array([(2.5, 2.5, 1.2), (6.0, 1.0, 1.2), (10.0, 3.0, 1.2)])

    def blob(seed: int) -> bytes:
        np.random.seed(seed)
        out = b""
        for r in AcousticScene(plan, AcousticsConfig()).responses(src, rcv):
            out += r.tail.tobytes() + repr(r.arrivals).encode() + omni_rir(r).tobytes()
        return out

    assert blob(1) == blob(2)
    # one response equals the same receiver in a batch
    one = AcousticScene(plan, AcousticsConfig()).response(src, tuple(rcv[1]))
    batch = AcousticScene(plan, AcousticsConfig()).responses(src, rcv)[1]
    assert one.tail.tobytes() == batch.tail.tobytes() and one.arrivals == batch.arrivals
    # the tail noise is seeded from quantised (1 mm) positions: 0.04 mm apart → the same
    # noise (only the onset moves by a hair); 1 cm apart → a different realisation
    sc = AcousticScene(plan, AcousticsConfig())
    a, b, c = (sc.response(src, p).tail for p in ((2.5, 2.5, 1.2), (2.50004, 2.5, 1.2), (2.51, 2.5, 1.2)))
    assert np.corrcoef(a[2000:], b[2000:])[0, 1] > 0.999
    assert abs(np.corrcoef(a[2000:], c[2000:])[0, 1]) < 0.2


def test_far_room_is_reached_through_both_doorways(three_rooms: AcousticScene) -> None:
    """Room 2 is two doorways away: its first arrival follows the doorway route (never the
    blocked straight line) and comes from the near doorway's side."""
    src, rcv = np.array([1.5, 1.5, 1.0]), np.array([10.0, 3.0, 1.2])
    r = three_rooms.response(tuple(src), tuple(rcv))
    # shortest route through the openings y ∈ [2.5, 3.5] at x = 4 and y ∈ [0.5, 1.5] at x = 8
    corners = [np.array([4.0, 2.5, 1.1]), np.array([8.0, 1.5, 1.1])]
    bound = np.linalg.norm(corners[0] - src) + np.linalg.norm(corners[1] - corners[0]) + np.linalg.norm(rcv - corners[1])
    first = r.arrivals[0]
    assert first.order == 0 and bound - 0.05 <= first.delay_s * SPEED_OF_SOUND <= bound + 1.0
    assert np.dot(first.direction[:2], (corners[1] - rcv)[:2] / np.linalg.norm((corners[1] - rcv)[:2])) > 0.9
    # and twice diffracted, it is weaker than the free-field sound over the same distance
    assert first.gain * first.band_gains[3] < 1.0 / (first.delay_s * SPEED_OF_SOUND)


def test_unknown_material_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="no_such_material"):
        AcousticScene(shoebox_plan(4.0, 4.0, "no_such_material", "carpet_cotton", "ceiling_plasterboard"), AcousticsConfig())


def test_coupled_room_energy_builds_up_and_integrates_to_the_steady_level(three_rooms: AcousticScene) -> None:
    """Diffuse energy after an impulse in room 0: its time integral is the steady-state
    energy balance; rooms further away build up later and decay no faster (coupled rooms)."""
    ac = three_rooms.acoustics
    env = ac.energy_envelopes(0, FS, 3 * FS)
    np.testing.assert_allclose(env.sum(axis=2), ac.levels(0), rtol=5e-3)
    peaks = env.argmax(axis=2)  # (rooms, bands)
    assert np.all(peaks[0] == 0) and np.all(peaks[1] > 0) and np.all(peaks[2] > peaks[1])
    i, j = int(0.3 * FS), int(0.6 * FS)
    slope = 10 * np.log10(env[:, :, j] / env[:, :, i])  # dB over 0.3 s
    assert np.all(slope[1] >= slope[0] - 0.5) and np.all(slope[2] >= slope[1] - 0.5)
    # a room alone decays with Eyring's time
    single = AcousticScene(shoebox_plan(4.0, 4.0, "plasterboard", "linoleum_on_concrete", "ceiling_plasterboard"), AcousticsConfig())
    e1 = single.acoustics.energy_envelopes(0, FS, FS)[0]
    t60 = -60.0 / (10 * np.log10(e1[:, 8000 - 1] / e1[:, 0]) / ((8000 - 1) / FS))
    np.testing.assert_allclose(t60, single.acoustics.t60[0], rtol=1e-3)


def test_diffuse_level_is_continuous_through_a_doorway() -> None:
    """Walking through the doorway the late level changes smoothly (the opening shows each
    side the other room's diffuse field), while the rooms' own levels differ."""
    scene = AcousticScene(row_plan((4.0, 4.0), doorway_y=(3.3,)), AcousticsConfig())
    xs = np.array([1.5, 3.94, 4.06, 6.5])
    resp = scene.responses((1.0, 1.0, 1.2), np.array([(x, 3.3, 1.2) for x in xs]))
    # late energy (after 60 ms: past every onset here) in dB
    # (own room's tail plus the neighbour's late energy heard through the opening)
    late = np.asarray(
        [
            10 * np.log10(sum(np.sum(x[..., 960:].astype(np.float64) ** 2) for x in [r.tail, *(ap.signals for ap in r.apertures)]))
            for r in resp
        ]
    )
    assert late[0] - late[3] > 2.0  # source room louder than the next room
    assert abs(late[1] - late[2]) < 1.0  # but no step at the doorway plane
    assert late[0] > late[1] and late[2] > late[3]
