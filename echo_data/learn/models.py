"""The networks: encoders per modality, the behaviour-cloning head and the planner heads.

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
from echo_data.records import ACTION_DIM


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


class ImageEncoder(nn.Module):
    """(B, C, S, S) normalised depth or RGB -> (B, out): three strided convolutions."""

    def __init__(self, channels: int, size: int, out: int = 128) -> None:
        super().__init__()
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 16, 5, stride=2),
            nn.ReLU(),
            nn.Conv2d(16, 32, 3, stride=2),
            nn.ReLU(),
            nn.Conv2d(32, 64, 3, stride=2),
            nn.ReLU(),
            nn.Flatten(),
        )
        self.fc = nn.Sequential(nn.Linear(_conv_out(self.cnn, (channels, size, size)), out), nn.ReLU())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.cnn(x))


def mlp(inp: int, hidden: int, out: int, layers: int = 2) -> nn.Sequential:
    mods: list[nn.Module] = []
    for i in range(layers):
        mods += [nn.Linear(inp if i == 0 else hidden, hidden), nn.ReLU()]
    mods.append(nn.Linear(hidden, out))
    return nn.Sequential(*mods)


class Encoders(nn.Module):
    """One encoder per input of a FeatureSpec; `forward` concatenates their codes. Head and
    wrist depth get separate encoders (they see different things: the room, the grasp); the
    target kind is a one-hot fed as is."""

    def __init__(self, spec: FeatureSpec, audio_shape: tuple[int, int] | None, width: int = 128) -> None:
        super().__init__()
        self.parts = nn.ModuleDict()
        dims: dict[str, int] = {}
        if "audio" in spec.inputs:
            assert audio_shape is not None
            self.parts["audio"] = AudioEncoder(*audio_shape, out=width, channels=spec.audio_channels)
        for name, channels in (("depth", 1), ("wrist_depth", 1), ("image", 3), ("rgb", 3)):
            if name in spec.inputs:
                self.parts[name] = ImageEncoder(channels, spec.image_size, out=width)
        if spec.state_names:
            self.parts["state"] = nn.Sequential(mlp(spec.state_dim, 64, 64, layers=1), nn.ReLU())
            dims["state"] = 64
        if "target" in spec.inputs:
            self.parts["target"] = nn.Sequential(mlp(GOAL_DIM, 64, 64, layers=1), nn.ReLU())
            dims["target"] = 64
        if "kind" in spec.inputs:
            self.parts["kind"] = nn.Identity()
            dims["kind"] = max(len(spec.kinds), 1)
        self.out_dim = sum(dims.get(name, width) for name in self.parts)

    def forward(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.cat([enc(x[name]) for name, enc in self.parts.items()], dim=1)


class BCNet(nn.Module):
    """Encoders -> MLP -> `chunk` future actions (normalised), shape (B, chunk, ACTION_DIM)."""

    def __init__(self, spec: FeatureSpec, audio_shape: tuple[int, int] | None, chunk: int = 1, hidden: int = 256) -> None:
        super().__init__()
        self.chunk = chunk
        self.enc = Encoders(spec, audio_shape)
        self.head = mlp(self.enc.out_dim, hidden, chunk * ACTION_DIM)

    def forward(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.head(self.enc(x)).view(-1, self.chunk, ACTION_DIM)


class BCRNN(nn.Module):
    """Encoders -> GRU over the steps of a skill segment -> next action (normalised): robomimic's
    BC-RNN, SoundSpaces' recurrent state. Inputs carry (B, T, ...) tensors; the hidden state is
    zero at a segment's first step in training, as a policy's is after `reset` at a skill's start.
    Returns ((B, T, 1, ACTION_DIM), hidden)."""

    def __init__(self, spec: FeatureSpec, audio_shape: tuple[int, int] | None, hidden: int = 256) -> None:
        super().__init__()
        self.chunk = 1
        self.enc = Encoders(spec, audio_shape)
        self.gru = nn.GRU(self.enc.out_dim, hidden, batch_first=True)
        self.head = mlp(hidden, hidden, ACTION_DIM, layers=1)

    def forward(self, x: dict[str, torch.Tensor], h: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        b, t = next(iter(x.values())).shape[:2]
        code = self.enc({k: v.reshape(b * t, *v.shape[2:]) for k, v in x.items()}).view(b, t, -1)
        y, h = self.gru(code, h)
        return self.head(y).view(b, t, 1, ACTION_DIM), h


class PlannerNet(nn.Module):
    """Encoders -> per-category logits (is this event sounding?) and priority scores (higher =
    resolve first); the chain follows from the sounding set sorted by score."""

    def __init__(self, spec: FeatureSpec, audio_shape: tuple[int, int] | None, categories: int, hidden: int = 128) -> None:
        super().__init__()
        self.enc = Encoders(spec, audio_shape)
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
