"""The arm's detour planner: collision-free and reproducible (no clock-seeded RRT needed)."""

from __future__ import annotations

import numpy as np

from echo_data.robot.planner import ArmPlanner, Box
from echo_data.skills.arm import READY_GROUP, tuck_group


def _blocked_planner(seed: int) -> tuple[ArmPlanner, np.ndarray, np.ndarray]:
    p = ArmPlanner(seed=seed)
    start = tuck_group(0.3)
    goal = np.array(READY_GROUP, dtype=np.float64)
    p.sync((0.0, 0.0, 0.0), start, 0.05)
    # scan obstacle positions in front of the robot until one blocks the straight segment
    for x in np.arange(0.25, 0.9, 0.05):
        p.set_obstacles([Box("post", (float(x), 0.0, 0.95), (0.06, 0.06, 0.15))])
        if not p.collisions(start) and not p.collisions(goal) and not p.segment_free(start, goal):
            return p, start, goal
    raise AssertionError("no obstacle position blocks the straight path")


def test_via_path_detours_without_collisions_and_repeats() -> None:
    p1, start, goal = _blocked_planner(7)
    p2, _, _ = _blocked_planner(7)
    a = p1.via_path(start, goal)
    b = p2.via_path(start, goal)
    assert a is not None and b is not None
    assert len(a) == 3
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    for u, v in zip(a[:-1], a[1:]):
        assert p1.segment_free(u, v)
    assert p1.within_limits(a[1])
