"""The environment speaks gymnasium: registered ids, the env checker, reset semantics, bad arguments."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from support.recipes import tiny_recipe

import echo_data.envs  # noqa: F401  (registers the ids)
from echo_data.envs import EchoDataEnv, EnvInputError

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("env_id, setting", [
    ("EchoData/ObjectRelocation-v0", "object_relocation"),
    ("EchoData/StateTransition-v0", "state_transition"),
    ("EchoData/MultiEvent-v0", "multi_event"),
])
def test_registered_ids_make_the_setting(env_id: str, setting: str) -> None:
    env = gym.make(env_id)
    assert env.unwrapped.recipe.setting == setting
    assert env.action_space.shape == (12,)
    assert "observation.audio.spectrogram" in env.observation_space.spaces
    env.close()


@pytest.mark.slow
def test_check_env_passes() -> None:
    from gymnasium.utils.env_checker import check_env

    env = EchoDataEnv(tiny_recipe(), split="test")
    check_env(env, skip_render_check=True)
    env.close()


def test_reset_to_an_index_and_to_a_fresh_seed() -> None:
    env = EchoDataEnv(tiny_recipe(), split="test", images=False, audio=False)
    _, info = env.reset(options={"split": "test", "index": 1})
    assert info["episode_id"] == "test-000001" and info["spec"]["index"] == 1
    assert info["active_skill"] == info["skills"][0]["skill"] and all(ev["sounding"] for ev in info["events"])
    _, a = env.reset(seed=5)
    _, b = env.reset(seed=5)
    _, c = env.reset(seed=6)
    assert a["spec"] == b["spec"] and a["spec"] != c["spec"]
    with pytest.raises(EnvInputError, match="index: 3 is outside the test split"):
        env.reset(options={"index": 3})
    with pytest.raises(EnvInputError, match=r"expected shape \(12,\)"):
        env.step(np.zeros(3, np.float32))
    obs, _, terminated, _, info = env.step(np.full(12, np.nan, np.float32))
    assert terminated and "non-finite action" in info["failure"]
    env.close()
