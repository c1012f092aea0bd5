"""The networks shared by the learners: encoders per modality and the planner heads (each skill
algorithm's own network lives in `learn/algos/<name>/`).

Small on purpose (trainable in minutes on two CPU cores). The audio encoder follows the layout of
SoundSpaces' AudioNav audio CNN: three convolutions 2 -> 32 -> 64 -> 64 channels with kernels
5, 3, 3 and strides 2, 2, 1 (their choice when a side of the spectrogram is under 30 bins, as for
the 65 x 26 spectrogram; 4, 2, 2 otherwise), then a linear layer. The two ears stay separate input channels, so interaural level and timing
cues reach the first convolution (swapping the ears changes the code).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from echo_data.learn.features import GOAL_DIM, FeatureSpec


def _conv_out(net: nn.Module, shape: tuple[int, ...]) -> int:
    with torch.no_grad():
        return int(net(torch.zeros(1, *shape)).numel())


def audio_strides(freq: int, frames: int) -> tuple[int, int, int]:
    """SoundSpaces' rule: strides 2, 2, 1 when a side is under 30 bins, else 4, 2, 2 (a 64 x 101
    log-mel would otherwise leave a 10-million-weight linear layer)."""
    return (2, 2, 1) if min(freq, frames) < 30 else (4, 2, 2)


def stored_audio_shape(shape: list[int] | tuple[int, ...] | None) -> tuple[int, int] | None:
    """(freq, frames) of the audio feature as a run's config stores it (a JSON list), or None."""
    if not shape:
        return None
    freq, frames = (int(v) for v in tuple(shape)[:2])
    return (freq, frames)


class AudioEncoder(nn.Module):
    """(B, C, F, T) normalised binaural features -> (B, out); C = 2 ears (+ their ILD: 3)."""

    def __init__(self, freq: int, frames: int, out: int = 128, channels: int = 2) -> None:
        super().__init__()
        s1, s2, s3 = audio_strides(freq, frames)
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 32, 5, stride=s1),
            nn.ReLU(),
            nn.Conv2d(32, 64, 3, stride=s2),
            nn.ReLU(),
            nn.Conv2d(64, 64, 3, stride=s3),
            nn.ReLU(),
            nn.Flatten(),
        )
        self.fc = nn.Sequential(nn.Linear(_conv_out(self.cnn, (channels, freq, frames)), out), nn.ReLU())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.cnn(x))


class PooledAudioEncoder(nn.Module):
    """(B, C, F, T) normalised binaural features -> (B, out), indifferent to when in the second a
    sound plays: three blocks of a 3 x 3 convolution with batch norm, each block halving both axes,
    then the mean over frequency and the mean plus the max over time (the layout of the PANNs CNN
    family, Kong et al. 2020, "PANNs: Large-Scale Pretrained Audio Neural Networks for Audio
    Pattern Recognition", cut to one convolution per block and 16-32-64 channels so that an
    epoch of the planner's 10,000 rows stays under a minute on one CPU thread).

    Why beside `AudioEncoder`: its flattened code ties a pattern to the frames where it was heard,
    so a doorbell's ring at 0.3 s and at 0.7 s are different inputs to the linear layer; tagging
    which events sound (the planner's question) wants the pattern wherever it is, and two events
    heard together are two patterns the max keeps apart."""

    def __init__(self, freq: int, frames: int, out: int = 128, channels: int = 2, width: int = 16) -> None:
        super().__init__()
        blocks: list[nn.Module] = []
        inp = channels
        for c in (width, 2 * width, 4 * width):
            blocks += [nn.Conv2d(inp, c, 3, padding=1, bias=False), nn.BatchNorm2d(c), nn.ReLU(), nn.AvgPool2d(2, ceil_mode=True)]
            inp = c
        self.cnn = nn.Sequential(*blocks)
        self.fc = nn.Sequential(nn.Dropout(0.2), nn.Linear(2 * inp, out), nn.ReLU())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        f = self.cnn(x).mean(dim=2)  # (B, C, T'): mean over frequency
        return self.fc(torch.cat([f.mean(dim=2), f.amax(dim=2)], dim=1))


AUDIO_ENCODERS = {"flat": AudioEncoder, "pooled": PooledAudioEncoder}


class ImageEncoder(nn.Module):
    """(B, C, H, W) normalised depth or RGB -> (B, out): three strided convolutions, flattened."""

    def __init__(self, channels: int, size: int | tuple[int, int], out: int = 128) -> None:
        super().__init__()
        h, w = (size, size) if isinstance(size, int) else size
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 16, 5, stride=2),
            nn.ReLU(),
            nn.Conv2d(16, 32, 3, stride=2),
            nn.ReLU(),
            nn.Conv2d(32, 64, 3, stride=2),
            nn.ReLU(),
            nn.Flatten(),
        )
        self.fc = nn.Sequential(nn.Linear(_conv_out(self.cnn, (channels, h, w)), out), nn.ReLU())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.cnn(x))


