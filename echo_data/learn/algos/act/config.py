"""ACT-style action chunking config (Zhao et al. 2023, "Learning Fine-Grained Bimanual
Manipulation with Low-Cost Hardware"): a transformer predicting `chunk` actions, executed with
temporal ensembling."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from echo_data.learn.algos.base import ConfigError, SkillConfig, opt


@dataclass
class ACTConfig(SkillConfig):
    """Defaults are a small ACT (ACT's own: chunk 100 at 50 Hz, 4+7 layers of width 512; ours at
    the dataset's control rate and two CPU cores). Also the privileged sanity learner: `--inputs
    state,observation.privileged....` with no image input is a state-only chunked learner."""

    ALGO: ClassVar[str] = "act"

    chunk: int = opt(20, "Actions predicted per query (ACT's k).")
    execute: int = opt(1, "Without ensembling: predicted actions executed before querying again.")
    ensemble: float = opt(0.01, "Temporal ensembling weight m (w_i = exp(-m i), i = 0 the oldest prediction); < 0 turns it off.")
    d_model: int = opt(128, "Transformer width.")
    heads: int = opt(4, "Attention heads.")
    layers: int = opt(2, "Encoder layers (the decoder has as many).")

    def window(self) -> int:
        return self.chunk

    def execute_steps(self) -> int:
        return 1 if self.ensemble_weight() is not None else self.execute

    def ensemble_weight(self) -> float | None:
        return None if self.ensemble < 0 else float(self.ensemble)

    def check(self) -> None:
        super().check()
        if self.chunk < 1 or not 1 <= self.execute <= self.chunk:
            raise ConfigError(f"--chunk {self.chunk} / --execute {self.execute}: need 1 <= execute <= chunk")
        if self.d_model % self.heads:
            raise ConfigError(f"--d-model {self.d_model}: must be a multiple of --heads {self.heads}")
