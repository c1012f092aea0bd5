"""Encoding one finished episode: its steps' images (PNG), arrays and rows (Arrow), its audio (WAV).

`encode_episode` runs in a worker: it validates an `EpisodeResult` against the recipe's
`StepLayout`, encodes the images and audio, builds the episode's step rows and summarises their
statistics. Nothing here depends on time, host or worker identity, so the same episode always
gives the same bytes.
"""

from __future__ import annotations

import hashlib
import io
import struct
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa

from echo_data.dataset import stats as stats_mod
from echo_data.dataset.schema import (
    ACTION,
    ACTION_EE,
    ACTION_EE_EXECUTED,
    ACTION_EXECUTED,
    CAMERA_POSES,
    CHAIN_SLOTS,
    IMAGE_TYPE,
    MEL,
    POSE_DIM,
    SKILL_STOP,
    SPECTROGRAM,
    STATE,
    VECTOR_COLUMNS,
    StepLayout,
    array3d_column,
    audio_relpath,
    task_index,
)
from echo_data.pcm import as_written, quantise
from echo_data.records import PRIVILEGED_COLUMNS, EpisodeResult, StepRecord

PNG_COMPRESS_LEVEL = 1  # the build is CPU-bound; zlib 1 is several times faster than 6
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
WAV_SUBTYPE = "PCM_16"  # no PEAK chunk (libsndfile stamps float WAVs with the time)
PLANNER_AUDIO_SECONDS = 3.0
PLANNER_SAMPLE_RATE = 16000  # Qwen2.5-Omni takes 16 kHz mono only
PLANNER_BINAURAL_SECONDS = 1.0  # the first second, both ears: what the learned planner hears (frame 0)
_RECORD_IMAGE_ATTR = {
    "observation.images.head_rgb": "head_rgb",
    "observation.images.head_depth": "head_depth",
    "observation.images.wrist_depth": "wrist_depth",
}


def encode_png(image: np.ndarray) -> bytes:
    """uint8 (H, W, 3) RGB or uint16 (H, W) depth in millimetres -> PNG bytes (16-bit for depth).

    Written directly (IHDR, one IDAT, IEND): every row with the PNG "Sub" filter (each byte minus
    the same byte of the pixel to its left), deflated at zlib level 1. Pillow's encoder tries all
    five filters on every row, which made PNG encoding a tenth of the build; one fixed filter is
    3-4x faster for the same size on rendered frames, and any PNG reader (Pillow, so HF `datasets`
    and LeRobot) decodes it to the same pixels.
    """
    img = np.asarray(image)
    if img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3:
        rows, depth, colour, bpp = img.reshape(img.shape[0], -1), 8, 2, 3
    elif img.dtype == np.uint16 and img.ndim == 2:
        rows, depth, colour, bpp = img.astype(">u2").view(np.uint8), 16, 0, 2
    else:
        raise ValueError(f"unsupported image: dtype {image.dtype}, shape {image.shape}")
    h, w = img.shape[:2]
    filtered = np.empty((h, rows.shape[1] + 1), dtype=np.uint8)
    filtered[:, 0] = 1  # filter type Sub
    filtered[:, 1 : 1 + bpp] = rows[:, :bpp]
    np.subtract(rows[:, bpp:], rows[:, :-bpp], out=filtered[:, 1 + bpp :])  # modulo 256

    def chunk(tag: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + tag + payload + struct.pack(">I", zlib.crc32(tag + payload))

    header = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    return _PNG_SIGNATURE + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(filtered.tobytes(), PNG_COMPRESS_LEVEL)) + chunk(b"IEND", b"")


def decode_png(data: bytes | dict[str, Any], rgb: bool = False) -> np.ndarray:
    """PNG bytes (or a Hugging Face Image cell {"bytes": ...}) -> the stored pixels: uint8 (H, W, 3)
    RGB or uint16 (H, W) depth in millimetres (`rgb`: converted to 3-channel RGB whatever it
    holds). The package's one PNG reader (training, loaders, exports and viewers decode through
    it), so a stored frame means one thing everywhere."""
    from PIL import Image

    raw = data["bytes"] if isinstance(data, dict) else data
    with Image.open(io.BytesIO(raw)) as im:
        return np.asarray(im.convert("RGB") if rgb else im)


def decode_pngs(cells: list[Any]) -> np.ndarray:
    """A column's PNG cells -> (n, H, W[, 3]) stacked pixels."""
    return np.stack([decode_png(c) for c in cells])


