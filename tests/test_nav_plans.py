"""The two-room plan the navigation tests share (tests/support/nav_plans.py) round-trips and closes its doorway."""

from __future__ import annotations

from support.nav_plans import two_room_plan

from echo_data.floorplan import FloorPlan


def test_plan_round_trips_and_door_closes_its_doorway() -> None:
    """The fixture itself: JSON round trip, and the closed leaf spans the doorway."""
    plan = two_room_plan()
    assert FloorPlan.from_dict(plan.to_dict()) == plan
    door, dw = plan.doors[0], plan.doorways[0]
    edge = door.free_edge(0.0)
    assert abs(edge[1] - door.hinge[1] - door.width) < 1e-9
    assert door.hinge[1] <= dw.center[1] - dw.width / 2 + 0.05 and edge[1] >= dw.center[1] + dw.width / 2 - 0.05
