"""Dataset observations -> normalised model inputs: the one path shared by training and acting.

Training decodes step rows to the arrays the world gives (PNG -> uint8 RGB, uint16 millimetre
depth), and both training and a policy acting in the world turn them into the loaders' form
(depth in metres (1, H, W), RGB in [0, 1] (3, H, W), spectrograms (F, T, 2)) with `canonical`
and then into model inputs with `prepare`: one path, so the two cannot drift. Normalisation constants come from the dataset's
meta/stats.json and are frozen into a `FeatureSpec` that the run folder stores.

Leak: the state vector's velocities are what the last action commanded (the base is driven by
velocity with high damping, so base_vx/vy/wz at step t equal action t-1 to ~1e-6, and actions are
smooth, so they predict action t almost perfectly); joint velocities likewise echo the last change
of a position target. `state` therefore leaves every velocity out; `state_raw` keeps them (only
to measure the shortcut). See docs/learners.md.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.schema import IMAGE_COLUMNS, MEL, SPECTROGRAM, STATE
from echo_data.records import ACTION_NAMES, BASE_FRAME_STATE, PRIVILEGED_PREFIX, STATE_NAMES

HEAD_DEPTH = IMAGE_COLUMNS["head_depth"]
HEAD_RGB = IMAGE_COLUMNS["head_rgb"]
WRIST_DEPTH = IMAGE_COLUMNS["wrist_depth"]
AUDIO_COLUMNS = {"spectrogram": SPECTROGRAM, "mel": MEL}
IMAGE_INPUT_COLUMNS = {"depth": HEAD_DEPTH, "wrist_depth": WRIST_DEPTH, "rgb": HEAD_RGB, "image": HEAD_RGB}  # image input -> its stored column

# State entries that echo the previous command (see module doc): never fed by `state`.
LEAKING_STATE = tuple(n for n in STATE_NAMES if n in ("base_vx", "base_vy", "base_wz") or n.endswith("_vel"))
BC_INPUTS = ("audio", "depth", "wrist_depth", "rgb", "state", "state_raw", "target", "kind", PRIVILEGED_PREFIX)  # the prefix: any privileged column by name
PLANNER_INPUTS = ("audio", "image")
DEPTH_MAX_M = 10.0  # farther readings (and the renderer's 0 = nothing hit) carry no more cue
GOAL_SCALE_M = 5.0  # goal offsets are divided by this: apartments are a few rooms across
# Audio forms a model can read (`--audio-form`): "stored" is the dataset's feature normalised per
# ear with its statistics; "level_ild" is each ear's level in dB plus the interaural level
# difference L - R in dB as a third channel (see `_level_ild`).
AUDIO_FORMS = ("stored", "level_ild")
LEVEL_FLOOR = 1e-5  # spectrogram magnitude floor (-100 dB re 1, the log-mel's floor): below the noise bed
LEVEL_REF_DB, LEVEL_SCALE_DB = -60.0, 20.0  # level channels: (dB - ref) / scale
ILD_SCALE_DB = 6.0  # ILD channel: dB / scale (head-shadow ILDs reach about +-20 dB at high frequencies)
YAW = STATE_NAMES.index("base_yaw")
# Action forms a BC run predicts (`--action-form`). "absolute": the dataset's action (joint position
# targets), normalised with the dataset's action statistics. "delta": the torso and arm targets as
# the change from the joints measured at that step (target - measured; base velocities and the
# gripper opening stay as they are), normalised with the statistics of the skill's own training
# rows. Why: an absolute target is the measured joint plus a small step, so a network fed the
# joints learns to copy them and under-steps, and closed loop the arm slows to a stop short of
# the object (measured: the skill-trace study on a Pick run, docs/learners.md); the change
# cannot be copied from the input. The stored `action` column is untouched: the form is the run's.
ACTION_FORMS = ("absolute", "delta")
DELTA_JOINTS = ("torso",) + tuple(f"arm_{i}" for i in range(7))
DELTA_ACTION = tuple(ACTION_NAMES.index(n) for n in DELTA_JOINTS)
DELTA_STATE = tuple(STATE_NAMES.index(n) for n in DELTA_JOINTS)


class FeatureError(ValueError):
    """Inputs that the dataset cannot provide (one line, names the key)."""


@dataclass(frozen=True)
class FeatureSpec:
    """Which inputs a model reads and the frozen constants that normalise them."""

    inputs: tuple[str, ...]
    state_names: tuple[str, ...] = ()  # state entries fed (yaw goes in as sin, cos)
    state_mean: tuple[float, ...] = ()
    state_std: tuple[float, ...] = ()
    audio_key: str = SPECTROGRAM
    audio_mean: tuple[float, ...] = (0.0, 0.0)  # per ear
    audio_std: tuple[float, ...] = (1.0, 1.0)
    depth_mean: float = 0.0
    depth_std: float = 1.0
    wrist_mean: float = 0.0
    wrist_std: float = 1.0
    image_size: int = 64  # depth / RGB are area-downsampled to this side; 0 = kept at the stored resolution
    rgb_mean: tuple[float, ...] = (0.0, 0.0, 0.0)
    rgb_std: tuple[float, ...] = (1.0, 1.0, 1.0)
    image_key: str = HEAD_RGB
    audio_form: str = "stored"  # one of AUDIO_FORMS
    kinds: tuple[str, ...] = ()  # "kind": the target kinds this skill serves in training (one-hot, unknown = zeros)
    extra: dict[str, Any] = field(default_factory=dict)
    sides: dict[str, Any] = field(default_factory=dict)  # image input -> stored (H, W), read when image_size is 0
    privileged: dict[str, Any] = field(default_factory=dict)  # privileged column -> {"dim", "mean", "std"}

    def side(self, name: str) -> int | tuple[int, int]:
        """The (H, W) an image input reaches its encoder at."""
        if self.image_size:
            return self.image_size
        h, w = self.sides[name]
        return (int(h), int(w))

    @property
    def audio_channels(self) -> int:
        """Input channels of the audio encoder: the two ears, plus the ILD for "level_ild"."""
        return 3 if self.audio_form == "level_ild" else 2

    @property
    def columns(self) -> list[str]:
        """Dataset columns `prepare` reads."""
        cols = []
        if "audio" in self.inputs:
            cols.append(self.audio_key)
        if "depth" in self.inputs:
            cols.append(HEAD_DEPTH)
        if "wrist_depth" in self.inputs:
            cols.append(WRIST_DEPTH)
        if "image" in self.inputs or "rgb" in self.inputs:
            cols.append(self.image_key)
        if any(i in self.inputs for i in ("state", "state_raw", "target")):
            cols.append(STATE)
        return cols + list(self.privileged)

    @property
    def state_dim(self) -> int:
        return len(self.state_names) + (1 if "base_yaw" in self.state_names else 0)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @staticmethod
    def from_dict(d: Mapping[str, Any]) -> FeatureSpec:
        tup = {k: tuple(v) for k, v in d.items() if isinstance(v, list)}
        return FeatureSpec(**{**d, **tup})


def parse_inputs(text: str, allowed: tuple[str, ...]) -> tuple[str, ...]:
    """"audio,depth,state" -> ("audio", "depth", "state"); unknown names raise FeatureError."""
    names = tuple(dict.fromkeys(t.strip() for t in text.split(",") if t.strip()))
    bad = [n for n in names if n not in allowed and not (PRIVILEGED_PREFIX in allowed and n.startswith(PRIVILEGED_PREFIX) and n != PRIVILEGED_PREFIX)]
    if not names or bad:
        raise FeatureError(f"--inputs: unknown {bad or 'empty list'}; choose from {', '.join(allowed)}")
    if "state" in names and "state_raw" in names:
        raise FeatureError("--inputs: state and state_raw exclude each other")
    return names


def feature_spec(
    dataset: Path, inputs: tuple[str, ...], audio: str = "spectrogram", image_size: int = 64, audio_form: str = "stored", kinds: tuple[str, ...] = ()
) -> FeatureSpec:
    """The spec for `inputs` with constants from `dataset`/meta/stats.json (train split);
    `kinds` is the target-kind vocabulary the "kind" input one-hot encodes."""
    path = dataset / "meta" / "stats.json"
    try:
        stats = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise FeatureError(f"{path}: cannot read dataset statistics ({e})") from None

    def need(key: str) -> dict[str, list[float]]:
        if key not in stats:
            raise FeatureError(f"{path}: no statistics for {key!r}; the dataset does not store it")
        return stats[key]

    kw: dict[str, Any] = {"inputs": inputs, "image_size": image_size, "kinds": tuple(kinds) if "kind" in inputs else ()}
    if not image_size:
        kw["sides"] = stored_sides(dataset, inputs)
    kw["privileged"] = {c: privileged_stats(dataset, c, stats) for c in inputs if c.startswith(PRIVILEGED_PREFIX)}
    if "audio" in inputs:
        if audio not in AUDIO_COLUMNS:
            raise FeatureError(f"--audio: unknown feature {audio!r}; choose from {', '.join(AUDIO_COLUMNS)}")
        if audio_form not in AUDIO_FORMS:
            raise FeatureError(f"--audio-form: unknown form {audio_form!r}; choose from {', '.join(AUDIO_FORMS)}")
        s = need(AUDIO_COLUMNS[audio])
        kw.update(audio_key=AUDIO_COLUMNS[audio], audio_mean=tuple(s["mean"]), audio_std=tuple(max(v, 1e-6) for v in s["std"]),
                  audio_form=audio_form)
    if "depth" in inputs:
        s = need(HEAD_DEPTH)
        kw.update(depth_mean=s["mean"][0], depth_std=max(s["std"][0], 1e-6))
    if "wrist_depth" in inputs:
        s = need(WRIST_DEPTH)
        kw.update(wrist_mean=s["mean"][0], wrist_std=max(s["std"][0], 1e-6))
    if "image" in inputs or "rgb" in inputs:
        s = need(HEAD_RGB)
        kw.update(rgb_mean=tuple(s["mean"]), rgb_std=tuple(max(v, 1e-6) for v in s["std"]))
    if "state" in inputs or "state_raw" in inputs:
        s = need(STATE)
        keep = [i for i, n in enumerate(STATE_NAMES) if "state_raw" in inputs or (n in BASE_FRAME_STATE and n not in LEAKING_STATE)]
        # Constant entries (std 0 in the data) are centred but not scaled up.
        kw.update(
            state_names=tuple(STATE_NAMES[i] for i in keep),
            state_mean=tuple(s["mean"][i] for i in keep),
            state_std=tuple(s["std"][i] if s["std"][i] > 1e-3 else 1.0 for i in keep),
        )
    elif "target" in inputs:
        need(STATE)
    return FeatureSpec(**kw)


def stored_sides(dataset: Path, inputs: tuple[str, ...]) -> dict[str, tuple[int, int]]:
    """(H, W) of each image input as the dataset stores it (manifest layout)."""
    from echo_data.dataset.reader import DatasetMeta

    try:
        layout = DatasetMeta.of(dataset).layout
    except (OSError, ValueError, KeyError) as e:
        raise FeatureError(f"{dataset / 'manifest.json'}: cannot read the step layout ({e})") from None
    out = {}
    for name, col in IMAGE_INPUT_COLUMNS.items():
        if name in inputs:
            if col not in layout.images:
                raise FeatureError(f"--inputs {name}: the dataset stores no {col}")
            out[name] = (int(layout.images[col][1]), int(layout.images[col][2]))
    return out


def privileged_stats(dataset: Path, column: str, stats: Mapping[str, Any]) -> dict[str, Any]:
    """Size and normalisation of a privileged column: its stats.json moments when the dataset has
    them, else its size from the shards' schema with mean 0 and scale 1."""
    if column in stats:
        mean, std = list(stats[column]["mean"]), list(stats[column]["std"])
        return {"dim": len(mean), "mean": mean, "std": [v if v > 1e-6 else 1.0 for v in std]}
    from echo_data.dataset.reader import DatasetMeta

    meta = DatasetMeta.of(dataset)
    dim = meta.vector_size(column)
    if dim is None:
        raise FeatureError(f"--inputs {column}: no such column in {dataset} (its step rows have {', '.join(c for c in meta.columns if c.startswith(PRIVILEGED_PREFIX)) or 'no privileged columns'})")
    return {"dim": dim, "mean": [0.0] * dim, "std": [1.0] * dim}


