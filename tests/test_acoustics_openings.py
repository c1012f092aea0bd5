"""Sound from another room comes from the doorway: behind a wall the first arrival and the
early sound lean towards the doorway's side of the head, not the (hidden) source's; the
neighbour's late energy is rendered from points across the opening."""

from __future__ import annotations

import numpy as np
from support.room_plans import row_plan

from echo_data.acoustics.binaural import binaural_irs
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.room import AcousticScene
from echo_data.recipe import AcousticsConfig

FS = 16000


def _onset_lead_us(ir: np.ndarray) -> float:
    """How much earlier (µs) the first sound reaches the left ear than the right: per ear, the
    first crossing of 30 % of the larger ear's peak within 2 ms of the first sound (8x
    upsampled); an ear that never crosses counts as reached at the window's end."""
    from scipy.signal import resample_poly

    on = int(np.argmax(np.abs(ir).max(axis=1) > 0.05 * np.abs(ir).max()))
    seg = np.abs(resample_poly(ir[max(on - 16, 0) : on + 32].astype(np.float64), 8, 1, axis=0))
    hit = seg >= 0.3 * seg.max()
    t = [int(np.argmax(hit[:, c])) if hit[:, c].any() else len(seg) for c in (0, 1)]
    return (t[1] - t[0]) / (8 * FS) * 1e6


def test_sound_behind_a_wall_arrives_from_the_doorway_side() -> None:
    # two 4 x 4 m rooms, the doorway in the shared wall x = 4 at y = 3 (1 m wide)
    scene = AcousticScene(row_plan((4.0, 4.0), doorway_y=(3.0,)), AcousticsConfig())
    hrtf = Hrtf.load("kemar", FS)
    src = (1.0, 1.0, 1.0)
    rcvs = np.array([(5.0, y, 1.2) for y in (1.2, 1.5, 1.8)])
    # from these receivers the doorway is behind-left for a head facing +x (yaw 0) and
    # ahead-right for a head facing -x (yaw 180°); the hidden source lies the other way:
    # behind-right (yaw 0) / ahead-left (yaw 180°)
    for resp, r in zip(scene.responses(src, rcvs), rcvs):
        straight = float(np.linalg.norm(r - np.asarray(src))) / 343.0
        assert resp.arrivals[0].delay_s > straight + 1e-3  # a wall is in the way: the sound goes round
        first = resp.arrivals[0].direction
        assert first[0] < 0 and first[1] > 0  # the earliest sound comes from the doorway (up-left)
        door_left, door_right = binaural_irs(resp, [0.0, np.pi], hrtf).astype(np.float64)
        # first arrival: the ear on the doorway's side hears it first
        assert _onset_lead_us(door_left) > 100.0 and _onset_lead_us(door_right) < -100.0
        # the first 20 ms (the opening as a secondary source, with its own reflections in
        # this room) are louder on the doorway's side
        on = int(np.argmax(np.abs(door_left).max(axis=1) > 0.1 * np.abs(door_left).max()))
        early = slice(on, on + int(0.02 * FS))
        ild = [10 * np.log10((ir[early, 0] ** 2).sum() / (ir[early, 1] ** 2).sum()) for ir in (door_left, door_right)]
        assert ild[0] > 1.0 and ild[1] < -1.0, (r, ild)
        assert resp.apertures  # rendered from points across the opening
