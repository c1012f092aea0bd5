"""BC (MLP): encoders -> MLP -> `chunk` future actions (normalised; logits for binary entries)."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from echo_data.learn.algos.base import action_loss, to_probabilities
from echo_data.learn.algos.bc.config import BCConfig
from echo_data.learn.features import FeatureSpec
from echo_data.learn.models import Encoders, mlp


class BCModel(nn.Module):
    def __init__(self, cfg: BCConfig, spec: FeatureSpec, audio_shape: tuple[int, int] | None) -> None:
        super().__init__()
        self.chunk, self.dim, self.binary = cfg.chunk, len(cfg.target_names), cfg.binary
        self.pos_weight = cfg.binary_weights()
        self.enc = Encoders(spec, audio_shape, encoder=cfg.encoder)
        self.head = mlp(self.enc.out_dim, cfg.hidden, cfg.chunk * self.dim)

    def forward(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.head(self.enc(x)).view(-1, self.chunk, self.dim)

    def loss(self, x: dict[str, torch.Tensor], target: torch.Tensor, valid: torch.Tensor, gen: torch.Generator | None = None) -> torch.Tensor:
        return action_loss(self(x), target, valid, self.binary, pos_weight=self.pos_weight)

    def predict(self, x: dict[str, torch.Tensor], state: Any = None, gen: torch.Generator | None = None) -> tuple[torch.Tensor, Any]:
        return to_probabilities(self(x), self.binary), None