def canonical(key: str, value: Any) -> np.ndarray:
    """One observation value (as the world or the dataset gives it) -> the loaders' form.

    Depth: uint16 millimetres (H, W) or float metres (H, W) / (1, H, W) -> float32 metres
    (1, H, W). RGB: uint8 (H, W, 3) or float (3, H, W) in [0, 1] -> float32 (3, H, W).
    Vectors and spectrograms pass through as float32."""
    x = value.detach().cpu().numpy() if hasattr(value, "detach") else np.asarray(value)
    if key in (HEAD_DEPTH, WRIST_DEPTH):
        if x.ndim == 3 and x.shape[-1] == 1:
            x = x[..., 0]
        metres = x.astype(np.float32) / 1000.0 if np.issubdtype(x.dtype, np.integer) else x.astype(np.float32)
        return metres if metres.ndim == 3 else metres[None]
    if key == HEAD_RGB:
        if x.ndim == 3 and x.shape[-1] == 3:
            x = x.transpose(2, 0, 1)
        return x.astype(np.float32) / 255.0 if np.issubdtype(x.dtype, np.integer) else x.astype(np.float32)
    return x.astype(np.float32)


def to_action_form(actions: np.ndarray, states: np.ndarray, form: str) -> np.ndarray:
    """Dataset actions (n, chunk, ACTION_DIM) and the states they were taken in (n, STATE_DIM) ->
    what a run of `form` predicts (see ACTION_FORMS)."""
    if form == "absolute":
        return actions
    out = np.array(actions, dtype=np.float32, copy=True)
    out[..., list(DELTA_ACTION)] -= states[:, None, list(DELTA_STATE)]
    return out


