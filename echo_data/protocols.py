"""What the episode loop, the environment and the build ask of the parts a user may bring: a skill
policy, a planner, a sound library. Structural types (`typing.Protocol`): any object with these
methods fits, no base class needed.

A policy sees observations only. `reset(info)` gets the skill call as a listener would say it
(`SKILL_INFO`: the skill, its target's name and kind, its place in the chain, its event, its step
budget, the episode's seed, the env's action form `action_mode`: "joint" (12 floats) or "ee_delta" (11)) and `act(obs)` the environment's observation dict; neither ever holds
the simulator's world, the episode spec or the skill call object. What a policy wants to know
about the target's position it reads from an observation key (`echo_data.records.GOAL_POSE`,
added by the runtime when the policy lists it in `observations`).

The scripted experts are the exception, and say so: a policy whose class sets `privileged = True`
(`OracleSkills`, `agents.dart.Demonstrator`) also gets `PRIVILEGED_INFO` in its reset info (the live world,
the `SkillCall`, the `EpisodeSpec`), because it plans on the true state. A planner's `reset` gets
the environment's reset info, the true chain and the spec only when it is privileged
(`OraclePlanner`); any other planner gets the episode's id and seed (`PLANNER_INFO`) and must
answer from the first observation.

Ending a skill (SoundSpaces' STOP): `act` returns None. A policy that sets `ends_itself = True`
ends each of its skills that way: the runtime runs it until it returns None (or its budget runs
out) and only then reads the skill's success test, on the state it stopped in; for a learned
(unprivileged) policy the environment also waits for the stop (`EchoDataEnv.stop_skill`), so
passing through the success region on the way counts for nothing. A policy without
`ends_itself` is stopped by the runtime at the first step its skill's test holds (an oracle stop);
None from it ends the skill the same way, there and then.

Optional members, read only where present: a policy's `observations` (the observation keys it
reads; absent = all), `ends_itself`, `privileged`, `outcome` (why it ended), `close()` and, for a
composition of policies (`echo_data.agents.compose.SkillDispatch`), `active` (the member acting
now: whether it is privileged decides the STOP rule above); a planner's `reset(info)`,
`privileged` and `observations`.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

# What every policy's reset info holds.
SKILL_INFO = ("skill", "target", "target_kind", "skill_index", "event", "budget", "episode_seed", "action_mode")
# Added for privileged policies only: the live `World`, the `SkillCall`, the `EpisodeSpec`.
PRIVILEGED_INFO = ("world", "call", "spec_object")
# What an unprivileged planner's `reset` gets.
PLANNER_INFO = ("episode_id", "episode_seed")


class Policy(Protocol):
    """A skill policy: reset once per skill of the chain, then one action per control step (None: STOP)."""

    def reset(self, info: dict[str, Any]) -> None: ...

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray | None: ...


def is_privileged(agent: Any) -> bool:
    """Whether `agent` (a policy or planner) reads the true state (see the module doc)."""
    return bool(getattr(agent, "privileged", False))


class Planner(Protocol):
    """Answers the episode's first observation with a skill chain ([{"skill", "target"}, ...] or its JSON text)."""

    def plan(self, first_obs: dict[str, np.ndarray]) -> Any: ...


class SoundLibrary(Protocol):
    """Sound instances by category and split, and their waveforms (`echo_data.sounds.SoundLibrary` is one)."""

    def instances(self, category: str | None = None, split: str | None = None) -> list[Any]: ...

    def get(self, instance_id: str) -> Any: ...  # also a fresh training instance's id (sounds.fresh_train_instances)

    def waveform(self, instance_id: str, sample_rate: int = 16000, seconds: float | None = None) -> np.ndarray: ...
