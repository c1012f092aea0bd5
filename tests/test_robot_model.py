"""The Fetch-like robot: URDF/SRDF consistency, drives, proprioception layout, determinism."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import sapien

from echo_data.recipe import RobotConfig
from echo_data.records import ACTION_DIM, STATE_DIM, STATE_NAMES
from echo_data.robot import urdf as U
from echo_data.robot.robot import GRIPPER_OPEN, TUCK_QPOS, Robot


def physics_scene() -> sapien.Scene:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(0.01)
    return scene


def make_robot(pose: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[sapien.Scene, Robot]:
    scene = physics_scene()
    robot = Robot(scene, RobotConfig())
    robot.set_base_pose(*pose)
    return scene, robot


def run(scene: sapien.Scene, robot: Robot, action: np.ndarray, control_steps: int) -> None:
    robot.apply(action)
    for _ in range(control_steps * 10):
        robot.before_substep()
        scene.step()


def test_committed_assets_match_generator() -> None:
    assert U.URDF_PATH.read_text() == U.urdf_text(False)
    assert U.SRDF_PATH.read_text() == U.srdf_text(False)
    assert U.ARM_URDF_PATH.read_text() == U.urdf_text(True)
    assert U.ARM_SRDF_PATH.read_text() == U.srdf_text(True)


def test_joint_limits_follow_fetch() -> None:
    _, robot = make_robot()
    limits = robot.articulation.get_qlimits()
    for name, (lo, hi) in U.ARM_LIMITS.items():
        got = limits[robot.joint_index[name]]
        assert got[0] == pytest.approx(lo, abs=1e-5) and got[1] == pytest.approx(hi, abs=1e-5), name
    torso = limits[robot.joint_index[U.TORSO_JOINT]]
    assert torso[0] == pytest.approx(0.0) and torso[1] == pytest.approx(0.386, abs=1e-6)
    for name in U.FINGER_JOINTS:
        assert limits[robot.joint_index[name]][1] == pytest.approx(0.05, abs=1e-6)
    assert U.ARM_LIMITS["shoulder_pan_joint"][1] == pytest.approx(1.6056)
    assert U.ARM_LIMITS["elbow_flex_joint"][1] == pytest.approx(2.251)


def test_srdf_disables_every_adjacent_pair() -> None:
    root = ET.fromstring(U.ARM_URDF_PATH.read_text())
    adjacent = {frozenset((j.find("parent").get("link"), j.find("child").get("link"))) for j in root.findall("joint")}
    srdf = ET.fromstring(U.ARM_SRDF_PATH.read_text())
    disabled = {frozenset((d.get("link1"), d.get("link2"))) for d in srdf.findall("disable_collisions")}
    assert adjacent <= disabled
    # the planning variant has no continuous joint (mplib refuses them)
    assert all(j.get("type") != "continuous" for j in root.findall("joint"))


def test_base_footprint_and_head_camera_height() -> None:
    _, robot = make_robot()
    base = robot.links["base_link"]
    lo, hi = base.compute_global_aabb_tight()
    assert (hi[0] - lo[0]) / 2.0 == pytest.approx(U.BASE_RADIUS, abs=0.005)
    (x, y, z), yaw = robot.ear_pose()
    assert 1.0 <= z <= 1.15  # head camera at about 1.06 m with the torso down
    # the tucked arm stays inside the base footprint (drive with it)
    for name in ("shoulder_lift_link", "elbow_flex_link", "wrist_flex_link", "wrist_roll_link", U.EE_LINK):
        lo, hi = robot.links[name].compute_global_aabb_tight()
        corners = [(a, b) for a in (lo[0], hi[0]) for b in (lo[1], hi[1])]
        assert max(math.hypot(a, b) for a, b in corners) <= U.BASE_RADIUS + 0.02, name


def test_state_layout_and_base_velocity_tracking() -> None:
    scene, robot = make_robot((1.0, 2.0, math.pi / 2))
    st = robot.state()
    assert st.shape == (STATE_DIM,) and st.dtype == np.float32 and len(STATE_NAMES) == STATE_DIM
    assert st[0:3] == pytest.approx([1.0, 2.0, math.pi / 2], abs=1e-5)
    assert st[4:11] == pytest.approx(TUCK_QPOS, abs=1e-5)
    assert st[11] == pytest.approx(GRIPPER_OPEN, abs=1e-5)
    a = robot.rest_action()
    assert a.shape == (ACTION_DIM,)
    a[0] = 0.4  # forward in the robot frame = +y in the world at yaw pi/2
    run(scene, robot, a, 20)  # 2 s
    st = robot.state()
    assert st[12] == pytest.approx(0.4, abs=0.01)  # robot-frame vx
    assert abs(st[13]) < 0.01
    assert st[1] - 2.0 == pytest.approx(0.8, abs=0.02)
    assert abs(st[0] - 1.0) < 0.01
    a = robot.rest_action()
    a[2] = 0.5
    run(scene, robot, a, 10)
    st = robot.state()
    assert st[14] == pytest.approx(0.5, abs=0.01)
    assert st[2] == pytest.approx(math.pi / 2 + 0.5, abs=0.03)


def test_position_targets_are_tracked() -> None:
    scene, robot = make_robot()
    a = robot.rest_action()
    a[3] = 0.3
    a[4:11] = [0.2, -0.3, 0.4, 1.0, 0.0, 0.5, -0.2]
    a[11] = 0.06
    run(scene, robot, a, 15)
    st = robot.state()
    assert st[3] == pytest.approx(0.3, abs=0.005)
    assert st[4:11] == pytest.approx(a[4:11], abs=0.01)
    assert st[11] == pytest.approx(0.06, abs=0.002)
    assert robot.holding is None and st[24] == 0.0


def test_same_actions_give_identical_states() -> None:
    rng = np.random.default_rng(7)
    actions = []
    for _ in range(12):
        a = np.zeros(ACTION_DIM, dtype=np.float32)
        a[:3] = rng.uniform(-0.3, 0.3, 3)
        a[3] = rng.uniform(0.0, 0.3)
        a[4:11] = TUCK_QPOS + rng.uniform(-0.2, 0.2, 7)
        a[11] = rng.uniform(0.0, 0.1)
        actions.append(a)

    def rollout() -> bytes:
        scene, robot = make_robot((0.5, -0.5, 0.3))
        out = []
        for a in actions:
            run(scene, robot, a, 1)
            out.append(robot.state().tobytes())
        return b"".join(out)

    first, second = rollout(), rollout()
    assert first == second
    assert len(set(first[i : i + 100] for i in range(0, len(first), 100))) > 1  # the robot moved