def from_action_form(pred: np.ndarray, state: np.ndarray | None, form: str) -> np.ndarray:
    """A run's prediction (ACTION_DIM,) in `form` and the state measured now -> the env's action."""
    if form == "absolute":
        return pred
    if state is None:
        raise FeatureError(f"a policy predicting {form} actions needs the state observation")
    out = np.array(pred, dtype=np.float32, copy=True)
    out[list(DELTA_ACTION)] += state[list(DELTA_STATE)]
    return out


def goal_features(state: Any, goal: Any) -> Any:
    """Goal (x, y, yaw) in the world -> (dx, dy) in the robot frame / GOAL_SCALE_M, distance,
    sin and cos of the heading error: what a policy needs, whatever the apartment's origin."""
    import torch

    x, y, yaw = state[:, 0], state[:, 1], state[:, YAW]
    dxw, dyw = goal[:, 0] - x, goal[:, 1] - y
    c, s = torch.cos(yaw), torch.sin(yaw)
    dx, dy = (c * dxw + s * dyw) / GOAL_SCALE_M, (-s * dxw + c * dyw) / GOAL_SCALE_M
    dyaw = goal[:, 2] - yaw
    return torch.stack([dx, dy, torch.sqrt(dx * dx + dy * dy), torch.sin(dyaw), torch.cos(dyaw)], dim=1)


