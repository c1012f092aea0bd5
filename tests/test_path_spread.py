"""The path-spread measures (echo_data.evaluation.path_spread): a time shift is no gap, a detour is."""

from __future__ import annotations

import numpy as np

from echo_data.evaluation.path_spread import first_arm_motion, joint_range_at_steps, path_gap


def _path(detour: float = 0.0, hold: int = 3, shift: int = 0) -> list[np.ndarray]:
    """`hold` still steps, then a straight joint move over 50 steps (paused `shift` steps half-way),
    optionally bulging `detour` rad in joint 2 mid-way."""
    start, end = np.zeros(7), np.linspace(0.5, 1.1, 7)
    out = [start.copy() for _ in range(hold)]
    for k in range(1, 51):
        q = start + (end - start) * k / 50
        q[2] += detour * np.sin(np.pi * k / 50)
        out.append(q)
        if k == 25:
            out += [q.copy() for _ in range(shift)]
    return out


def test_a_pause_is_no_gap_and_a_detour_is() -> None:
    assert first_arm_motion(_path(hold=3)) == 3
    assert first_arm_motion(_path(hold=7)) == 7
    assert path_gap(_path(hold=3), _path(hold=7, shift=4)) < 0.02  # one step of the move at most
    assert 0.5 < path_gap(_path(), _path(detour=1.0)) <= 1.0  # (nearest points of the other path: a lower bound)
    still = [np.zeros(7)] * 5
    assert first_arm_motion(still) == 5 and path_gap(still, _path()) == float("inf")


def test_joint_range_at_steps_aligns_at_the_first_motion() -> None:
    r = joint_range_at_steps([_path(hold=2), _path(hold=9)], (0, 10, 40))
    assert r == {0: 0.0, 10: 0.0, 40: 0.0}
    r = joint_range_at_steps([_path(), _path(detour=0.5)], (25,))
    assert abs(r[25] - 0.5) < 0.02
