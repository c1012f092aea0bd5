"""ACT-style transformer: one token per encoded input (audio, each camera, proprioception, ...),
a transformer encoder over them, and `chunk` learned queries decoded against it into `chunk`
actions (L1 loss as in ACT; binary entries by cross-entropy).

Why our own and not LeRobot's or ACT's code: LeRobot >= 0.5 needs Python 3.12 and numpy 2 (our
stack pins numpy < 2 for mplib), LeRobot 0.4.4 (the last for Python 3.11) requires torch < 2.11 and
torchvision (we pin torch 2.13), robomimic 0.3.0's models import torchvision, and ACT's repository
is not a package. Left out on purpose: ACT's CVAE latent (it models the variability of human
demonstrations; our demonstrations are scripted and consistent, and ACT's ablation shows it
matters little on scripted data) and ResNet feature-map tokens (one token per encoder here; the
spatial-softmax encoder supplies keypoints). No dropout: a resumed run then draws exactly what an
uninterrupted one does."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from echo_data.learn.algos.act.config import ACTConfig
from echo_data.learn.algos.base import action_loss, to_probabilities
from echo_data.learn.features import FeatureSpec
from echo_data.learn.models import Encoders


class ACTModel(nn.Module):
    def __init__(self, cfg: ACTConfig, spec: FeatureSpec, audio_shape: tuple[int, int] | None) -> None:
        super().__init__()
        self.chunk, self.dim, self.binary = cfg.chunk, len(cfg.target_names), cfg.binary
        self.pos_weight = cfg.binary_weights()
        self.enc = Encoders(spec, audio_shape, encoder=cfg.encoder)
        d = cfg.d_model
        self.proj = nn.ModuleDict({name: nn.Linear(dim, d) for name, dim in self.enc.dims.items()})
        self.pos = nn.Parameter(torch.randn(len(self.proj), d) * 0.02)
        self.queries = nn.Parameter(torch.randn(cfg.chunk, d) * 0.02)
        self.transformer = nn.Transformer(d, cfg.heads, cfg.layers, cfg.layers, 4 * d, dropout=0.0, batch_first=True)
        self.head = nn.Linear(d, self.dim)

    def forward(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        codes = self.enc.codes(x)
        tokens = torch.stack([self.proj[name](c) for name, c in codes.items()], dim=1) + self.pos
        out = self.transformer(tokens, self.queries.expand(tokens.shape[0], -1, -1))
        return self.head(out)  # (B, chunk, A)

    def loss(self, x: dict[str, torch.Tensor], target: torch.Tensor, valid: torch.Tensor, gen: torch.Generator | None = None) -> torch.Tensor:
        return action_loss(self(x), target, valid, self.binary, l1=True, pos_weight=self.pos_weight)

    def predict(self, x: dict[str, torch.Tensor], state: Any = None, gen: torch.Generator | None = None) -> tuple[torch.Tensor, Any]:
        return to_probabilities(self(x), self.binary), None
