"""The hand-made room plans the acoustics tests share (tests/support/room_plans.py) are consistent."""

from __future__ import annotations

import math

from support.room_plans import DOOR_W, row_plan


def test_row_plan_is_consistent() -> None:
    plan = row_plan(door=True)
    assert len(plan.rooms) == 3 and len(plan.doorways) == 2
    d = plan.doors[0]
    # the closed leaf spans the doorway on room 1's side, opening turns it into room 1
    assert d.hinge[0] > plan.doorways[0].center[0]
    assert d.free_edge(math.pi / 2)[0] > d.hinge[0] + 0.9
    assert abs(d.free_edge(0.0)[1] - (plan.doorways[0].center[1] + DOOR_W / 2 + 0.02)) < 1e-9
