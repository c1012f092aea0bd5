"""The on-disk layout of a dataset: column names, Arrow schemas and Hugging Face features.

One `StepLayout` is derived from the recipe before anything runs, so every shard of a build
has the same schema (and the same bytes whatever the worker count). The Hugging Face features
are embedded as schema metadata (`huggingface` -> {"info": {"features": ...}}) so that
`datasets.load_dataset("parquet", ...)` decodes images and arrays with no extra code.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa

from echo_data.recipe import SETTINGS, Recipe
from echo_data.records import ACTION_DIM, EE_ACTION_DIM, PRIVILEGED_COLUMNS, PRIVILEGED_PREFIX, STATE_DIM

# echo-data/2: fixed-length `skill_success`, per-step `audio_path` / `audio_sample_rate`, per-step
# camera poses (`camera_pose.head` / `camera_pose.wrist`), `action.executed`.
# echo-data/3: the end-effector action form (`action.ee`, `action.ee.executed`), the privileged
# observations (`observation.privileged.*`) and `skill_stop`.
FORMAT_VERSION = "echo-data/3"
# Rows per Parquet row group: fixed so shard bytes never depend on how a build ran; small
# enough that random access from a DataLoader decodes little more than it needs.
ROW_GROUP_ROWS = 64
PARQUET_COMPRESSION = "zstd"
PARQUET_COMPRESSION_LEVEL = 3
# Metadata key (in each shard's Parquet schema) holding that shard's episode records and
# partial statistics, so a shard is self-describing and meta/ can be rebuilt from data/.
SHARD_META_KEY = "echo_data"

# The observation-key vocabulary: the environment, the agents, the evaluation and every
# file of a dataset name observations with these keys and no others.
IMAGE_PREFIX = "observation.images."
AUDIO_PREFIX = "observation.audio."
IMAGE_COLUMNS = {name: IMAGE_PREFIX + name for name in ("head_rgb", "head_depth", "wrist_depth")}
SPECTROGRAM = AUDIO_PREFIX + "spectrogram"
MEL = AUDIO_PREFIX + "mel"
BINAURAL = AUDIO_PREFIX + "binaural"  # the raw block of one step: observed, never stored
ACTION = "action"
# What the robot executed at the step: `action` plus the experts' DART noise (`experts.action_noise`;
# equal to `action` without noise). Replaying these reproduces the episode; `action` is the label.
ACTION_EXECUTED = "action.executed"
# The same two commands in end-effector form (echo_data.records.EE_ACTION_NAMES,
# docs/action_spaces.md); replaying `action.ee.executed` in the env's ee mode reproduces the episode.
ACTION_EE = "action.ee"
ACTION_EE_EXECUTED = "action.ee.executed"
STATE = "observation.state"
# Fixed-length float32 vector columns of every step row, in schema order, and their lengths.
VECTOR_COLUMNS: dict[str, int] = {
    ACTION: ACTION_DIM, ACTION_EXECUTED: ACTION_DIM, ACTION_EE: EE_ACTION_DIM, ACTION_EE_EXECUTED: EE_ACTION_DIM, STATE: STATE_DIM,
}
# Privileged observations (echo_data.records.PRIVILEGED_COLUMNS): flagged `privileged: true` in
# their Hugging Face feature and the LeRobot export; no loader's default inputs hold them.
PRIVILEGED = PRIVILEGED_PREFIX
# 1 on the last row of each skill segment: the expert ended the skill after this row's action
# (a learned skill's STOP label, as SoundSpaces' stop action).
SKILL_STOP = "skill_stop"


def is_privileged(column: str) -> bool:
    """A column only a simulator can fill (never a default input of a learner)."""
    return column.startswith(PRIVILEGED_PREFIX)
# Per-step world pose of each camera: row-major 4x4 camera-to-world matrix, OpenCV axes
# (x right, y down, z forward = the depth axis), flattened to 16 float32.
CAMERA_POSES = {"head": "camera_pose.head", "wrist": "camera_pose.wrist"}
POSE_DIM = 16
# Chain slots of `skill_success`: the sampler chains at most one relocation event (Navigate,
# Pick, Place) and one state event (Navigate, OpenDoor|CloseSink). Fixed so the default
# PyTorch collate stacks the column; unused slots are False.
CHAIN_SLOTS = 5
IMAGE_TYPE = pa.struct([("bytes", pa.binary()), ("path", pa.string())])
_HF_ARRAY3D_NAME = "datasets.features.features.Array3DExtensionType"


class HfArray3D(pa.ExtensionType):
    """Arrow type written exactly as `datasets.Array3D` stores itself (same extension name and
    serialisation), so `datasets` decodes the column as Array3D; pyarrow-only readers see the
    nested-list storage. Never registered here, to avoid clashing with `datasets`' own type."""

    def __init__(self, shape: tuple[int, ...], dtype: str = "float32") -> None:
        self.shape = tuple(int(s) for s in shape)
        self.value_type = dtype
        storage: pa.DataType = pa.from_numpy_dtype(np.dtype(dtype))
        for _ in self.shape:
            storage = pa.list_(storage)
        super().__init__(storage, _HF_ARRAY3D_NAME)

    def __arrow_ext_serialize__(self) -> bytes:
        return json.dumps((list(self.shape), self.value_type)).encode()

    @classmethod
    def __arrow_ext_deserialize__(cls, storage_type: pa.DataType, serialized: bytes) -> HfArray3D:
        shape, dtype = json.loads(serialized)
        return cls(tuple(shape), dtype)


