"""Several environments in several processes: `gymnasium.make_vec(..., vectorization_mode="async")`
steps two `EchoDataEnv`s, each in its own process, with every observation (cameras and audio)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from support.recipes import tiny_recipe

import echo_data.envs  # noqa: F401  (registers the ids)
from echo_data.envs.env import BINAURAL, SPECTROGRAM


def test_async_vector_env_over_two_processes() -> None:
    recipe = tiny_recipe()
    envs = gym.make_vec(
        "EchoData/ObjectRelocation-v0", num_envs=2, vectorization_mode="async",
        vector_kwargs={"context": "spawn"}, recipe=recipe, split="test",
    )
    try:
        obs, info = envs.reset(seed=[3, 4])
        assert obs[SPECTROGRAM].shape == (2, *envs.single_observation_space[SPECTROGRAM].shape)
        assert len(set(info["spec"]["seed"])) == 2  # two episodes
        procs = envs.unwrapped.processes
        assert len({p.pid for p in procs}) == 2 and all(p.is_alive() for p in procs)  # each env in its own process
        rng = np.random.default_rng(0)
        low, high = envs.single_action_space.low, envs.single_action_space.high
        for _ in range(3):
            obs, reward, terminated, truncated, info = envs.step(rng.uniform(low, high, (2, len(low))).astype(np.float32))
        assert obs[BINAURAL].shape == (2, *envs.single_observation_space[BINAURAL].shape)
        assert np.abs(obs[BINAURAL]).max() > 0  # both hear their room
        for col, space in envs.single_observation_space.spaces.items():
            assert obs[col].shape == (2, *space.shape) and obs[col].dtype == space.dtype, col
        assert not np.array_equal(obs[SPECTROGRAM][0], obs[SPECTROGRAM][1])
    finally:
        envs.close()
