"""How much of the head camera's view the arm and a held object cover in a carry pose.

    python benchmarks/carry_view.py                       # READY and Place's CARRY_DRIVE_GROUP
    python benchmarks/carry_view.py --group 0.386,1.098,-1.09,-1.187,-1.864,-0.446,-1.48,-0.003

Renders the head camera (the recipe default: 128 x 128, 70 deg, tilted HEAD_TILT) of the robot
alone on a floor with the torso and arm at each group (torso, 7 arm joints) and a furby-sized box
(the largest target) hanging from the pads, and prints the share of pixels whose segmentation
id is a robot link or the box, the TCP in the base frame, and the largest horizontal distance of
an arm link origin from the base axis (what a turn in place sweeps).
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import sapien

from echo_data.recipe import Recipe
from echo_data.robot.robot import POSITION_PICTURE, Robot
from echo_data.scene.objects import object_size
from echo_data.skills import arm
from echo_data.skills.place import CARRY_DRIVE_GROUP

ARM_LINKS = ("shoulder_lift_link", "upperarm_roll_link", "elbow_flex_link", "forearm_roll_link", "wrist_flex_link", "wrist_roll_link", "gripper_link")
GRASP_BELOW_TOP = 0.03  # echo_data.skills.pick: the pads hold an object this far below its top


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--group", action="append", default=[], help="torso and 7 arm joints, comma-separated")
    a = ap.parse_args()
    groups = {"READY": arm.READY_GROUP, "CARRY_DRIVE": CARRY_DRIVE_GROUP}
    groups.update({f"group{i}": np.array([float(v) for v in g.split(",")]) for i, g in enumerate(a.group)})
    scene = sapien.Scene()
    scene.add_ground(0.0)
    robot = Robot(scene, Recipe(name="carry_view").robot)
    sx, sy, sz = object_size("furby")
    b = scene.create_actor_builder()
    b.add_box_visual(half_size=[sx / 2, sy / 2, sz / 2])
    held = b.build_kinematic(name="held")
    ids = list({ln.entity.per_scene_id for ln in robot.articulation.links} | {held.per_scene_id})
    comp, _ = robot.cameras["head"]
    for name, g in groups.items():
        q = robot.articulation.get_qpos()
        q[robot.torso_index] = g[0]
        q[robot.arm_indices] = g[1:]
        robot.articulation.set_qpos(q)
        tcp = robot.ee_pose()
        held.set_pose(sapien.Pose(np.asarray(tcp.p) + [0.0, 0.0, GRASP_BELOW_TOP - sz / 2]))
        scene.update_render()
        comp.take_picture()
        covered = float(np.isin(comp.get_picture(POSITION_PICTURE)[..., 3], ids).mean())
        reach = max(math.hypot(*robot.links[n].entity_pose.p[:2]) for n in ARM_LINKS)
        print(f"{name:12s} head view covered {covered:6.1%}  TCP {np.round(tcp.p, 3).tolist()}  arm reach {reach:.3f} m")


if __name__ == "__main__":
    main()