@dataclass(frozen=True)
class StepLayout:
    """What a step row holds for one recipe: fixed before the build starts."""

    fps: int
    sample_rate: int
    images: dict[str, tuple[str, int, int]] = field(default_factory=dict)  # column -> (kind, H, W)
    spectrogram_shape: tuple[int, int, int] | None = None
    mel_shape: tuple[int, int, int] | None = None
    cameras: tuple[str, ...] = ()  # cameras whose pose is stored ("head", "wrist")

    @staticmethod
    def from_recipe(recipe: Recipe) -> StepLayout:
        obs = set(recipe.outputs.observations)
        head, wrist = recipe.robot.head_camera, recipe.robot.wrist_camera
        images: dict[str, tuple[str, int, int]] = {}
        if "head_rgb" in obs and head.rgb:
            images[IMAGE_COLUMNS["head_rgb"]] = ("rgb", head.height, head.width)
        if "head_depth" in obs and head.depth:
            images[IMAGE_COLUMNS["head_depth"]] = ("depth", head.height, head.width)
        if "wrist_depth" in obs and wrist.depth:
            images[IMAGE_COLUMNS["wrist_depth"]] = ("depth", wrist.height, wrist.width)
        sr = recipe.acoustics.sample_rate
        # SoundSpaces features over the last 1 s: STFT n_fft 512, hop 160 (centred) -> frames.
        frames = 1 + sr // 160
        spec = (math.ceil(257 / 4), math.ceil(frames / 4), 2) if "spectrogram" in obs else None
        mel = (recipe.acoustics.mel_bands, frames, 2) if "mel" in obs else None
        cams = tuple(c for c, col in (("head", "head_rgb"), ("head", "head_depth"), ("wrist", "wrist_depth")) if IMAGE_COLUMNS[col] in images)
        return StepLayout(recipe.robot.control_hz, sr, images, spec, mel, tuple(dict.fromkeys(cams)))

    @property
    def pose_columns(self) -> list[str]:
        """Camera pose columns (one per stored camera)."""
        return [CAMERA_POSES[c] for c in self.cameras]

    @property
    def arrays(self) -> dict[str, tuple[int, int, int]]:
        """Fixed-shape float32 array columns and their shapes."""
        out: dict[str, tuple[int, int, int]] = {}
        if self.spectrogram_shape:
            out[SPECTROGRAM] = self.spectrogram_shape
        if self.mel_shape:
            out[MEL] = self.mel_shape
        return out

    def hf_features(self) -> dict[str, Any]:
        """The `datasets.Features` dict (as `Features.to_dict()` writes it) of a step row."""
        v = lambda dtype: {"dtype": dtype, "_type": "Value"}  # noqa: E731
        feats: dict[str, Any] = {
            "episode_index": v("int64"),
            "frame_index": v("int64"),
            "index": v("int64"),
            "timestamp": v("float32"),
            "task_index": v("int64"),
            "setting": v("string"),
            "skill": v("string"),
            "skill_index": v("int64"),
        }
        for col, n in VECTOR_COLUMNS.items():
            feats[col] = {"feature": v("float32"), "length": n, "_type": "List"}
        for col in self.images:
            feats[col] = {"_type": "Image"}
        for col, shape in self.arrays.items():
            feats[col] = {"shape": list(shape), "dtype": "float32", "_type": "Array3D"}
        for col in self.pose_columns:
            feats[col] = {"feature": v("float32"), "length": POSE_DIM, "_type": "List"}
        feats["audio_path"] = v("string")
        feats["audio_sample_rate"] = v("int64")
        feats["audio_offset"] = v("int64")
        feats["done"] = v("bool")
        feats["skill_success"] = {"feature": v("bool"), "length": CHAIN_SLOTS, "_type": "List"}
        feats[SKILL_STOP] = v("int8")
        for col, n in PRIVILEGED_COLUMNS.items():
            feats[col] = {"feature": v("float32"), "length": n, "_type": "List"}
        return feats

    @staticmethod
    def privileged_columns() -> list[str]:
        """The privileged step columns (flagged in the schema metadata, the card and the LeRobot export)."""
        return list(PRIVILEGED_COLUMNS)

    def schema(self) -> pa.Schema:
        """Arrow schema of a shard, with the Hugging Face features embedded."""
        fields = [
            pa.field("episode_index", pa.int64()),
            pa.field("frame_index", pa.int64()),
            pa.field("index", pa.int64()),
            pa.field("timestamp", pa.float32()),
            pa.field("task_index", pa.int64()),
            pa.field("setting", pa.string()),
            pa.field("skill", pa.string()),
            pa.field("skill_index", pa.int64()),
        ]
        fields += [pa.field(col, pa.list_(pa.float32(), n)) for col, n in VECTOR_COLUMNS.items()]
        fields += [pa.field(col, IMAGE_TYPE) for col in self.images]
        fields += [pa.field(col, HfArray3D(shape)) for col, shape in self.arrays.items()]
        fields += [pa.field(col, pa.list_(pa.float32(), POSE_DIM)) for col in self.pose_columns]
        fields += [
            pa.field("audio_path", pa.string()),
            pa.field("audio_sample_rate", pa.int64()),
            pa.field("audio_offset", pa.int64()),
            pa.field("done", pa.bool_()),
            pa.field("skill_success", pa.list_(pa.bool_(), CHAIN_SLOTS)),
            pa.field(SKILL_STOP, pa.int8()),
        ]
        fields += [
            pa.field(col, pa.list_(pa.float32(), n), metadata={b"privileged": b"true"}) for col, n in PRIVILEGED_COLUMNS.items()
        ]
        meta = {
            "huggingface": json.dumps({"info": {"features": self.hf_features()}}, sort_keys=False),
            "echo_data.privileged": json.dumps(self.privileged_columns()),
        }
        return pa.schema(fields, metadata=meta)

    def episode_schema(self) -> pa.Schema:
        """Schema of one episode's rows before the global `index` is known (intermediate files)."""
        s = self.schema()
        return s.remove(s.get_field_index("index")).remove_metadata()

    @staticmethod
    def from_dict(d: dict[str, Any]) -> StepLayout:
        """The layout as the manifest stores it (readers need no recipe validation)."""
        return StepLayout(
            fps=int(d["fps"]),
            sample_rate=int(d["sample_rate"]),
            images={k: (v[0], int(v[1]), int(v[2])) for k, v in d["images"].items()},
            spectrogram_shape=tuple(d["spectrogram_shape"]) if d.get("spectrogram_shape") else None,
            mel_shape=tuple(d["mel_shape"]) if d.get("mel_shape") else None,
            cameras=tuple(d.get("cameras", ())),
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "fps": self.fps,
            "sample_rate": self.sample_rate,
            "images": {k: list(v) for k, v in self.images.items()},
            "spectrogram_shape": list(self.spectrogram_shape) if self.spectrogram_shape else None,
            "mel_shape": list(self.mel_shape) if self.mel_shape else None,
            "cameras": list(self.cameras),
        }


