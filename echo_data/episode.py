"""Episode specs: what one episode is, before anything is simulated.

An `EpisodeSpec` is a pure function of (recipe, split, index, attempt): the floor plan, the
robot's start pose, the sound events in priority order and the ground-truth skill chain. It
is JSON-serialisable so it can be stored, shown (`echo-data preview`) and rebuilt anywhere.
The sampler lives in `echo_data.scene.sampling` (it needs the scene generator and the
solvability checks); this module only holds the data and the seed derivation.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from echo_data import seeds
from echo_data.categories import source_level_db
from echo_data.floorplan import FloorPlan, Vec3

SPLIT_KEYS = {"train": 0, "val": 1, "test": 2}


def episode_id(split: str, index: int) -> str:
    """The name of episode `index` of `split` (its files and records carry it)."""
    return f"{split}-{index:06d}"


def episode_seed(recipe_seed: int, split: str, index: int, attempt: int = 0) -> int:
    """Seed of one episode attempt, derived with SeedSequence from (recipe seed, split, index, attempt).

    Never depends on worker identity or timing, so any worker reproduces any episode.
    """
    ss = np.random.SeedSequence([int(recipe_seed), SPLIT_KEYS[split], int(index), int(attempt)])
    return int(ss.generate_state(1, dtype=np.uint64)[0]) & 0x7FFF_FFFF_FFFF_FFFF


def attempt_draws(recipe_seed: int, split: str, index: int, attempt: int, budget: int) -> list[tuple[int, int]]:
    """The sampler draws of build attempt `attempt` of an episode, as (draw, seed) pairs.

    The one owner of the seed story: build attempt a (a retry after an expert failure) lets
    the sampler try draws a*budget .. (a+1)*budget - 1, draw k seeded with `episode_seed(...,
    k)`, so no two attempts share a draw. The spec that is simulated records its draw
    (`EpisodeSpec.attempt`) and seed; the build's manifest records them for every attempt,
    failed or not, and `sample_episode(recipe, split, index, library, attempt=a)` redoes it.
    """
    return [(k, episode_seed(recipe_seed, split, index, k)) for k in range(attempt * budget, (attempt + 1) * budget)]


def fresh_sound_seed(seed: int, event: int) -> int:
    """Seed of the fresh training sound instance of event `event` of the episode draw `seed`
    (`sounds.fresh_train_instances`): a stream of its own, so the option changes the voices and
    nothing else of the episode (same plan, start and events as without it)."""
    ss = np.random.SeedSequence([int(seed), int(event), seeds.FRESH_SOUND])
    return int(ss.generate_state(1, dtype=np.uint64)[0])


@dataclass(frozen=True)
class SoundEvent:
    """One sounding event: what sounds, where, and what resolves it."""

    category: str  # phone | alarm | furby | doorbell | sink
    sound_id: str  # instance id in the sound library
    target: str  # object name ("phone_0"), "door:<i>" or "faucet:<i>"
    source: Vec3  # where the sound comes from (object centre, doorbell button, faucet spout)
    priority: int  # 0 is resolved first
    level_db: float | None = None  # source level, dB SPL at 1 m; None: drawn by the spec (categories.source_level_db)


@dataclass(frozen=True)
class SkillCall:
    """One entry of the skill chain."""

    skill: str  # Navigate | Pick | Place | OpenDoor | CloseSink
    target: str  # object name, "door:<i>", "faucet:<i>" or "furniture:<i>" (Place goal)
    event: int  # index into EpisodeSpec.events


@dataclass(frozen=True)
class EpisodeSpec:
    episode_id: str  # e.g. "train-000042"
    split: str
    index: int
    attempt: int  # the sampler draw that produced this spec (see attempt_draws)
    seed: int  # episode_seed(recipe seed, split, index, draw)
    setting: str  # object_relocation | state_transition | multi_event
    plan: FloorPlan
    start: tuple[float, float, float]  # base x, y, yaw
    events: tuple[SoundEvent, ...]  # in priority order
    chain: tuple[SkillCall, ...]

    def __post_init__(self) -> None:
        # Every event carries its source level: the one drawn from (plan seed, event) unless given.
        if any(ev.level_db is None for ev in self.events):
            events = tuple(
                ev if ev.level_db is not None else dataclasses.replace(ev, level_db=source_level_db(ev.category, self.plan.seed, e))
                for e, ev in enumerate(self.events)
            )
            object.__setattr__(self, "events", events)

    def source_level(self, e: int) -> float:
        """Event `e`'s source level, dB SPL at 1 m."""
        level = self.events[e].level_db
        assert level is not None  # filled in __post_init__
        return float(level)

    def to_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "plan": self.plan.to_dict()}  # the plan writes itself (FloorPlan.to_dict)

    @staticmethod
    def from_dict(d: dict[str, Any]) -> EpisodeSpec:
        return EpisodeSpec(
            episode_id=d["episode_id"],
            split=d["split"],
            index=d["index"],
            attempt=d["attempt"],
            seed=d["seed"],
            setting=d["setting"],
            plan=FloorPlan.from_dict(d["plan"]),
            start=tuple(d["start"]),
            events=tuple(SoundEvent(**{**e, "source": tuple(e["source"])}) for e in d["events"]),
            chain=tuple(SkillCall(**c) for c in d["chain"]),
        )
