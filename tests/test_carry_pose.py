"""The carry pose (Pick ends in it, Place drives in it) keeps the head camera's view clear and sweeps little."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sapien

from echo_data.recipe import Recipe
from echo_data.robot.planner import ArmPlanner
from echo_data.robot.robot import HEAD_TILT, POSITION_PICTURE, Robot
from echo_data.scene.objects import object_size
from echo_data.skills import arm
from echo_data.skills.success import CARRY_TCP

ARM_LINKS = ("shoulder_lift_link", "upperarm_roll_link", "elbow_flex_link", "forearm_roll_link", "wrist_flex_link", "wrist_roll_link", "gripper_link")
GRASP_BELOW_TOP = 0.03  # echo_data.skills.pick: the pads hold an object this far below its top


def _pose(robot: Robot, group: np.ndarray) -> tuple[float, sapien.Pose]:
    q = robot.articulation.get_qpos()
    q[robot.torso_index] = group[0]
    q[robot.arm_indices] = group[1:]
    robot.articulation.set_qpos(q)
    reach = max(math.hypot(*robot.links[n].entity_pose.p[:2]) for n in ARM_LINKS)
    return reach, robot.ee_pose()


@pytest.fixture(scope="module")
def rendered() -> tuple[sapien.Scene, Robot]:
    scene = sapien.Scene()
    scene.add_ground(0.0)
    return scene, Robot(scene, Recipe(name="t").robot)


def _covered(scene: sapien.Scene, robot: Robot, held: sapien.Entity) -> float:
    """Share of the head camera's pixels showing a robot link or the held object (segmentation ids)."""
    ids = {ln.entity.per_scene_id for ln in robot.articulation.links} | {held.per_scene_id}
    scene.update_render()
    comp, _ = robot.cameras["head"]
    comp.take_picture()
    seg = comp.get_picture(POSITION_PICTURE)[..., 3]
    return float(np.isin(seg, list(ids)).mean())


@pytest.mark.parametrize("category, turn", [("furby", 0.0), ("alarm", 0.0), ("phone", 0.0), ("phone", math.pi / 2)])
def test_carry_keeps_the_head_view_clear(rendered: tuple[sapien.Scene, Robot], category: str, turn: float) -> None:
    scene, robot = rendered
    sx, sy, sz = object_size(category)
    b = scene.create_actor_builder()
    b.add_box_visual(half_size=[sx / 2, sy / 2, sz / 2])
    held = b.build_kinematic(name=f"held_{category}")
    try:
        for group, bound in ((arm.READY_GROUP, (0.5, 1.0)), (arm.CARRY_GROUP, (0.0, 0.01))):
            _, tcp = _pose(robot, group)
            # hanging from the pads GRASP_BELOW_TOP under its top, long side along or across the jaws
            centre = np.asarray(tcp.p) + [0.0, 0.0, GRASP_BELOW_TOP - sz / 2]
            held.set_pose(sapien.Pose(centre, [math.cos(turn / 2), 0.0, 0.0, math.sin(turn / 2)]))
            covered = _covered(scene, robot, held)
            # READY (the old carry) fills most of the view; CARRY leaves it clear
            assert bound[0] <= covered <= bound[1], (category, turn, group.tolist(), covered)
    finally:
        scene.remove_entity(held)


def test_carry_pose_is_compact_and_reached_with_an_object_in_hand() -> None:
    robot = Robot(sapien.Scene([sapien.physx.PhysxCpuSystem()]), Recipe(name="t").robot)
    ready_reach, _ = _pose(robot, arm.READY_GROUP)
    carry_reach, carry_tcp = _pose(robot, arm.CARRY_GROUP)
    assert np.allclose(carry_tcp.p, CARRY_TCP, atol=0.005)  # the success test's carry point is this pose's TCP
    assert abs(float(carry_tcp.to_transformation_matrix()[2, 0]) + 1.0) < 1e-3  # pointing down: the object hangs straight
    # a turn in place sweeps a circle of the farthest link's radius: inside the nav grid's 0.32 m robot radius
    assert carry_reach <= 0.31 < 0.45 <= ready_reach
    planner = ArmPlanner(seed=0)
    planner.sync((0.0, 0.0, 0.0), arm.READY_GROUP, 0.0, (0.0, HEAD_TILT))
    planner.set_obstacles([])
    for category in ("phone", "alarm", "furby"):
        sx, sy, sz = object_size(category)
        # TCP frame: x = approach (down), y = finger travel (across the object's width)
        planner.attach_box([sz, sy, sx], sapien.Pose([sz / 2 - GRASP_BELOW_TOP, 0.0, 0.0]))
        assert not planner.collisions(arm.CARRY_GROUP.copy()), category
        assert planner.path(arm.READY_GROUP.copy(), arm.CARRY_GROUP.copy()) is not None, category
        planner.detach()
