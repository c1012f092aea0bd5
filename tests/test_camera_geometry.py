"""Depth -> world points with the stored intrinsics and camera poses land on known geometry."""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.camera import depth_to_world, intrinsics
from echo_data.recipe import CameraConfig, RobotConfig
from echo_data.robot.robot import POSITION_PICTURE, Robot
from echo_data.world import keep_render_alive

HALF = np.array([0.10, 0.15, 0.05])  # box half extents (m)


def test_box_depth_pixels_land_on_the_box() -> None:
    keep_render_alive()
    scene = sapien.Scene()
    scene.set_timestep(0.01)
    scene.set_ambient_light([0.6, 0.6, 0.6])
    yaw = 0.4
    base = np.array([0.3, -0.2])
    centre = np.array([*(base + 1.1 * np.array([math.cos(yaw), math.sin(yaw)])), HALF[2]])
    b = scene.create_actor_builder()
    b.add_box_visual(half_size=HALF.tolist())
    b.set_initial_pose(sapien.Pose(centre.tolist(), [math.cos(0.3), 0.0, 0.0, math.sin(0.3)]))  # turned 0.6 rad
    box = b.build_static(name="box")
    cam_cfg = CameraConfig(width=64, height=48, fov_deg=60.0)
    robot = Robot(scene, RobotConfig(head_camera=cam_cfg, wrist_camera=CameraConfig(width=16, height=16, rgb=False)))
    robot.set_base_pose(float(base[0]), float(base[1]), yaw)
    scene.step()
    depth = robot.observe()["head_depth"]
    pose = robot.camera_poses()["head"]
    cam = robot.cameras["head"][0]
    np.testing.assert_allclose(intrinsics(64, 48, 60.0), cam.get_intrinsic_matrix(), rtol=1e-5)  # our K is SAPIEN's
    mask = cam.get_picture(POSITION_PICTURE)[..., 3] == box.per_scene_id
    assert mask.sum() > 30
    pts = depth_to_world(depth, intrinsics(64, 48, 60.0), pose.reshape(-1))[mask]
    # into the box frame: every pixel of the box must lie on its surface, within 2 cm
    r = box.pose.to_transformation_matrix()[:3, :3]
    local = (pts - centre) @ r
    assert np.all(np.abs(local) <= HALF + 0.02)
    to_face = np.min(HALF - np.abs(local), axis=1)
    assert np.all(np.abs(to_face) <= 0.02)
    top = local[:, 2] > HALF[2] - 0.02  # the head looks down on it: the top face is seen
    assert top.sum() > 10 and np.abs(local[top, 2] - HALF[2]).max() <= 0.02
