"""The path follower on a kinematic base (first-order velocity lag), no physics."""

from __future__ import annotations

import math

import pytest
from support.nav_plans import two_room_plan

from echo_data.scene.nav import NavGrid, interaction_pose
from echo_data.skills.navigate import ACC_ANG, ACC_LIN, GOAL_TOL, MAX_ANG, MAX_LIN, YAW_TOL, PathFollower

DT = 0.1
BASE_RADIUS = 0.28  # the robot's physical base disc (echo_data.robot.urdf.BASE_RADIUS)


def _drive(grid: NavGrid, start: tuple[float, float, float], goal: tuple[float, float, float], lag: float = 0.05):
    """Run the follower on a unicycle whose velocities follow the commands with time constant `lag`."""
    path = grid.plan_path(start[:2], goal[:2])
    assert path is not None
    f = PathFollower(path, goal[2], DT)
    x, y, yaw = start
    v = w = 0.0
    commands, min_clear = [], math.inf
    for _ in range(800):
        cmd = f.command((x, y, yaw))
        if f.done:
            break
        commands.append(cmd)
        for _ in range(10):
            h = DT / 10
            v += (cmd[0] - v) * h / lag
            w += (cmd[2] - w) * h / lag
            x += v * math.cos(yaw) * h
            y += v * math.sin(yaw) * h
            yaw += w * h
            min_clear = min(min_clear, grid.clearance(x, y))
    return (x, y, yaw), commands, min_clear, f.done


@pytest.mark.parametrize(
    ("start", "target"),
    [((1.0, 1.0, 0.0), "faucet:0"), ((7.0, 2.5, 1.0), "phone_0"), ((1.0, 1.0, 3.0), "mug_0"), ((6.5, 1.5, -2.0), "door:0")],
)
def test_follower_reaches_pose_without_touching_walls(start, target) -> None:
    plan = two_room_plan()
    grid = NavGrid.from_plan(plan, door_angles={0: math.radians(90)})
    goal = interaction_pose(plan, target, grid=grid)
    (x, y, yaw), commands, min_clear, done = _drive(grid, start, goal)
    assert done
    assert math.hypot(x - goal[0], y - goal[1]) <= GOAL_TOL + 0.03
    assert abs(math.remainder(yaw - goal[2], 2 * math.pi)) <= YAW_TOL + math.radians(2)
    assert min_clear > BASE_RADIUS  # the base disc never overlaps an obstacle


def test_commands_respect_limits_and_ramps() -> None:
    plan = two_room_plan()
    grid = NavGrid.from_plan(plan, door_angles={0: math.radians(90)})
    goal = interaction_pose(plan, "faucet:0", grid=grid)
    _, commands, _, _ = _drive(grid, (1.0, 1.0, 0.0), goal)
    prev = (0.0, 0.0, 0.0)
    for vx, vy, wz in commands:
        assert 0.0 <= vx <= MAX_LIN + 1e-9 and vy == 0.0 and abs(wz) <= MAX_ANG + 1e-9
        assert abs(vx - prev[0]) <= ACC_LIN * DT + 1e-9
        assert abs(wz - prev[2]) <= ACC_ANG * DT + 1e-9
        prev = (vx, vy, wz)
    assert max(c[0] for c in commands) > 0.9 * MAX_LIN  # it does reach cruise speed on a 7 m path


def test_goal_behind_turns_in_place_first() -> None:
    grid = NavGrid.from_plan(two_room_plan())
    f = PathFollower(grid.plan_path((2.0, 2.0), (1.0, 2.0)), math.pi, DT)
    vx, _, wz = f.command((2.0, 2.0, 0.0))  # facing +x, goal at -x
    assert vx == 0.0 and abs(wz) > 0.0