def encode_wav(audio: np.ndarray, sample_rate: int, what: str = "audio") -> bytes:
    """float (n, channels) -> 16-bit PCM WAV bytes; ClippingError if it would clip (see pcm)."""
    import soundfile as sf

    buf = io.BytesIO()
    sf.write(buf, quantise(audio, what), sample_rate, subtype=WAV_SUBTYPE, format="WAV")
    return buf.getvalue()


def _at_planner_rate(x: np.ndarray, sample_rate: int) -> np.ndarray:
    """Resampled along time (axis 0) to the planner export's 16 kHz."""
    if sample_rate == PLANNER_SAMPLE_RATE:
        return x
    from math import gcd

    from scipy.signal import resample_poly

    g = gcd(PLANNER_SAMPLE_RATE, sample_rate)
    return resample_poly(x, PLANNER_SAMPLE_RATE // g, sample_rate // g, axis=0)


def planner_audio(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """The first seconds heard, as 16 kHz mono (mean of the two ears)."""
    head = np.asarray(audio[: int(round(PLANNER_AUDIO_SECONDS * sample_rate))], dtype=np.float64)
    mono = head.mean(axis=1) if head.ndim == 2 else head
    return _at_planner_rate(mono, sample_rate).astype(np.float32)


def planner_binaural(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """The first second heard, both ears (left, right) at 16 kHz: the window frame 0's features
    look at, what the learned planner decides from. Interaural time and level differences (where
    the source is) survive here; the mono clip averages them away."""
    head = np.asarray(audio[: int(round(PLANNER_BINAURAL_SECONDS * sample_rate))], dtype=np.float64)
    return _at_planner_rate(head, sample_rate).astype(np.float32)


def planner_wav_bytes(audio: np.ndarray, sample_rate: int) -> bytes:
    """The planner export's clip of an episode track (as written: validate recomputes it from the WAV)."""
    return encode_wav(planner_audio(audio, sample_rate)[:, None], PLANNER_SAMPLE_RATE, "planner audio")


def planner_binaural_wav_bytes(audio: np.ndarray, sample_rate: int) -> bytes:
    """The planner export's binaural first second (2 channels; validate recomputes it from the WAV)."""
    return encode_wav(planner_binaural(audio, sample_rate), PLANNER_SAMPLE_RATE, "planner binaural audio")


@dataclass
class EncodedEpisode:
    """A complete episode as bytes, plus what the manifest needs about every attempt."""

    split: str
    index: int
    episode_id: str
    table_ipc: bytes  # step rows (StepLayout.episode_schema), Arrow IPC stream
    wav: bytes
    planner_wav: bytes | None
    planner_png: bytes | None
    planner_binaural_wav: bytes | None
    episode: dict[str, Any]  # row of meta/episodes.parquet (shard fields filled later)
    stats: dict[str, dict[str, Any]]  # feature -> summary (see stats.py)
    failures: list[dict[str, Any]] = field(default_factory=list)  # failed attempts before success
    rejected: dict[str, int] = field(default_factory=dict)  # sampling rejections by reason
    skills: dict[str, list[int]] = field(default_factory=dict)  # skill -> [attempts, successes]

    def meta(self) -> dict[str, Any]:
        """Everything but the bulky bytes (stored as the episode's commit marker)."""
        return {
            "split": self.split,
            "index": self.index,
            "episode_id": self.episode_id,
            "episode": self.episode,
            "stats": self.stats,
            "failures": self.failures,
            "rejected": self.rejected,
            "skills": self.skills,
        }


def _spec_row(spec: Any) -> dict[str, Any]:
    return {
        "episode_index": int(spec.index),
        "episode_id": str(spec.episode_id),
        "split": str(spec.split),
        "setting": str(spec.setting),
        "task_index": task_index(spec.setting),
        "seed": int(spec.seed),
        "attempt": int(spec.attempt),
        "scene_seed": int(getattr(spec.plan, "seed", spec.seed)),
        "start": [float(v) for v in spec.start],
        "events": [
            {
                "category": e.category,
                "sound_id": e.sound_id,
                "priority": int(e.priority),
                "target": e.target,
                "source": [float(v) for v in e.source],
                "level_db": spec.source_level(k),
            }
            for k, e in enumerate(spec.events)
        ],
        "chain": [
            {"skill": c.skill, "target": c.target, "event": int(c.event), "target_kind": target_kind(c.target, spec.plan)}
            for c in spec.chain
        ],
    }


def target_kind(target: str, plan: Any) -> str:
    """What a listener would call a scene target: "phone_0" -> phone, "door:1" -> door,
    "faucet:0" -> sink, "furniture:3" -> its kind (table, counter, ...)."""
    from echo_data.target import Target

    return Target.parse(target).spoken(plan)


def _check_stack(name: str, arr: np.ndarray | None, n: int, shape: tuple[int, ...]) -> np.ndarray:
    if arr is None:
        raise ValueError(f"episode has no {name} but the recipe stores it")
    arr = np.asarray(arr)
    if arr.shape != (n, *shape):
        raise ValueError(f"{name} has shape {arr.shape}, expected {(n, *shape)}")
    return arr


def _step_vector(s: StepRecord, col: str) -> np.ndarray | None:
    """A step's value of a fixed-length vector column (None where the record has none)."""
    got = {
        ACTION: s.action, ACTION_EXECUTED: s.action_executed, ACTION_EE: s.action_ee, ACTION_EE_EXECUTED: s.action_ee_executed,
        STATE: s.state,
    }
    return got[col] if col in got else s.privileged.get(col)


def _vector_stack(episode_id: str, steps: list[StepRecord], col: str, dim: int) -> np.ndarray:
    """(n, dim) float32 of a vector column over an episode, or ValueError naming the column."""
    rows = []
    for s in steps:
        v = _step_vector(s, col)
        if v is None:
            raise ValueError(f"{episode_id}: frame {s.frame_index} has no {col}")
        v = np.asarray(v, dtype=np.float32)
        if v.shape != (dim,):
            raise ValueError(f"{episode_id}: {col} has shape {v.shape} at frame {s.frame_index}, expected ({dim},)")
        rows.append(v)
    return np.stack(rows)


def encode_episode(result: EpisodeResult, layout: StepLayout) -> EncodedEpisode:
    """Validate a complete (successful or cut) `EpisodeResult` against the layout and encode it (runs in workers).
    Long because each column is checked where it is encoded, in the stored order (one pass over the steps)."""
    spec = result.spec
    steps = result.steps
    n = len(steps)
    if n == 0:
        raise ValueError(f"{spec.episode_id}: episode has no steps")
    if result.audio is None or result.audio_offsets is None:
        raise ValueError(f"{spec.episode_id}: episode has no audio track / offsets")
    audio = np.asarray(result.audio, dtype=np.float32)
    if audio.ndim != 2 or audio.shape[1] != 2:
        raise ValueError(f"{spec.episode_id}: audio must be (n_samples, 2), got {audio.shape}")
    offsets = np.asarray(result.audio_offsets, dtype=np.int64)
    if offsets.shape != (n,) or (offsets < 0).any() or (offsets > len(audio)).any():
        raise ValueError(f"{spec.episode_id}: audio_offsets must be ({n},) within [0, {len(audio)}]")

    vectors = {col: _vector_stack(spec.episode_id, steps, col, dim) for col, dim in VECTOR_COLUMNS.items()}
    privileged = {col: _vector_stack(spec.episode_id, steps, col, dim) for col, dim in PRIVILEGED_COLUMNS.items()}
    action, executed, state = vectors[ACTION], vectors[ACTION_EXECUTED], vectors[STATE]

    chain_len = len(spec.chain)
    if chain_len > CHAIN_SLOTS:
        raise ValueError(f"{spec.episode_id}: chain of {chain_len} skills exceeds the {CHAIN_SLOTS} skill_success slots")
    cols: dict[str, pa.Array] = {
        "episode_index": pa.array(np.full(n, spec.index, dtype=np.int64)),
        "frame_index": pa.array(np.array([s.frame_index for s in steps], dtype=np.int64)),
        "timestamp": pa.array(np.array([s.timestamp for s in steps], dtype=np.float32)),
        "task_index": pa.array(np.full(n, task_index(spec.setting), dtype=np.int64)),
        "setting": pa.array([spec.setting] * n, pa.string()),
        "skill": pa.array([s.skill for s in steps], pa.string()),
        "skill_index": pa.array(np.array([s.skill_index for s in steps], dtype=np.int64)),
    }
    for col, vec in (vectors | privileged).items():
        cols[col] = pa.FixedSizeListArray.from_arrays(pa.array(vec.reshape(-1)), vec.shape[1])
    if not np.array_equal(cols["frame_index"].to_numpy(), np.arange(n)):
        raise ValueError(f"{spec.episode_id}: frame_index must run 0..{n - 1}")

    image_stacks: dict[str, tuple[str, np.ndarray]] = {}
    for col, (kind, h, w) in layout.images.items():
        attr = _RECORD_IMAGE_ATTR[col]
        frames = [getattr(s, attr) for s in steps]
        if any(f is None for f in frames):
            raise ValueError(f"{spec.episode_id}: a step has no {attr} but the recipe stores it")
        shape = (h, w, 3) if kind == "rgb" else (h, w)
        dtype = np.uint8 if kind == "rgb" else np.uint16
        stack = np.stack(frames)
        if stack.shape != (n, *shape) or stack.dtype != dtype:
            raise ValueError(f"{spec.episode_id}: {attr} is {stack.dtype}{stack.shape[1:]}, expected {np.dtype(dtype)}{shape}")
        image_stacks[col] = (kind, stack)
        cols[col] = pa.array([{"bytes": encode_png(f), "path": None} for f in stack], IMAGE_TYPE)

    array_stacks: dict[str, np.ndarray] = {}
    sources = {SPECTROGRAM: result.spectrogram, MEL: result.mel}
    for col, shape in layout.arrays.items():
        stack = _check_stack(col, sources[col], n, shape).astype(np.float32)
        array_stacks[col] = stack
        cols[col] = array3d_column(stack)

    for cam in layout.cameras:
        if any(cam not in s.camera_poses for s in steps):
            raise ValueError(f"{spec.episode_id}: a step has no {cam} camera pose but the recipe stores the camera")
        poses = np.stack([np.asarray(s.camera_poses[cam], dtype=np.float32).reshape(POSE_DIM) for s in steps])
        cols[CAMERA_POSES[cam]] = pa.FixedSizeListArray.from_arrays(pa.array(poses.reshape(-1)), POSE_DIM)
    audio_path = audio_relpath(spec.split, spec.episode_id)
    cols["audio_path"] = pa.array([audio_path] * n, pa.string())
    cols["audio_sample_rate"] = pa.array(np.full(n, layout.sample_rate, dtype=np.int64))
    cols["audio_offset"] = pa.array(offsets)
    cols["done"] = pa.array(np.array([bool(s.done) for s in steps]))
    flags = [bool(v) for s in steps for v in (tuple(s.skill_success)[:chain_len] + (False,) * CHAIN_SLOTS)[:CHAIN_SLOTS]]
    cols["skill_success"] = pa.FixedSizeListArray.from_arrays(pa.array(flags, pa.bool_()), CHAIN_SLOTS)
    cols[SKILL_STOP] = pa.array(np.array([bool(s.skill_stop) for s in steps], dtype=np.int8))
    schema = layout.episode_schema()
    table = pa.Table.from_arrays([cols[f.name] for f in schema], schema=schema)
    sink = io.BytesIO()
    with pa.ipc.new_stream(sink, schema) as w:
        w.write_table(table)

    audio = as_written(audio, f"{spec.episode_id} audio")  # what the WAV holds (and the planner clip is cut from)
    wav = encode_wav(audio, layout.sample_rate, f"{spec.episode_id} audio")
    row = _spec_row(spec)
    row.update(
        {
            "outcomes": [o.to_dict() for o in result.outcomes],
            "success": bool(result.success),
            "truncated_at": None if result.truncated_at is None else int(result.truncated_at),
            "n_steps": n,
            "audio_path": audio_path,
            "audio_samples": int(len(audio)),
            "audio_sha256": hashlib.sha256(wav).hexdigest(),
        }
    )
    values = stats_mod.episode_feature_values(action, state, image_stacks, array_stacks, executed, {**vectors, **privileged})
    summaries = {k: stats_mod.summarize(v, n) for k, v in values.items()}

    planner_png = None
    if steps[0].head_rgb is not None:
        planner_png = encode_png(np.asarray(steps[0].head_rgb, dtype=np.uint8))
    planner_wav = planner_wav_bytes(audio, layout.sample_rate)
    planner_binaural_wav = planner_binaural_wav_bytes(audio, layout.sample_rate)
    return EncodedEpisode(
        split=spec.split,
        index=int(spec.index),
        episode_id=spec.episode_id,
        table_ipc=sink.getvalue(),
        wav=wav,
        planner_wav=planner_wav,
        planner_png=planner_png,
        planner_binaural_wav=planner_binaural_wav,
        episode=row,
        stats=summaries,
    )


def read_ipc(data: bytes) -> pa.Table:
    return pa.ipc.open_stream(pa.py_buffer(data)).read_all()
