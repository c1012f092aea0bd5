"""Occupancy grid, A* and interaction poses on the hand-made two-room plan."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from support.nav_plans import two_room_plan

from echo_data.floorplan import Furniture
from echo_data.scene.nav import NavGrid, handle_xy, interaction_pose, target_point

R = 0.32
OPEN = {0: math.radians(90)}


def _occ(grid: NavGrid, x: float, y: float) -> bool:
    i, j = grid.cell(x, y)
    return bool(grid.occupied[i, j])


def _path_min_clearance(grid: NavGrid, path: list[tuple[float, float]]) -> float:
    return min(grid.segment_clearance(a, b) for a, b in zip(path, path[1:]))


def test_walls_furniture_and_outside_are_blocked() -> None:
    grid = NavGrid.from_plan(two_room_plan(), robot_radius=R)
    assert _occ(grid, 2.0, 0.0) and _occ(grid, 4.0, 0.8) and _occ(grid, 4.0, 3.2)  # walls
    assert _occ(grid, 1.5, 3.45) and _occ(grid, 7.65, 0.9)  # table, sink cabinet
    assert _occ(grid, -0.2, 2.0) and _occ(grid, 8.2, 2.0)  # outside the apartment
    assert not _occ(grid, 2.0, 2.0) and grid.is_free(2.0, 2.0)
    # Inflation: a point 0.2 m from a wall is not occupied but not free for a 0.32 m base.
    assert not _occ(grid, 0.25, 2.0) and not grid.is_free(0.25, 2.0)
    assert grid.is_free(0.45, 2.0)


def test_clearance_is_distance_to_nearest_wall() -> None:
    grid = NavGrid.from_plan(two_room_plan(), robot_radius=R)
    # (1.0, 1.0): nearest obstacle faces are the walls at x=0.05 and y=0.05, 0.95 m away.
    assert grid.clearance(1.0, 1.0) == pytest.approx(0.95, abs=0.06)
    assert grid.clearance(2.0, 0.0) == 0.0


def test_closed_door_blocks_doorway_open_door_frees_it() -> None:
    closed = NavGrid.from_plan(two_room_plan(), robot_radius=R)
    opened = NavGrid.from_plan(two_room_plan(), robot_radius=R, door_angles=OPEN)
    assert _occ(closed, 4.1, 2.0)  # the closed leaf stands in the doorway
    assert not _occ(opened, 4.1, 2.0) and opened.is_free(4.0, 2.05)
    # The open leaf blocks where it stands now: pointing east from the hinge.
    hinge = two_room_plan().doors[0].hinge
    assert _occ(opened, hinge[0] + 0.5, hinge[1]) and not _occ(closed, hinge[0] + 0.5, hinge[1])
    # The plan's own Door.angle is used when no override is given.
    assert not _occ(NavGrid.from_plan(two_room_plan(door_angle=math.radians(90))), 4.1, 2.0)


def test_astar_goes_through_open_doorway_not_walls() -> None:
    closed = NavGrid.from_plan(two_room_plan(), robot_radius=R)
    opened = NavGrid.from_plan(two_room_plan(), robot_radius=R, door_angles=OPEN)
    start, goal = (1.0, 1.0), (6.5, 1.5)
    assert closed.plan_path(start, goal) is None
    path = opened.plan_path(start, goal)
    assert path is not None
    assert path[0] == start and path[-1] == goal
    # It crosses the wall line x=4 inside the doorway (y in [1.5, 2.5]) and nowhere else.
    crossings = []
    for (ax, ay), (bx, by) in zip(path, path[1:]):
        if (ax - 4.0) * (bx - 4.0) < 0:
            crossings.append(ay + (4.0 - ax) / (bx - ax) * (by - ay))
    assert len(crossings) == 1 and 1.5 + R <= crossings[0] <= 2.5 - R + 1e-6
    # Shortened path is near the straight-line lower bound (start->doorway->goal).
    length = sum(math.dist(a, b) for a, b in zip(path, path[1:]))
    assert length < 1.15 * (math.dist(start, (4.0, 2.0)) + math.dist((4.0, 2.0), goal))


def test_path_clearance_is_at_least_robot_radius() -> None:
    grid = NavGrid.from_plan(two_room_plan(), robot_radius=R, door_angles=OPEN)
    rng = np.random.default_rng(0)
    free = np.argwhere(grid.free)
    checked = 0
    for _ in range(12):
        a = grid.center(*free[rng.integers(len(free))])
        b = grid.center(*free[rng.integers(len(free))])
        path = grid.plan_path(a, b)
        assert path is not None  # the open door connects all free space
        if len(path) > 1:
            assert _path_min_clearance(grid, path) >= R
            checked += 1
    assert checked >= 10


def test_blocked_goal_snaps_within_radius_else_none() -> None:
    grid = NavGrid.from_plan(two_room_plan(), robot_radius=R)
    # 0.2 m from the south wall: blocked, but a free cell lies within 0.3 m.
    path = grid.plan_path((2.0, 2.0), (2.0, 0.25))
    assert path is not None and grid.is_free(*path[-1]) and math.dist(path[-1], (2.0, 0.25)) <= 0.3
    # Inside the table: nearest free cell is farther than 0.3 m.
    assert grid.plan_path((2.0, 2.0), (1.5, 3.45)) is None


@pytest.mark.parametrize("target", ["phone_0", "mug_0", "furniture:0", "furniture:2", "faucet:0", "door:0"])
def test_interaction_poses_are_free_and_face_target(target: str) -> None:
    plan = two_room_plan()
    grid = NavGrid.from_plan(plan, robot_radius=R)
    x, y, yaw = interaction_pose(plan, target, grid=grid)
    assert grid.is_free(x, y)
    tx, ty = target_point(plan, target)
    bearing = math.atan2(ty - y, tx - x)
    assert abs(math.remainder(yaw - bearing, 2 * math.pi)) < math.radians(1)
    d = math.hypot(tx - x, ty - y)
    if target in ("phone_0", "mug_0"):
        assert 0.55 <= d <= 0.85  # within a Fetch arm's reach
    # Reachable from the start room with the door open.
    opened = NavGrid.from_plan(plan, robot_radius=R, door_angles=OPEN)
    assert opened.plan_path((1.0, 1.0), (x, y)) is not None


def test_object_pose_stands_in_front_of_receptacle() -> None:
    plan = two_room_plan()
    x, y, _ = interaction_pose(plan, "phone_0")
    table = plan.furniture[0]
    assert y < table.footprint.ymin - R  # the table's front faces south (yaw -pi/2)
    assert abs(x - 1.3) < 0.05


def test_door_pose_is_on_swing_side_near_handle() -> None:
    plan = two_room_plan()
    x, y, _ = interaction_pose(plan, "door:0")
    assert plan.room_at(x, y) == plan.doors[0].swing_room
    hx, hy = target_point(plan, "door:0")
    assert 0.6 <= math.hypot(hx - x, hy - y) <= 1.1


def test_blocked_nominal_pose_falls_back_to_a_free_one() -> None:
    """A bin right in front of the phone blocks the nominal pose; a nearby free one is chosen."""
    plan = two_room_plan()
    nominal = interaction_pose(plan, "phone_0")
    nx, ny = nominal[0], nominal[1]
    blocker = Furniture(3, "cabinet", 0, (nx, ny - 0.1), (0.3, 0.3, 0.5), 0.0, "wooden_door", False)
    plan = dataclasses.replace(plan, furniture=plan.furniture + (blocker,))
    grid = NavGrid.from_plan(plan, robot_radius=R)
    assert not grid.is_free(nx, ny)
    x, y, yaw = interaction_pose(plan, "phone_0", grid=grid)
    assert grid.is_free(x, y) and math.dist((x, y), (1.3, 3.3)) <= 0.85


def test_no_free_pose_raises() -> None:
    """A receptacle boxed in by cabinets on its front and both sides has no interaction pose."""
    plan = two_room_plan()
    blockers = (
        Furniture(3, "cabinet", 0, (1.5, 2.7), (3.9, 0.8, 0.5), 0.0, "wooden_door", False),
        Furniture(4, "cabinet", 0, (0.45, 3.45), (0.9, 0.7, 0.5), 0.0, "wooden_door", False),
        Furniture(5, "cabinet", 0, (2.6, 3.45), (1.0, 0.7, 0.5), 0.0, "wooden_door", False),
    )
    plan = dataclasses.replace(plan, furniture=plan.furniture + blockers)
    with pytest.raises(ValueError):
        interaction_pose(plan, "phone_0")


@pytest.mark.parametrize("q", [0.0, 0.7, 1.6])
def test_handle_bars_are_blocked_in_the_grid(q: float) -> None:
    """The handle layout has one owner (`echo_data.scene.door_handle`, checked against the built
    SAPIEN door in test_door_articulation); the grid blocks the swing-side bar wherever the leaf stands."""
    door = two_room_plan().doors[0]
    grid = NavGrid.from_plan(two_room_plan(), robot_radius=R, door_angles={0: q})
    assert _occ(grid, *handle_xy(door, q))
    assert handle_xy(door, q) == handle_xy(door, q, door.open_sign)


def test_start_in_a_narrow_pocket_steps_out_with_larger_snap() -> None:
    """A 0.7 m dead-end corridor: a 0.28 m base fits, a grid inflated by 0.36 m does not."""
    plan = two_room_plan()
    cabinets = (
        Furniture(3, "cabinet", 0, (1.15, 0.55), (0.4, 1.0, 0.8), math.pi / 2, "wooden_door", False),
        Furniture(4, "cabinet", 0, (2.25, 0.55), (0.4, 1.0, 0.8), math.pi / 2, "wooden_door", False),
    )
    plan = dataclasses.replace(plan, furniture=plan.furniture + cabinets)
    grid = NavGrid.from_plan(plan, robot_radius=0.36)
    start = (1.7, 0.7)
    assert not grid.is_free(*start) and grid.clearance(*start) > 0.28
    assert grid.plan_path(start, (3.0, 2.0)) is None  # nothing free within the default 0.3 m
    path = grid.plan_path(start, (3.0, 2.0), start_snap=0.6)
    assert path is not None and path[0] == start and grid.is_free(*path[1])
    assert math.dist(start, path[1]) <= 0.6
    assert _path_min_clearance(grid, path[1:]) >= 0.36