def task_index(setting: str) -> int:
    """Stable integer id of a setting (LeRobot's `task_index`)."""
    return SETTINGS.index(setting)


def audio_relpath(split: str, episode_id: str) -> str:
    """Where an episode's binaural WAV lives, relative to the dataset root."""
    return f"audio/{split}/{episode_id}.wav"


def shard_name(split: str, i: int, n: int) -> str:
    return f"{split}-{i:05d}-of-{n:05d}.parquet"


def array3d_column(values: np.ndarray) -> pa.ExtensionArray:
    """(n, a, b, c) float32 -> an Array3D column (nested lists built from offsets, no copies)."""
    values = np.ascontiguousarray(values, dtype=np.float32)
    arr: pa.Array = pa.array(values.reshape(-1))
    for d in reversed(values.shape[1:]):
        count = len(arr) // d
        arr = pa.ListArray.from_arrays(pa.array(np.arange(0, count * d + 1, d, dtype=np.int32)), arr)
    return pa.ExtensionArray.from_storage(HfArray3D(values.shape[1:]), arr)


def column_to_numpy(col: pa.ChunkedArray | pa.Array, shape: tuple[int, ...]) -> np.ndarray:
    """A fixed-shape list column (fixed-size lists or Array3D, any extension) -> (n, *shape)."""
    chunks = col.chunks if isinstance(col, pa.ChunkedArray) else [col]
    parts = []
    for chunk in chunks:
        if isinstance(chunk.type, pa.BaseExtensionType):
            chunk = chunk.storage
        for _ in shape:
            chunk = chunk.flatten()
        parts.append(chunk.to_numpy(zero_copy_only=False))
    flat = np.concatenate(parts) if parts else np.zeros(0, np.float32)
    return flat.reshape((-1, *shape))


