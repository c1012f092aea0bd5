"""What the episode loop, the environment and the build ask of the parts a user may bring: a skill
policy, a planner, a sound library. Structural types (`typing.Protocol`): any object with these
methods fits, no base class needed.

Optional members, read only where present: a policy's `observations` (the observation keys it
reads; absent = all), `ends_itself` (it returns None from `act` when its skill is over, like the
scripted experts), `outcome` (why it ended) and `close()`; a planner's `reset(info)` and
`observations`.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class Policy(Protocol):
    """A skill policy: reset once per skill of the chain, then one action per control step."""

    def reset(self, info: dict[str, Any]) -> None: ...

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray | None: ...


class Planner(Protocol):
    """Answers the episode's first observation with a skill chain ([{"skill", "target"}, ...] or its JSON text)."""

    def plan(self, first_obs: dict[str, np.ndarray]) -> Any: ...


class SoundLibrary(Protocol):
    """Sound instances by category and split, and their waveforms (`echo_data.sounds.SoundLibrary` is one)."""

    def instances(self, category: str | None = None, split: str | None = None) -> list[Any]: ...

    def get(self, instance_id: str) -> Any: ...  # also a fresh training instance's id (sounds.fresh_train_instances)

    def waveform(self, instance_id: str, sample_rate: int = 16000, seconds: float | None = None) -> np.ndarray: ...
