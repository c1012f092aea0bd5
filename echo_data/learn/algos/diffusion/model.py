"""Diffusion Policy's CNN variant, small: a 1-D convolutional U-Net over the action horizon whose
blocks are modulated (FiLM) by the observation code and the noise level; DDPM training (predict
the noise added at a random level of a squared-cosine schedule), DDIM sampling when acting
(deterministic, eta 0, from seeded noise). Binary action entries (the end-effector form's
gripper) are not diffused: a classification head on the observation code predicts them over the
horizon (cross-entropy), so the gripper command is a decision, not a denoised real number.

Why our own: LeRobot >= 0.5 needs Python 3.12 and numpy 2, LeRobot 0.4.4 (the last for Python
3.11) requires torch < 2.11 and torchvision (we pin torch 2.13), `diffusers` is not in our environment and the reference code is not a package; the
pieces (schedule, U-Net, DDIM step) are short and tested here (tests/test_learn_algos.py)."""

from __future__ import annotations

import math
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from echo_data.learn.algos.diffusion.config import DiffusionConfig
from echo_data.learn.features import FeatureSpec
from echo_data.learn.models import Encoders, mlp

X0_CLIP = 5.0  # denoised actions are clipped to +-5 standard deviations of the training actions


def cosine_alpha_bar(steps: int, s: float = 0.008) -> torch.Tensor:
    """Cumulative signal fraction per level of the squared-cosine schedule (Nichol & Dhariwal
    2021, "Improved DDPM", eq. 17), betas capped at 0.999 as they do."""
    f = lambda t: math.cos((t / steps + s) / (1 + s) * math.pi / 2) ** 2  # noqa: E731
    betas = torch.tensor([min(1 - f(i + 1) / f(i), 0.999) for i in range(steps)], dtype=torch.float64)
    return torch.cumprod(1 - betas, dim=0).float()


def timestep_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    """Sinusoidal embedding of integer noise levels (Vaswani et al. 2017's positions)."""
    half = dim // 2
    freq = torch.exp(-math.log(10000.0) * torch.arange(half, device=t.device, dtype=torch.float32) / half)
    arg = t.float()[:, None] * freq[None]
    return torch.cat([torch.sin(arg), torch.cos(arg)], dim=1)


