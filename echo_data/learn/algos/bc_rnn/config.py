"""BC-RNN config (robomimic's BC-RNN): a GRU over the steps of a skill segment."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from echo_data.learn.algos.base import SkillConfig, opt


@dataclass
class BCRNNConfig(SkillConfig):
    """Trains on whole segments (`batch_size` of them per step, padded and masked), the GRU's
    state zero at each segment's first row: what the policy sees after `reset` at a skill's start."""

    ALGO: ClassVar[str] = "bc_rnn"
    SEQUENCE: ClassVar[bool] = True

    batch_size: int = opt(4, "Skill segments per optimiser step.")
    hidden: int = opt(256, "GRU width.")