GOAL_DIM = 5


def _level_ild(a: Any, key: str) -> Any:
    """(B, 2, F, T) stored binaural feature -> (B, 3, F, T): left and right level in dB and their
    difference, the interaural level difference (ILD).

    Why: the stored spectrogram is log1p of magnitudes that are mostly far below 1 (median about
    3e-4 at the calibrated full scale), so it is nearly linear and the ratio of the ears, the
    cue that says left or right, is a small difference between tiny numbers. In dB the ILD is
    a plain subtraction, 20 log10(|L| / |R|) (the level ratio of the two ears), which the network
    no longer has to learn from magnitudes. The log-mel is already in dB (power, -100 dB floor).
    Fixed scales, not dataset moments: stats.json holds the stored form's moments, and a fixed
    scale keeps 0 dB ILD at 0 for every dataset."""
    import torch

    db = 20.0 * torch.log10(torch.clamp(torch.expm1(a), min=LEVEL_FLOOR)) if key == AUDIO_COLUMNS["spectrogram"] else a
    ild = (db[:, 0:1] - db[:, 1:2]) / ILD_SCALE_DB
    return torch.cat([(db - LEVEL_REF_DB) / LEVEL_SCALE_DB, ild], dim=1)


def _area(x: Any, size: int) -> Any:
    """Area-downsample to `size` x `size`; 0 keeps the stored resolution."""
    import torch.nn.functional as F

    return x if size == 0 or (x.shape[-1] == size and x.shape[-2] == size) else F.adaptive_avg_pool2d(x, size)


