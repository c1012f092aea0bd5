"""Robot cameras (rendered on the CPU): image layout and metric depth against known geometry."""

from __future__ import annotations

import numpy as np
import pytest
import sapien

from echo_data.recipe import CameraConfig, RobotConfig
from echo_data.robot.robot import Robot
from echo_data.world import keep_render_alive

WALL_X = 2.5


def test_head_rgb_depth_and_wrist_depth() -> None:
    keep_render_alive()
    scene = sapien.Scene()
    scene.set_timestep(0.01)
    scene.set_ambient_light([0.6, 0.6, 0.6])
    builder = scene.create_actor_builder()
    builder.add_box_collision(half_size=[0.05, 3.0, 2.0])
    builder.add_box_visual(half_size=[0.05, 3.0, 2.0], material=[0.9, 0.1, 0.1])
    builder.set_initial_pose(sapien.Pose([WALL_X + 0.05, 0.0, 2.0]))
    builder.build_static(name="wall")
    cfg = RobotConfig(head_camera=CameraConfig(width=32, height=24, fov_deg=60.0), wrist_camera=CameraConfig(width=16, height=16, rgb=False))
    robot = Robot(scene, cfg)
    robot.set_base_pose(0.0, 0.0, 0.0)
    scene.step()
    obs = robot.observe()
    assert set(obs) == {"head_rgb", "head_depth", "wrist_depth"}
    assert obs["head_rgb"].shape == (24, 32, 3) and obs["head_rgb"].dtype == np.uint8
    assert obs["head_depth"].shape == (24, 32) and obs["head_depth"].dtype == np.uint16
    assert obs["wrist_depth"].shape == (16, 16) and obs["wrist_depth"].dtype == np.uint16
    # the upper half of the head image sees the red wall (the head looks slightly down)
    top = obs["head_rgb"][2:8, 12:20].astype(int)
    assert np.all(top[..., 0] > top[..., 1] + 40)
    # depth is metric along the optical axis: plane x = WALL_X seen from the camera pose
    cam = robot.cameras["head"][0]
    pose = cam.global_pose
    # pixel row 4 (upper part, wall) in the central columns: ray through that pixel
    k = cam.get_intrinsic_matrix()
    depth = obs["head_depth"][4, 15:17].astype(float).mean() / 1000.0
    u, v = 16.0, 4.5
    ray_cam = np.array([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], 1.0])  # OpenCV camera frame
    # SAPIEN camera frame: x forward, y left, z up  <- OpenCV (x right, y down, z forward)
    r = pose.to_transformation_matrix()[:3, :3]
    ray_world = r @ np.array([ray_cam[2], -ray_cam[0], -ray_cam[1]])
    t = (WALL_X - pose.p[0]) / ray_world[0]  # along the ray with unit optical-axis component
    assert depth == pytest.approx(t, rel=0.02)
