"""Reaching a handle or a lever: the arm and base primitives that OpenDoor and CloseSink share.

A short holonomic base approach to a stance in front of a door or a counter, IK near a
reference or a seed pose, the world's arm planner with the door leaves as obstacles, and the
arm's way out of and back into its tuck (`echo_data.skills.arm` holds the generic arm motions).
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sapien

from echo_data.records import ACTION_DIM
from echo_data.robot.planner import ArmPlanner, Box
from echo_data.robot.robot import HEAD_PAN, HEAD_TILT, Robot
from echo_data.skills import arm

if TYPE_CHECKING:
    from echo_data.world import World

APPROACH_SPEED = 0.4  # m/s, final base approach
APPROACH_MIN_SPEED = 0.04  # m/s, so the last centimetres do not crawl
APPROACH_TURN = 0.8  # rad/s
APPROACH_TOL = 0.015  # m
APPROACH_YAW_TOL = math.radians(1.5)


def wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def door_boxes(world: World) -> list[Box]:
    """Door leaves at their current hinge angles (handles left out: the gripper takes them) and
    the floor, as planner boxes; `arm.scene_boxes` has walls, furniture and objects."""
    plan = world.plan
    angles = world.handles.door_angles()
    x, y, _ = world.robot.base_pose()
    boxes = [Box("floor", (x, y, -0.05), (6.0, 6.0, 0.1))]
    for d in plan.doors:
        yaw = d.leaf_yaw(angles.get(d.index, d.angle))
        mid = (d.hinge[0] + d.width / 2.0 * math.cos(yaw), d.hinge[1] + d.width / 2.0 * math.sin(yaw))
        if math.hypot(mid[0] - x, mid[1] - y) < arm.OBSTACLE_RADIUS + d.width:
            boxes.append(Box(f"door_{d.index}", (mid[0], mid[1], d.height / 2.0), (d.width, d.thickness, d.height), yaw))
    return boxes


def planner_at(world: World, base: tuple[float, float, float] | None = None) -> ArmPlanner:
    """The world's arm planner with the apartment's nearby boxes, its base at `base` (default: where it is)."""
    robot = world.robot
    planner = arm.arm_planner(world, extra=door_boxes(world))
    if base is not None:
        planner.sync(base, arm.commanded_group(robot), robot.gripper_opening(), (HEAD_PAN, HEAD_TILT))
        planner.set_obstacles(arm.scene_boxes(world) + door_boxes(world))  # re-expressed in the new base frame
    return planner


def tcp_pose(position: np.ndarray, rotation: np.ndarray) -> sapien.Pose:
    """A world TCP pose from a position and a 3x3 rotation (columns: approach, finger travel, normal)."""
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = position
    return sapien.Pose(m)


def reach_ik(planner: ArmPlanner, position: np.ndarray, rotation: np.ndarray, torso: float, ref: np.ndarray, fix_torso: bool = False) -> np.ndarray | None:
    """IK for a first reach: the solution nearest the reference arm shape `ref` at `torso`."""
    return planner.ik(tcp_pose(position, rotation), np.concatenate([[torso], ref]), fix_torso=fix_torso, tries=40)


def near_ik(planner: ArmPlanner, position: np.ndarray, rotation: np.ndarray, seed: np.ndarray, fix_torso: bool = False) -> np.ndarray | None:
    """IK next to `seed` (smooth sequences): None when only a different arm branch reaches it."""
    q = planner.ik(tcp_pose(position, rotation), seed, fix_torso=fix_torso, tries=8)
    if q is None or float(np.max(np.abs(q - seed))) > 0.6:
        return None
    return q


def arm_action(robot: Robot, q: np.ndarray, gripper: float, base: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """An action holding torso + arm at `q` (8 values) and the gripper at `gripper` (m)."""
    a = np.zeros(ACTION_DIM, dtype=np.float32)
    a[0:3] = base
    a[3] = q[0]
    a[4:11] = q[1:8]
    a[11] = gripper
    return a


@dataclass
class Moved:
    """How a base approach ended."""

    success: bool
    reason: str
    steps: int


def approach_base(
    world: World, goal: tuple[float, float, float], hold: np.ndarray, max_steps: int
) -> Generator[np.ndarray, None, Moved]:
    """Drive the (holonomic) base straight to a nearby pose, holding torso/arm/gripper as in `hold`.

    For the last few decimetres in front of a door or counter, where the path is clear by
    construction of the interaction pose; longer trips are Navigate's job.
    """
    robot = world.robot
    steps = 0
    while True:
        x, y, yaw = robot.base_pose()
        ex, ey, eyaw = goal[0] - x, goal[1] - y, wrap(goal[2] - yaw)
        if math.hypot(ex, ey) < APPROACH_TOL and abs(eyaw) < APPROACH_YAW_TOL:
            break
        if steps >= max_steps:
            return Moved(False, "timeout", steps)
        c, s = math.cos(yaw), math.sin(yaw)
        v = 2.0 * np.array([c * ex + s * ey, -s * ex + c * ey])
        speed = float(np.linalg.norm(v))
        if speed > APPROACH_SPEED:
            v *= APPROACH_SPEED / speed
        elif 0.0 < speed < APPROACH_MIN_SPEED:
            v *= APPROACH_MIN_SPEED / speed
        action = np.array(hold, dtype=np.float32)
        action[0:3] = (v[0], v[1], float(np.clip(2.0 * eyaw, -APPROACH_TURN, APPROACH_TURN)))
        yield action
        steps += 1
    stop = np.array(hold, dtype=np.float32)
    stop[0:3] = 0.0
    yield stop
    return Moved(True, "", steps + 1)


def untuck_waypoints(start: np.ndarray, goal: np.ndarray) -> list[np.ndarray]:
    """Joint waypoints from `start` to a reach `goal`: out of the tuck with the upper arm raised
    while the torso already travels (shorter than passing through the robot's READY pose)."""
    if not arm.is_tucked(start):
        return [start, goal]
    raised = arm.tuck_group(float(goal[0]))
    raised[2] = arm.UNTUCK_LIFT
    return [start, raised, goal]


def tuck_arm(world: World, gripper: float) -> Generator[np.ndarray, None, int | None]:
    """Bring the arm back into the tuck (upper arm raised on the way in); None when no path is found."""
    robot = world.robot
    planner = planner_at(world)
    start = arm.commanded_group(robot)
    raised = arm.tuck_group(float(start[0]))
    raised[2] = arm.UNTUCK_LIFT
    path = arm.plan_through(planner, [start, raised, arm.tuck_group(float(start[0]))], gripper=gripper)
    if path is None:
        return None
    return (yield from arm.follow_path(world, path, gripper=gripper))