def kind_index(spec: FeatureSpec, kind: str | None) -> int:
    """Position of a target kind in the spec's vocabulary; -1 (all-zero one-hot) when unknown."""
    return spec.kinds.index(kind) if kind in spec.kinds else -1


def prepare(batch: Mapping[str, Any], spec: FeatureSpec, goal: Any | None = None, kind: Any | None = None) -> dict[str, Any]:
    """Loader-form batch {column: (B, ...)} -> {"audio", "depth", "wrist_depth", "image" | "rgb",
    "state", "target", "kind"} float32 tensors, normalised. `goal` (B, 3) world poses is needed
    when "target" is an input, `kind` (B,) indices into `spec.kinds` when "kind" is."""
    import torch

    t = lambda k: torch.as_tensor(batch[k], dtype=torch.float32)  # noqa: E731
    out: dict[str, Any] = {}
    if "audio" in spec.inputs:
        a = t(spec.audio_key).permute(0, 3, 1, 2)  # (B, ears, F, T)
        if spec.audio_form == "level_ild":
            out["audio"] = _level_ild(a, spec.audio_key)
        else:
            mean = torch.tensor(spec.audio_mean).view(1, -1, 1, 1)
            std = torch.tensor(spec.audio_std).view(1, -1, 1, 1)
            out["audio"] = (a - mean) / std
    if "depth" in spec.inputs:
        d = _area(t(HEAD_DEPTH).clamp(0.0, DEPTH_MAX_M), spec.image_size)
        out["depth"] = (d - spec.depth_mean) / spec.depth_std
    if "wrist_depth" in spec.inputs:
        w = _area(t(WRIST_DEPTH).clamp(0.0, DEPTH_MAX_M), spec.image_size)
        out["wrist_depth"] = (w - spec.wrist_mean) / spec.wrist_std
    for name in ("image", "rgb"):
        if name in spec.inputs:
            im = _area(t(spec.image_key), spec.image_size)
            out[name] = (im - torch.tensor(spec.rgb_mean).view(1, 3, 1, 1)) / torch.tensor(spec.rgb_std).view(1, 3, 1, 1)
    if spec.state_names or "target" in spec.inputs:
        st = t(STATE)
    if spec.state_names:
        idx = [STATE_NAMES.index(n) for n in spec.state_names]
        v = (st[:, idx] - torch.tensor(spec.state_mean)) / torch.tensor(spec.state_std)
        if "base_yaw" in spec.state_names:  # an angle: give its sine and cosine, not the wrapped value
            j = spec.state_names.index("base_yaw")
            yaw = st[:, YAW]
            v = torch.cat([v[:, :j], torch.sin(yaw)[:, None], torch.cos(yaw)[:, None], v[:, j + 1 :]], dim=1)
        out["state"] = v
    if "target" in spec.inputs:
        if goal is None:
            raise FeatureError("the model reads a target position but none was given (the observation's goal pose)")
        out["target"] = goal_features(st, torch.as_tensor(goal, dtype=torch.float32))
    if "kind" in spec.inputs:
        if kind is None:
            raise FeatureError("the model reads the target kind but none was given (info['target_kind'])")
        k = torch.as_tensor(kind, dtype=torch.long).reshape(-1)
        out["kind"] = torch.zeros(len(k), max(len(spec.kinds), 1))
        known = k >= 0
        out["kind"][known, k[known]] = 1.0
    for col, p in spec.privileged.items():
        v = t(col).reshape(len(t(col)), -1)
        out[col.replace(".", "__")] = (v - torch.tensor(p["mean"])) / torch.tensor(p["std"])
    return out


def single(obs: Mapping[str, Any], spec: FeatureSpec) -> dict[str, np.ndarray]:
    """One observation dict (dataset keys) -> a batch of one in the loaders' form."""
    missing = [c for c in spec.columns if c not in obs]
    if missing:
        raise FeatureError(f"observation lacks {missing}; it has {sorted(obs)}")
    return {c: canonical(c, obs[c])[None] for c in spec.columns}
