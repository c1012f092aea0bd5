"""The carry pose the Place expert drives in: out of the head camera's view, reached with the hand
kept pointing down, a smaller sweep when the base turns."""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.recipe import Recipe
from echo_data.robot.planner import ArmPlanner
from echo_data.robot.robot import HEAD_TILT, Robot
from echo_data.skills import arm
from echo_data.skills.head_view import HeadView, arm_reach, set_group
from echo_data.skills.place import CARRY_DRIVE_GROUP


def _tilt_deg(tcp: sapien.Pose) -> float:
    """Angle between the gripper's approach axis (TCP +x) and straight down."""
    return math.degrees(math.acos(min(1.0, -float(tcp.to_transformation_matrix()[2, 0]))))


def test_carry_pose_keeps_the_head_view_clear() -> None:
    """Share of rendered head-camera pixels whose segmentation is a robot link or the held object."""
    view = HeadView()
    ready = {c: view.covered(arm.READY_GROUP, c) for c in view.held}
    carry = {c: view.covered(CARRY_DRIVE_GROUP, c) for c in view.held}
    # READY (where Pick ends) fills most of the view; the carry leaves >= 90 % of it clear
    assert min(ready.values()) > 0.5, ready
    assert max(carry.values()) < 0.10, carry


def test_fold_keeps_the_hand_down_and_sweeps_less() -> None:
    robot = Robot(sapien.Scene([sapien.physx.PhysxCpuSystem()]), Recipe(name="t").robot)
    ready_tcp = set_group(robot, arm.READY_GROUP)
    ready_reach = arm_reach(robot)
    carry_tcp = set_group(robot, CARRY_DRIVE_GROUP)
    # the object stays at least as high as READY holds it (above every receptacle) and the
    # arm inside a smaller circle when the base turns
    assert carry_tcp.p[2] >= ready_tcp.p[2] - 0.005
    assert arm_reach(robot) <= 0.36 < 0.45 <= ready_reach
    # Place follows the straight joint segment; along it the hand points down within 4 deg, so the
    # two-finger pinch does not let the object pivot about the jaw axis
    tilts = [_tilt_deg(set_group(robot, arm.READY_GROUP + (CARRY_DRIVE_GROUP - arm.READY_GROUP) * t)) for t in np.linspace(0.0, 1.0, 41)]
    assert max(tilts) < 4.0, tilts
    planner = ArmPlanner(seed=0)
    planner.sync((0.0, 0.0, 0.0), arm.READY_GROUP, 0.0, (0.0, HEAD_TILT))
    planner.set_obstacles([])
    planner.attach_box([0.15, 0.07, 0.015], sapien.Pose([0.0, 0.0, 0.05]))  # a phone in hand
    assert planner.segment_free(arm.READY_GROUP.copy(), CARRY_DRIVE_GROUP.copy())
