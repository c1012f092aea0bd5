"""BC-RNN: encoders -> GRU over a segment's steps -> next action (robomimic's BC-RNN, SoundSpaces'
recurrent state). Inputs carry (B, T, ...) tensors; returns ((B, T, 1, A), hidden)."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from echo_data.learn.algos.base import action_loss, to_probabilities
from echo_data.learn.algos.bc_rnn.config import BCRNNConfig
from echo_data.learn.features import FeatureSpec
from echo_data.learn.models import Encoders, mlp


class BCRNNModel(nn.Module):
    def __init__(self, cfg: BCRNNConfig, spec: FeatureSpec, audio_shape: tuple[int, int] | None) -> None:
        super().__init__()
        self.chunk, self.dim, self.binary = 1, len(cfg.target_names), cfg.binary
        self.pos_weight = cfg.binary_weights()
        self.enc = Encoders(spec, audio_shape, encoder=cfg.encoder)
        self.gru = nn.GRU(self.enc.out_dim, cfg.hidden, batch_first=True)
        self.head = mlp(cfg.hidden, cfg.hidden, self.dim, layers=1)

    def forward(self, x: dict[str, torch.Tensor], h: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        b, t = next(iter(x.values())).shape[:2]
        code = self.enc({k: v.reshape(b * t, *v.shape[2:]) for k, v in x.items()}).view(b, t, -1)
        y, h = self.gru(code, h)
        return self.head(y).view(b, t, 1, self.dim), h

    def loss(self, x: dict[str, torch.Tensor], target: torch.Tensor, valid: torch.Tensor, gen: torch.Generator | None = None) -> torch.Tensor:
        """x: (B, T, ...) segments; target (B*T, 1, A), valid (B*T, 1) row by row."""
        pred, _ = self(x)
        return action_loss(pred.reshape(-1, 1, self.dim), target, valid, self.binary, pos_weight=self.pos_weight)

    def predict(self, x: dict[str, torch.Tensor], state: Any = None, gen: torch.Generator | None = None) -> tuple[torch.Tensor, Any]:
        """One step (B, ...) from hidden state `state` (None = zero, a segment's start)."""
        y, h = self({k: v[:, None] for k, v in x.items()}, state)
        return to_probabilities(y[:, 0], self.binary), h