class FiLMBlock(nn.Module):
    """Two 1-D convolutions with GroupNorm and Mish; the condition scales and shifts the first's output."""

    def __init__(self, cin: int, cout: int, cond: int, kernel: int = 5) -> None:
        super().__init__()
        self.conv1 = nn.Sequential(nn.Conv1d(cin, cout, kernel, padding=kernel // 2), nn.GroupNorm(8, cout), nn.Mish())
        self.conv2 = nn.Sequential(nn.Conv1d(cout, cout, kernel, padding=kernel // 2), nn.GroupNorm(8, cout), nn.Mish())
        self.film = nn.Linear(cond, 2 * cout)
        self.skip = nn.Conv1d(cin, cout, 1) if cin != cout else nn.Identity()

    def forward(self, x: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        scale, bias = self.film(c).unsqueeze(-1).chunk(2, dim=1)
        return self.conv2(self.conv1(x) * (1 + scale) + bias) + self.skip(x)


class UNet1D(nn.Module):
    """(B, A, H) noisy actions, levels (B,), condition (B, C) -> predicted noise (B, A, H); H % 4 == 0."""

    def __init__(self, actions: int, cond: int, width: int = 64, temb: int = 64) -> None:
        super().__init__()
        w, w2 = width, 2 * width
        self.temb = temb
        self.t_mlp = nn.Sequential(nn.Linear(temb, 2 * temb), nn.Mish(), nn.Linear(2 * temb, temb))
        c = cond + temb
        self.d0, self.ds0 = FiLMBlock(actions, w, c), nn.Conv1d(w, w, 3, stride=2, padding=1)
        self.d1, self.ds1 = FiLMBlock(w, w2, c), nn.Conv1d(w2, w2, 3, stride=2, padding=1)
        self.mid = FiLMBlock(w2, w2, c)
        self.us1, self.u1 = nn.ConvTranspose1d(w2, w2, 4, stride=2, padding=1), FiLMBlock(2 * w2, w, c)
        self.us0, self.u0 = nn.ConvTranspose1d(w, w, 4, stride=2, padding=1), FiLMBlock(2 * w, w, c)
        self.out = nn.Conv1d(w, actions, 1)

    def forward(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        c = torch.cat([cond, self.t_mlp(timestep_embedding(t, self.temb))], dim=1)
        h0 = self.d0(x, c)
        h1 = self.d1(self.ds0(h0), c)
        m = self.mid(self.ds1(h1), c)
        u1 = self.u1(torch.cat([self.us1(m), h1], dim=1), c)
        u0 = self.u0(torch.cat([self.us0(u1), h0], dim=1), c)
        return self.out(u0)


class DiffusionModel(nn.Module):
    def __init__(self, cfg: DiffusionConfig, spec: FeatureSpec, audio_shape: tuple[int, int] | None) -> None:
        super().__init__()
        self.horizon, self.dim, self.binary = cfg.horizon, len(cfg.target_names), cfg.binary
        self.pos_weight = cfg.binary_weights()
        self.cont = [i for i in range(self.dim) if i not in self.binary]
        self.sample_steps = cfg.sample_steps
        self.history = cfg.history()
        self.enc = Encoders(spec, audio_shape, encoder=cfg.encoder)
        cond = self.enc.out_dim * self.history
        self.unet = UNet1D(len(self.cont), cond, cfg.width)
        self.gripper = mlp(cond, 128, cfg.horizon * len(self.binary)) if self.binary else None
        self.alpha_bar: torch.Tensor
        self.register_buffer("alpha_bar", cosine_alpha_bar(cfg.train_steps))

    def _code(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """The condition: each observation step encoded, concatenated ((B, history, ...) inputs)."""
        if self.history == 1:
            return self.enc(x)
        b = next(iter(x.values())).shape[0]
        return self.enc({k: v.flatten(0, 1) for k, v in x.items()}).view(b, -1)

    def _noise(self, shape: tuple[int, ...], gen: torch.Generator | None, device: torch.device) -> torch.Tensor:
        return torch.randn(shape, generator=gen).to(device)  # drawn on the CPU: the same numbers on any device

    def loss(self, x: dict[str, torch.Tensor], target: torch.Tensor, valid: torch.Tensor, gen: torch.Generator | None = None) -> torch.Tensor:
        code = self._code(x)
        a0 = target[..., self.cont]
        b, dev = a0.shape[0], a0.device
        t = torch.randint(0, len(self.alpha_bar), (b,), generator=gen).to(dev)
        noise = self._noise(tuple(a0.shape), gen, dev)
        ab = self.alpha_bar[t].view(b, 1, 1)
        noisy = ab.sqrt() * a0 + (1 - ab).sqrt() * noise
        eps = self.unet(noisy.transpose(1, 2), t, code).transpose(1, 2)
        err = ((eps - noise) ** 2).mean(dim=-1)
        if self.gripper is not None:
            logits = self.gripper(code).view(b, self.horizon, len(self.binary))
            w = torch.tensor(self.pos_weight, dtype=logits.dtype, device=logits.device) if any(v != 1.0 for v in self.pos_weight) else None
            err = err + F.binary_cross_entropy_with_logits(logits, target[..., list(self.binary)], pos_weight=w, reduction="none").mean(dim=-1)
        return (err * valid).sum() / torch.clamp(valid.sum(), min=1)

    def predict(self, x: dict[str, torch.Tensor], state: Any = None, gen: torch.Generator | None = None) -> tuple[torch.Tensor, Any]:
        """DDIM (Song et al. 2021, eq. 12 with sigma 0) over `sample_steps` evenly spaced levels."""
        code = self._code(x)
        b, dev = code.shape[0], code.device
        a = self._noise((b, self.horizon, len(self.cont)), gen, dev)
        levels = torch.linspace(len(self.alpha_bar) - 1, 0, self.sample_steps).round().long().unique_consecutive()
        x0 = a
        for i, t in enumerate(levels.tolist()):
            ab = self.alpha_bar[t]
            ab_prev = self.alpha_bar[levels[i + 1]] if i + 1 < len(levels) else torch.ones((), device=dev)
            eps = self.unet(a.transpose(1, 2), torch.full((b,), t, device=dev), code).transpose(1, 2)
            x0 = ((a - (1 - ab).sqrt() * eps) / ab.sqrt()).clamp(-X0_CLIP, X0_CLIP)
            a = ab_prev.sqrt() * x0 + (1 - ab_prev).sqrt() * eps
        out = torch.zeros(b, self.horizon, self.dim, device=dev)
        out[..., self.cont] = x0
        if self.gripper is not None:
            out[..., list(self.binary)] = torch.sigmoid(self.gripper(code).view(b, self.horizon, len(self.binary)))
        return out, None
