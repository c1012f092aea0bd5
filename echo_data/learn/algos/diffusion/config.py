"""Diffusion Policy config (Chi et al. 2023, "Diffusion Policy: Visuomotor Policy Learning via
Action Diffusion"): a 1-D convolutional U-Net denoises a `horizon` of actions conditioned on the
observation, trained as a DDPM, sampled by DDIM when acting."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from echo_data.learn.algos.base import ConfigError, SkillConfig, opt


@dataclass
class DiffusionConfig(SkillConfig):
    """Defaults after Diffusion Policy's CNN variant, smaller (two U-Net levels, 100 training
    steps, 10 DDIM steps when acting); two observation steps as theirs."""

    ALGO: ClassVar[str] = "diffusion"

    horizon: int = opt(16, "Actions denoised per query (a multiple of 4).")
    execute: int = opt(8, "Of those, executed before querying again (1 <= execute <= horizon).")
    train_steps: int = opt(100, "DDPM noise levels in training.")
    sample_steps: int = opt(10, "DDIM steps when acting (deterministic, eta 0).")
    width: int = opt(64, "Channels of the U-Net's first level (the second has twice as many).")
    obs_steps: int = opt(2, "Observation steps the denoiser is conditioned on (Diffusion Policy's 2: t-1 and t).")

    def window(self) -> int:
        return self.horizon

    def execute_steps(self) -> int:
        return self.execute

    def history(self) -> int:
        return self.obs_steps

    def check(self) -> None:
        super().check()
        if self.horizon < 4 or self.horizon % 4 or not 1 <= self.execute <= self.horizon:
            raise ConfigError(f"--horizon {self.horizon} / --execute {self.execute}: need a horizon multiple of 4 and 1 <= execute <= horizon")
        if self.obs_steps < 1:
            raise ConfigError(f"--obs-steps {self.obs_steps}: must be >= 1")
        if not 1 <= self.sample_steps <= self.train_steps:
            raise ConfigError(f"--sample-steps {self.sample_steps}: need 1 <= sample-steps <= train-steps ({self.train_steps})")