class SpatialSoftmaxEncoder(nn.Module):
    """(B, C, H, W) -> (B, out): convolutions, then each of `keypoints` feature maps becomes the
    expected image position (x, y in [-1, 1]) under a softmax over its pixels (Levine et al. 2016,
    "End-to-end training of deep visuomotor policies"; robomimic's default image encoder).

    Why: a flattened CNN code mixes what and where; keypoints are where things are, which is what
    an arm needs to reach an object it sees. Convolutions keep the stored resolution to stride 2,
    so a few-pixel object still owns a peak."""

    def __init__(self, channels: int, size: int | tuple[int, int], out: int = 128, keypoints: int = 32) -> None:
        super().__init__()
        h, w = (size, size) if isinstance(size, int) else size
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 32, 5, stride=2, padding=2),
            nn.ReLU(),
            nn.Conv2d(32, 32, 3, padding=1),
            nn.ReLU(),
            nn.Conv2d(32, keypoints, 3, padding=1),
        )
        fh, fw = (h + 1) // 2, (w + 1) // 2
        ys, xs = torch.meshgrid(torch.linspace(-1, 1, fh), torch.linspace(-1, 1, fw), indexing="ij")
        self.grid: torch.Tensor
        self.register_buffer("grid", torch.stack([xs.reshape(-1), ys.reshape(-1)], dim=1), persistent=False)  # (HW, 2)
        self.fc = nn.Sequential(nn.Linear(2 * keypoints, out), nn.ReLU())

    def keypoints(self, f: torch.Tensor) -> torch.Tensor:
        """(B, K, h, w) feature maps -> (B, K, 2): the expected (x, y) in [-1, 1] of each map's softmax."""
        return torch.softmax(f.flatten(2), dim=-1) @ self.grid

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.keypoints(self.cnn(x)).flatten(1))


IMAGE_ENCODERS = {"cnn": ImageEncoder, "spatial_softmax": SpatialSoftmaxEncoder}


def mlp(inp: int, hidden: int, out: int, layers: int = 2) -> nn.Sequential:
    mods: list[nn.Module] = []
    for i in range(layers):
        mods += [nn.Linear(inp if i == 0 else hidden, hidden), nn.ReLU()]
    mods.append(nn.Linear(hidden, out))
    return nn.Sequential(*mods)


class Encoders(nn.Module):
    """One encoder per input of a FeatureSpec; `forward` concatenates their codes, `codes` keeps
    them apart (ACT reads one token per input). Head and wrist depth get separate encoders (they
    see different things: the room, the grasp); the target kind is a one-hot fed as is; each
    privileged column (a vector) gets a small MLP."""

    def __init__(self, spec: FeatureSpec, audio_shape: tuple[int, int] | None, width: int = 128, encoder: str = "cnn", audio_encoder: str = "flat") -> None:
        super().__init__()
        self.parts = nn.ModuleDict()
        self.dims: dict[str, int] = {}
        if "audio" in spec.inputs:
            assert audio_shape is not None
            self.parts["audio"] = AUDIO_ENCODERS[audio_encoder](*audio_shape, out=width, channels=spec.audio_channels)
        for name, channels in (("depth", 1), ("wrist_depth", 1), ("image", 3), ("rgb", 3)):
            if name in spec.inputs:
                self.parts[name] = IMAGE_ENCODERS[encoder](channels, spec.side(name), out=width)
        if spec.state_names:
            self.parts["state"] = nn.Sequential(mlp(spec.state_dim, 64, 64, layers=1), nn.ReLU())
            self.dims["state"] = 64
        if "target" in spec.inputs:
            self.parts["target"] = nn.Sequential(mlp(GOAL_DIM, 64, 64, layers=1), nn.ReLU())
            self.dims["target"] = 64
        if "kind" in spec.inputs:
            self.parts["kind"] = nn.Identity()
            self.dims["kind"] = max(len(spec.kinds), 1)
        for col, p in spec.privileged.items():
            self.parts[part_name(col)] = nn.Sequential(mlp(int(p["dim"]), 64, 64, layers=1), nn.ReLU())
            self.dims[part_name(col)] = 64
        for name in self.parts:
            self.dims.setdefault(name, width)
        self.out_dim = sum(self.dims.values())

    def codes(self, x: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        return {name: enc(x[name]) for name, enc in self.parts.items()}

    def forward(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.cat(list(self.codes(x).values()), dim=1)


def part_name(column: str) -> str:
    """A privileged column's encoder name (ModuleDict keys may not hold dots)."""
    return column.replace(".", "__")


class PlannerNet(nn.Module):
    """Encoders -> per-category logits (is this event sounding?) and priority scores (higher =
    resolve first); the chain follows from the sounding set sorted by score."""

    def __init__(self, spec: FeatureSpec, audio_shape: tuple[int, int] | None, categories: int, hidden: int = 128, audio_encoder: str = "flat") -> None:
        super().__init__()
        self.enc = Encoders(spec, audio_shape, audio_encoder=audio_encoder)
        self.head = mlp(self.enc.out_dim, hidden, 2 * categories)
        self.categories = categories

    def forward(self, x: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        out = self.head(self.enc(x))
        return out[:, : self.categories], out[:, self.categories :]


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def audio_shape(spec: FeatureSpec, layout: dict[str, Any]) -> tuple[int, int] | None:
    """(F, T) of the audio feature a spec reads, from the manifest's layout."""
    if "audio" not in spec.inputs:
        return None
    key = "spectrogram_shape" if spec.audio_key.endswith("spectrogram") else "mel_shape"
    shape = layout.get(key)
    if not shape:
        from echo_data.learn.features import FeatureError

        raise FeatureError(f"layout: the dataset stores no {spec.audio_key}")
    return int(shape[0]), int(shape[1])
