"""Gymnasium environments over the echo-data world (see `echo_data.envs.env`).

Registered ids (importing this package registers them):
`EchoData/ObjectRelocation-v0`, `EchoData/StateTransition-v0`, `EchoData/MultiEvent-v0`,
each over the shipped recipe of that setting; pass `recipe=` (a path or a Recipe) to override.
"""

from __future__ import annotations

import gymnasium as gym

from echo_data.envs.env import EchoDataEnv, EnvInputError, action_space, observation_space

__all__ = ["EchoDataEnv", "EnvInputError", "action_space", "observation_space", "ENV_IDS"]

ENV_IDS = {
    "EchoData/ObjectRelocation-v0": "object_relocation",
    "EchoData/StateTransition-v0": "state_transition",
    "EchoData/MultiEvent-v0": "multi_event",
}

for _id, _recipe in ENV_IDS.items():
    if _id not in gym.registry:
        gym.register(id=_id, entry_point="echo_data.envs.env:EchoDataEnv", kwargs={"recipe": _recipe})
