"""DART-style perturbation of the scripted experts (`experts.perturbation`, in end-effector
space; `experts.action_noise` is the joint-space form, whose gating rule is checked here too;
echo_data/agents/dart.py).

With a perturbation the label (`action.ee`, the expert's own command) differs from what the robot
executed by exactly the noise drawn from the episode's stream, only where the noise is allowed;
the expert corrects from the perturbed state (its holds do not drift with the noise) and still
succeeds. Bit-for-bit replay from the executed actions is in tests/test_env_replay.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from echo_data.agents.dart import EePerturbation, noise_mask
from echo_data.recipe import Perturbation, load_recipe
from echo_data.records import ACTION_DIM
from echo_data.robot.robot import GRIPPER_OPEN

ROOT = Path(__file__).resolve().parents[1]


def test_mask_follows_the_documented_rules() -> None:
    driving = np.zeros(ACTION_DIM, np.float32)
    driving[0], driving[11] = 0.3, GRIPPER_OPEN
    standing_closed = np.zeros(ACTION_DIM, np.float32)
    m = noise_mask(driving, quiet=False)
    assert m.all()  # base commanded, gripper open: every element may be perturbed
    m = noise_mask(standing_closed, quiet=False)
    assert not m[:3].any() and not m[11] and m[3:11].all()  # base standing, gripper closed: arm and torso only
    assert not noise_mask(driving, quiet=True).any()


@pytest.fixture(scope="module")
def noisy_rollout() -> tuple:
    from echo_data.app.pipeline import simulate
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary

    base = load_recipe(ROOT / "recipes" / "object_relocation.yaml")
    experts = base.experts.model_copy(update={"perturbation": Perturbation(position_cm=0.1, rotation_deg=0.2)})
    recipe = base.model_copy(update={"experts": experts})
    spec, _ = sample_episode(recipe, "train", 0, SoundLibrary.from_recipe(recipe))
    return spec, recipe, simulate(spec, recipe, observe=False)


@pytest.mark.slow
def test_label_and_executed_differ_by_the_drawn_noise(noisy_rollout: tuple) -> None:
    """Every expert computes its command in end-effector form (skills/servo): each step's executed
    `action.ee` is its label plus exactly the perturbation drawn from the episode's stream where
    the gate allows it (agents/dart.EePerturbation), and the expert still succeeds."""
    spec, recipe, ro = noisy_rollout
    assert ro.success, [(o.skill, o.reason) for o in ro.outcomes]  # the expert recovers from its perturbations
    ee = EePerturbation(recipe.experts.perturbation, recipe.robot.control_hz, spec.seed)
    perturbed = 0
    for s in ro.steps:
        assert s.action_ee is not None
        assert np.array_equal(s.action_ee_executed, s.action_ee + ee(s.action_ee)), f"frame {s.frame_index}"
        perturbed += bool(np.any(s.action_ee_executed != s.action_ee))
    assert perturbed > 0.3 * len(ro.steps)


@pytest.mark.slow
def test_the_expert_corrects_rather_than_drifts(noisy_rollout: tuple) -> None:
    """The label is the expert's command from the perturbed state, never the perturbed command
    copied: after a perturbed step the next label differs from what was executed. While Navigate
    drives, its labels hold the torso and the arm exactly (a zero TCP change; the perturbation
    only touches what the expert moves: there, the base)."""
    spec, _recipe, ro = noisy_rollout
    labels = np.stack([s.action_ee for s in ro.steps])
    executed = np.stack([s.action_ee_executed for s in ro.steps])
    noisy = np.any(executed != labels, axis=1)[:-1]
    copied = np.all(labels[1:] == executed[:-1], axis=1) & noisy
    assert noisy.any() and not copied.any()  # never took the perturbed command as its own
    nav = [i for i, s in enumerate(ro.steps) if s.skill == "Navigate"]
    joint = np.stack([s.action for s in ro.steps])
    assert len(nav) > 20 and np.all(joint[nav, 3:11] == joint[nav[0], 3:11])  # torso and arm held exactly
    assert np.mean(np.any(executed[nav, :3] != labels[nav, :3], axis=1)) > 0.3  # the base was perturbed
