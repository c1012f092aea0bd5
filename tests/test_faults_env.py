"""The environment refuses what it would misread: reset options of the wrong key, type or value,
actions that are not 12 real numbers, and steps after the episode ended (until `reset`), each
with an `EnvInputError` naming the option. gymnasium's own checker still passes
(`test_env_gym.test_check_env_passes`)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from support.recipes import tiny_recipe

from echo_data.envs import EchoDataEnv, EnvInputError


@pytest.fixture(scope="module")
def env() -> Any:
    e = EchoDataEnv(tiny_recipe(), split="test", images=False, audio=False)
    yield e
    e.close()


def _still(obs: dict[str, np.ndarray]) -> np.ndarray:
    a = np.zeros(12, np.float32)
    a[3:12] = obs["observation.state"][3:12]
    return a


@pytest.mark.parametrize("options, says", [
    ({"index": 1.0}, "options['index']: expected an integer, got float"),
    ({"index": 1.7}, "options['index']: expected an integer, got float"),
    ({"index": "1"}, "options['index']: expected an integer, got str"),
    ({"index": True}, "options['index']: expected an integer, got bool"),
    ({"index": -1}, "options['index']: must be >= 0"),
    ({"index": 0, "attempt": 0.5}, "options['attempt']: expected an integer"),
    ({"attempt": 1}, "options['attempt']: needs 'index'"),
    ({"idx": 1}, "unknown key 'idx'"),
    ({"split": 3}, "options['split']: 3 is not a split"),
    ({"split": "val", "index": 0}, "options['split']: 'val' is not a split"),
    ({"spec": {"index": 0}}, "options['spec']: expected an EpisodeSpec, got dict"),
    (["index", 1], "reset options: expected a dict, got list"),
])
def test_bad_reset_options_name_the_option(options: Any, says: str, env: Any) -> None:
    with pytest.raises(EnvInputError) as e:
        env.reset(options=options)
    assert says in str(e.value) and len(str(e.value).splitlines()) == 1, str(e.value)


@pytest.mark.parametrize("action, says", [
    ("twelve floats", "expected 12 numbers, got str"),
    (None, "expected 12 numbers, got NoneType"),
    ({"base": 0.0}, "expected 12 numbers, got dict"),
    ([[0.0] * 12, [0.0]], "not an array of 12 numbers"),
    (np.zeros(12, np.complex64) + 1j, "complex values"),
    (np.zeros((2, 6), np.float32), r"expected shape (12,), got (2, 6)"),
])
def test_actions_that_are_not_twelve_reals_are_refused(action: Any, says: str, env: Any) -> None:
    env.reset(options={"index": 0})
    with pytest.raises(EnvInputError) as e:
        env.step(action)
    assert says in str(e.value), str(e.value)
    assert env.steps == 0  # nothing was simulated


def test_no_step_after_terminated_or_truncated_until_reset(env: Any) -> None:
    obs, _ = env.reset(options={"index": 0})
    obs, _, terminated, _, info = env.step(np.full(12, np.nan, np.float32))
    assert terminated and "non-finite" in info["failure"]
    with pytest.raises(EnvInputError, match="terminated at step 0; call reset"):
        env.step(_still(obs))
    obs, _ = env.reset(options={"index": 0})
    env.max_episode_steps = 2  # a short episode budget, to reach truncation quickly
    for _ in range(2):
        obs, _, terminated, truncated, _ = env.step(_still(obs))
    assert truncated and not terminated
    with pytest.raises(EnvInputError, match="truncated at step 2; call reset"):
        env.step(_still(obs))
    obs, _ = env.reset(options={"index": 0})
    env.step(_still(obs))
    assert env.steps == 1
