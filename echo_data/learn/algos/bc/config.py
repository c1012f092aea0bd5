"""BC (MLP) config: an MLP over the encoders' codes predicting `chunk` future actions."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from echo_data.learn.algos.base import ConfigError, SkillConfig, opt


@dataclass
class BCConfig(SkillConfig):
    """Behaviour cloning with an MLP head; `chunk` > 1 is open-loop action chunking."""

    ALGO: ClassVar[str] = "bc"

    chunk: int = opt(1, "Actions predicted per step (action chunking).")
    execute: int = opt(1, "Predicted actions executed before predicting again (1 <= execute <= chunk).")
    hidden: int = opt(256, "Width of the MLP head.")

    def window(self) -> int:
        return self.chunk

    def execute_steps(self) -> int:
        return self.execute

    def check(self) -> None:
        super().check()
        if self.chunk < 1 or not 1 <= self.execute <= self.chunk:
            raise ConfigError(f"--chunk {self.chunk} / --execute {self.execute}: need 1 <= execute <= chunk")
