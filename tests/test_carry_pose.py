"""The compact carry pose the Place expert drives in: READY's grip, a smaller sweep when the base turns."""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.recipe import Recipe
from echo_data.robot.planner import ArmPlanner
from echo_data.robot.robot import HEAD_TILT, Robot
from echo_data.skills import arm
from echo_data.skills.place import CARRY_DRIVE_GROUP

ARM_LINKS = ("shoulder_lift_link", "upperarm_roll_link", "elbow_flex_link", "forearm_roll_link", "wrist_flex_link", "wrist_roll_link", "gripper_link")


def _pose(robot: Robot, group: np.ndarray) -> tuple[float, sapien.Pose]:
    q = robot.articulation.get_qpos()
    q[robot.torso_index] = group[0]
    q[robot.arm_indices] = group[1:]
    robot.articulation.set_qpos(q)
    reach = max(math.hypot(*robot.links[n].entity_pose.p[:2]) for n in ARM_LINKS)
    return reach, robot.ee_pose()


def test_carry_pose_holds_like_ready_and_sweeps_less() -> None:
    robot = Robot(sapien.Scene([sapien.physx.PhysxCpuSystem()]), Recipe(name="t").robot)
    ready_reach, ready_tcp = _pose(robot, arm.READY_GROUP)
    carry_reach, carry_tcp = _pose(robot, CARRY_DRIVE_GROUP)
    # the object stays where READY holds it: same TCP position and jaw direction
    assert np.allclose(carry_tcp.p, ready_tcp.p, atol=0.005)
    assert abs(math.remainder(arm.jaw_yaw(carry_tcp) - arm.jaw_yaw(ready_tcp), 2 * math.pi)) < 0.05
    # a turn in place sweeps a circle of the farthest link's radius: 0.35 m instead of 0.47 m
    assert carry_reach <= 0.36 < 0.45 <= ready_reach
    planner = ArmPlanner(seed=0)
    planner.sync((0.0, 0.0, 0.0), arm.READY_GROUP, 0.0, (0.0, HEAD_TILT))
    planner.set_obstacles([])
    planner.attach_box([0.15, 0.07, 0.015], sapien.Pose([0.0, 0.0, 0.05]))  # a phone in hand
    assert planner.path(arm.READY_GROUP.copy(), CARRY_DRIVE_GROUP.copy()) is not None
