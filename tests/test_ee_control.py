"""The end-effector action map (echo_data.robot.ee_control) and the closed-loop servo on the real robot.

Checks: forward kinematics agrees with SAPIEN's own link poses; a zero change holds the joint
targets bit for bit; a commanded TCP change arrives (rigid-body kinematics: FK(IK(T)) = T); the
joint form's end-effector twin inverts the map; a straight Cartesian move out of the tuck reaches
READY (the joint-limit and posture handling); the servo drives the measured TCP to a goal under
physics and corrects a perturbation of the commanded pose.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import sapien

from echo_data.recipe import load_recipe
from echo_data.records import EE_ACTION_DIM
from echo_data.robot.ee_control import world_to_base
from echo_data.robot.robot import READY_GROUP, TUCK_QPOS, Robot
from echo_data.skills import servo as S

RECIPE = Path(__file__).resolve().parents[1] / "recipes" / "quickstart.yaml"


def _robot(arm: np.ndarray, base: tuple[float, float, float] = (1.0, -0.5, 0.7)) -> tuple[Robot, sapien.Scene]:
    recipe = load_recipe(RECIPE)
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(1.0 / recipe.robot.physics_hz)
    robot = Robot(scene, recipe.robot)
    robot.set_base_pose(*base)
    a = robot.rest_action()
    a[3] = READY_GROUP[0]
    a[4:11] = arm
    robot.apply(a)
    _physics(robot, scene, 60)
    return robot, scene


def _physics(robot: Robot, scene: sapien.Scene, control_steps: int) -> None:
    for _ in range(control_steps * robot.cfg.physics_hz // robot.cfg.control_hz):
        robot.before_substep()
        scene.step()


def _ee(torso: float, delta: tuple[float, ...] = (0.0,) * 6, close: float = 0.0) -> np.ndarray:
    a = np.zeros(EE_ACTION_DIM, dtype=np.float32)
    a[3] = torso
    a[4:10] = delta
    a[10] = close
    return a


def test_forward_kinematics_matches_sapien_links() -> None:
    robot, _ = _robot(READY_GROUP[1:])
    measured = world_to_base(robot.ee_pose().to_transformation_matrix(), robot.base_pose())
    q = np.concatenate([[robot.torso()], robot.arm_qpos()])
    fk = robot.ee.tcp_in_base(float(q[0]), q[1:])
    assert np.allclose(fk[:3, 3], measured[:3, 3], atol=1e-4)
    assert np.allclose(fk[:3, :3], measured[:3, :3], atol=1e-4)


def test_zero_change_holds_exactly_and_gripper_is_binary() -> None:
    robot, _ = _robot(READY_GROUP[1:])
    held = robot.applied_action()
    j = robot.ee.to_joint(_ee(float(held[3])))
    assert j.dtype == np.float32 and np.array_equal(j, held)
    assert robot.ee.to_joint(_ee(float(held[3]), close=1.0))[11] == 0.0
    assert robot.ee.to_joint(_ee(float(held[3]), close=0.0))[11] == pytest.approx(0.1)


@pytest.mark.parametrize("delta", [(0.02, 0.0, 0.0, 0.0, 0.0, 0.0), (0.0, 0.03, -0.02, 0.0, 0.0, 0.1), (-0.01, 0.01, 0.01, 0.05, -0.05, 0.0)])
def test_commanded_change_arrives_and_inverts(delta: tuple[float, ...]) -> None:
    robot, _ = _robot(READY_GROUP[1:])
    ref = robot.applied_action()
    before = robot.ee.tcp_in_base(float(ref[3]), ref[4:11].astype(np.float64))
    j = robot.ee.to_joint(_ee(float(ref[3]), delta))
    after = robot.ee.tcp_in_base(float(j[3]), j[4:11].astype(np.float64))
    assert np.allclose(after[:3, 3] - before[:3, 3], delta[:3], atol=5e-4)  # float32 joint targets: ~1e-7 rad each
    back = robot.ee.to_ee(j, reference=ref)
    assert np.allclose(back[4:10], delta, atol=2e-3)
    assert back[10] == 0.0


def test_straight_move_out_of_the_tuck_reaches_ready() -> None:
    """Without joint limits and a posture in the IK this move ends 6 cm short, pressed on the wrist limit."""
    robot, _ = _robot(TUCK_QPOS)
    goal = robot.ee.tcp_in_base(float(READY_GROUP[0]), READY_GROUP[1:])
    ref = robot.applied_action()
    for _ in range(60):
        d = robot.ee.delta_towards(goal)
        a = _ee(float(READY_GROUP[0]), S.step_towards(d, 0.25, 1.0, 0.1))
        j = robot.ee.to_joint(a, reference=ref)
        assert float(np.max(np.abs(j[4:11] - ref[4:11]))) < 0.25  # no joint jumps between control steps
        robot.apply(j)
        ref = robot.applied_action()
    final = robot.ee.tcp_in_base(float(ref[3]), ref[4:11].astype(np.float64))
    assert np.linalg.norm(final[:3, 3] - goal[:3, 3]) < 2e-3


def test_servo_reaches_a_goal_under_physics_and_corrects_a_perturbation() -> None:
    robot, scene = _robot(READY_GROUP[1:])
    world = SimpleNamespace(robot=robot)
    goal = robot.ee_pose().to_transformation_matrix()
    goal[:3, 3] += (0.10, -0.05, -0.08)
    gen = S.servo(world, goal, max_steps=80)  # type: ignore[arg-type]
    perturbed = False
    steps = 0
    try:
        while True:
            a = next(gen)
            if steps == 5 and not perturbed:  # knock the commanded TCP 3 cm sideways: the next labels must undo it
                a = a.copy()
                a[5] += 0.03
                perturbed = True
            robot.apply(robot.ee.to_joint(a))
            _physics(robot, scene, 1)
            steps += 1
    except StopIteration as stop:
        assert stop.value is True
    assert perturbed
    assert np.linalg.norm(robot.ee_pose().p - goal[:3, 3]) < S.SETTLE_TOL


def _servo_under_perturbation(seed: int, sigma_m: float, sigma_rad: float, max_steps: int) -> tuple[bool, float]:
    """Run the servo with DART-style noise (agents/dart.py: on every step that moves the hand);
    returns whether it reported arrival and the measured TCP's distance to the goal then."""
    robot, scene = _robot(READY_GROUP[1:])
    world = SimpleNamespace(robot=robot)
    goal = robot.ee_pose().to_transformation_matrix()
    goal[:3, 3] += (0.06, -0.04, -0.05)
    rng = np.random.default_rng(seed)
    gen = S.servo(world, goal, speed=S.SLOW_SPEED, max_steps=max_steps)  # type: ignore[arg-type]
    try:
        while True:
            a = next(gen).copy()
            if np.any(a[4:10] != 0.0):
                a[4:7] += rng.normal(0.0, sigma_m, 3)
                a[7:10] += rng.normal(0.0, sigma_rad, 3)
            robot.apply(robot.ee.to_joint(a))
            _physics(robot, scene, 1)
    except StopIteration as stop:
        arrived = bool(stop.value)
    return arrived, float(np.linalg.norm(robot.ee_pose().p - goal[:3, 3]))


def test_servo_arrives_under_a_per_step_perturbation() -> None:
    # 0.5 cm / 1 deg per step (the sanity recipe's level): every aimed step lands ~0.9 cm off. The
    # servo accepts what an aimed step leaves within AIMED_POS_TOL (it re-aimed until max_steps
    # when it demanded POS_TOL, 4 mm: Pick 3 of 10). Ten stretches of 8.8 cm, 40 steps each (the
    # clean servo needs ~17 at 6 cm/s).
    results = [_servo_under_perturbation(seed, 0.005, np.radians(1.0), 40) for seed in range(10)]
    assert all(ok for ok, _ in results), results
    assert all(dist <= S.AIMED_POS_TOL + 0.005 for _, dist in results), results
    # and without noise it still ends within the strict tolerance
    ok, dist = _servo_under_perturbation(0, 0.0, 0.0, 40)
    assert ok and dist < S.SETTLE_TOL
