"""How much of the head camera's view the arm and a held object cover in a given arm configuration.

Why: a carry pose must leave the head camera clear so that Place (and a policy learned from the
head view) can see where it goes. Used by tests/test_carry_pose.py and the carry-search study.
The robot stands alone on a floor; each object category's collision box hangs from the pads as
Pick holds it (top GRASP_BELOW_TOP above the pads, yawed with the jaws). It lives with the skills
because it measures their carry pose with their grasp (`skills.pick`, `skills.arm`).
"""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.recipe import Recipe
from echo_data.robot.robot import POSITION_PICTURE, Robot
from echo_data.scene.objects import CATEGORIES, object_size

# Links that move with the arm (a turn in place sweeps a circle of the farthest one's radius).
ARM_LINKS = (
    "shoulder_lift_link",
    "upperarm_roll_link",
    "elbow_flex_link",
    "forearm_roll_link",
    "wrist_flex_link",
    "wrist_roll_link",
    "gripper_link",
)


def set_group(robot: Robot, group: np.ndarray) -> sapien.Pose:
    """Put the torso and arm at `group` (torso, 7 arm joints); returns the TCP pose."""
    q = robot.articulation.get_qpos()
    q[robot.torso_index] = group[0]
    q[robot.arm_indices] = group[1:]
    robot.articulation.set_qpos(q)
    return robot.ee_pose()


def arm_reach(robot: Robot) -> float:
    """Largest horizontal distance of an arm link origin from the base axis (m)."""
    return max(math.hypot(*robot.links[n].entity_pose.p[:2]) for n in ARM_LINKS)


class HeadView:
    """A rendered robot on a floor with one box per object category to hold."""

    def __init__(self) -> None:
        from echo_data.skills.pick import GRASP_BELOW_TOP

        self.below_top = GRASP_BELOW_TOP
        self.scene = sapien.Scene()
        self.scene.add_ground(0.0)
        self.robot = Robot(self.scene, Recipe(name="head_view").robot)
        self.camera, _ = self.robot.cameras["head"]
        self.robot_ids = {ln.entity.per_scene_id for ln in self.robot.articulation.links}
        self.held: dict[str, sapien.Entity] = {}
        for c in CATEGORIES:
            b = self.scene.create_actor_builder()
            b.add_box_visual(half_size=[v / 2 for v in object_size(c)])
            self.held[c] = b.build_kinematic(name=c)
            self.held[c].set_pose(sapien.Pose([0.0, 0.0, -10.0]))

    def covered(self, group: np.ndarray, category: str) -> float:
        """Share of head pixels showing a robot link or the held `category` box at `group`."""
        from echo_data.skills.arm import jaw_yaw

        tcp = set_group(self.robot, group)
        yaw = jaw_yaw(tcp)
        box = self.held[category]
        drop = self.below_top - object_size(category)[2] / 2
        box.set_pose(sapien.Pose(np.asarray(tcp.p) + [0.0, 0.0, drop], [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]))
        self.scene.update_render()
        self.camera.take_picture()
        ids = list(self.robot_ids | {box.per_scene_id})
        share = float(np.isin(self.camera.get_picture(POSITION_PICTURE)[..., 3], ids).mean())
        box.set_pose(sapien.Pose([0.0, 0.0, -10.0]))
        return share


__all__ = ["ARM_LINKS", "HeadView", "arm_reach", "set_group"]