# One chain entry's hand-over (`records.HandOverRecord`, docs/handover.md).
HANDOVER_FIELDS = pa.struct(
    [
        ("skill", pa.string()),
        ("index", pa.int64()),
        ("distance", pa.float64()),
        ("heading", pa.float64()),
        # (x, y, yaw); variable-size lists: a fixed-size list inside a null struct does not read back from Parquet
        ("end", pa.list_(pa.float64())),
        ("goal", pa.list_(pa.float64())),
        ("goal_distance", pa.float64()),
        ("heading_error", pa.float64()),
        ("inside", pa.bool_()),
        ("learner_stop", pa.bool_()),
    ]
)

EPISODE_FIELDS = pa.schema(
    [
        pa.field("episode_index", pa.int64()),
        pa.field("episode_id", pa.string()),
        pa.field("split", pa.string()),
        pa.field("setting", pa.string()),
        pa.field("task_index", pa.int64()),
        pa.field("seed", pa.int64()),
        pa.field("attempt", pa.int64()),
        pa.field("scene_seed", pa.int64()),
        pa.field("start", pa.list_(pa.float64(), 3)),
        pa.field(
            "events",
            pa.list_(
                pa.struct(
                    [
                        ("category", pa.string()),
                        ("sound_id", pa.string()),
                        ("priority", pa.int64()),
                        ("target", pa.string()),
                        ("source", pa.list_(pa.float64(), 3)),
                        ("level_db", pa.float64()),  # source level, dB SPL at 1 m
                    ]
                )
            ),
        ),
        pa.field(
            "chain",
            pa.list_(
                pa.struct([("skill", pa.string()), ("target", pa.string()), ("event", pa.int64()), ("target_kind", pa.string())])
            ),
        ),
        pa.field(
            "outcomes",
            pa.list_(
                pa.struct(
                    [
                        ("skill", pa.string()),
                        ("target", pa.string()),
                        ("success", pa.bool_()),
                        ("reason", pa.string()),
                        ("steps", pa.int64()),
                        # where the entry's drive handed over (records.HandOverRecord; null: it hands over to no stance)
                        ("handover", HANDOVER_FIELDS),
                    ]
                )
            ),
        ),
        pa.field("success", pa.bool_()),
        # steps after which the recipe's outputs.max_frames cut the episode (null: whole episode)
        pa.field("truncated_at", pa.int64()),
        pa.field("n_steps", pa.int64()),
        pa.field("audio_path", pa.string()),
        pa.field("audio_samples", pa.int64()),
        pa.field("audio_sha256", pa.string()),
        pa.field("shard", pa.string()),
        pa.field("dataset_from_index", pa.int64()),
        pa.field("dataset_to_index", pa.int64()),
    ]
)
