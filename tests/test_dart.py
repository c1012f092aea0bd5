"""DART noise on the scripted experts (`experts.action_noise`, echo_data/agents/dart.py).

With noise the label (`action`, the expert's own command) differs from what the robot executed
by exactly the noise drawn from the episode's stream, only where the noise is allowed; the
expert corrects from the perturbed state (its holds do not drift with the noise) and still
succeeds. Bit-for-bit replay from the executed actions is in tests/test_env_replay.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from echo_data.agents.dart import NOISE_STD, QUIET_STEPS, noise_mask
from echo_data.recipe import load_recipe
from echo_data.records import ACTION_DIM
from echo_data.robot.robot import GRIPPER_OPEN
from echo_data.seeds import ACTION_NOISE, derived_rng

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
    recipe = base.model_copy(update={"experts": base.experts.model_copy(update={"action_noise": 1.0})})
    spec, _ = sample_episode(recipe, "train", 0, SoundLibrary.from_recipe(recipe))
    return spec, simulate(spec, recipe, observe=False)


@pytest.mark.slow
def test_label_and_executed_differ_by_the_drawn_noise(noisy_rollout: tuple) -> None:
    spec, ro = noisy_rollout
    assert ro.success, [(o.skill, o.reason) for o in ro.outcomes]  # the expert recovers from its perturbations
    rng = derived_rng(ACTION_NOISE, spec.seed)
    quiet, grip = 0, None
    perturbed = 0
    for s in ro.steps:
        label, executed = s.action, s.action_executed
        draw = rng.standard_normal(ACTION_DIM) * NOISE_STD
        if grip is not None and label[11] != grip:
            quiet = QUIET_STEPS
        grip = float(label[11])
        noise = np.where(noise_mask(label, quiet > 0), draw, 0.0).astype(np.float32)
        quiet = max(quiet - 1, 0)
        assert np.array_equal(executed, label + noise), f"frame {s.frame_index}"
        perturbed += bool(np.any(noise != 0))
    assert perturbed > 0.5 * len(ro.steps)


@pytest.mark.slow
def test_the_expert_corrects_rather_than_drifts(noisy_rollout: tuple) -> None:
    """Holding still, the expert commands the same targets step after step (its own, not the
    noisy ones it executed), so the noise does not add up into a random walk of the arm."""
    _, ro = noisy_rollout
    labels = np.stack([s.action for s in ro.steps])[:, 3:11]
    executed = np.stack([s.action_executed for s in ro.steps])[:, 3:11]
    noisy = np.any(executed != labels, axis=1)[:-1]
    held = np.all(labels[1:] == labels[:-1], axis=1) & noisy
    assert held.sum() > 20  # the expert held its arm targets through many perturbed steps
    copied = np.all(labels[1:] == executed[:-1], axis=1) & noisy
    assert not copied.any()  # and never took the perturbed target as its own
