"""`echo-data export --format lerobot`: an echo-data dataset as a LeRobot (codebase v3.0) dataset.

LeRobot v3.0 keeps many episodes per Parquet file under `data/chunk-XXX/file-XXX.parquet`,
episode records under `meta/episodes/chunk-XXX/file-XXX.parquet`, the task strings in
`meta/tasks.parquet` (index = task, column `task_index`), normalisation statistics in
`meta/stats.json` and the schema in `meta/info.json`. Episodes are numbered across the whole
dataset (train first, then val, test), `index` counts frames over the whole dataset, and the
echo-data splits become LeRobot's `splits` ("start:end" episode ranges).

Cameras are image features (PNG bytes in the Parquet rows, as echo-data stores them), not
MP4 videos: depth is 16-bit millimetres, which 8-bit yuv420p H.264 cannot hold without loss;
the PNG bytes are copied as they are (the frames a LeRobot user reads are the exact frames of
the echo-data rows); and image features decode with PIL alone, with no video decoder.

Audio: LeRobot has no audio feature. Each frame carries the echo-data audio columns
(`observation.audio.spectrogram` / `.mel` of the last second, `audio_path`, `audio_sample_rate`,
`audio_offset`); the episode WAVs are copied to `audio/{split}/{episode_id}.wav` (the path the
rows name, relative to the export root) and the episode records name them too.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset.manifest import ManifestError, load_manifest
from echo_data.dataset.schema import (
    ACTION,
    ACTION_EXECUTED,
    CAMERA_POSES,
    CHAIN_SLOTS,
    PARQUET_COMPRESSION,
    ROW_GROUP_ROWS,
    STATE,
    StepLayout,
)
from echo_data.dataset.shards import conform
from echo_data.dataset.storage import atomic_write_json, canonical_json, fsync_dir
from echo_data.episode import SPLIT_KEYS
from echo_data.recipe import SETTINGS
from echo_data.records import ACTION_NAMES, STATE_NAMES

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000  # files per chunk folder (LeRobot's default)
DATA_FILES_SIZE_IN_MB = 100  # a data file is closed once its rows reach this size
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
ROBOT_TYPE = "echo_data_fetchlike"
# The natural-language task of each setting (LeRobot's `task`; index = echo-data's task_index).
TASKS = {
    "object_relocation": "Find the sounding object, pick it up and put it where it belongs.",
    "state_transition": "Attend to the sound: open the door for the doorbell or turn off the running faucet.",
    "multi_event": "Handle every sound event in order of priority.",
}


class ExportError(ValueError):
    """Bad input for an export (not a complete dataset, output exists): exit 2, nothing written."""


def _names(layout: StepLayout) -> dict[str, list[str]]:
    """Element names of the vector features (LeRobot's `names`)."""
    names: dict[str, list[str]] = {ACTION: list(ACTION_NAMES), ACTION_EXECUTED: list(ACTION_NAMES), STATE: list(STATE_NAMES)}
    names.update({col: [f"T{r}{c}" for r in range(4) for c in range(4)] for col in CAMERA_POSES.values()})
    names["skill_success"] = [f"chain_{k}" for k in range(CHAIN_SLOTS)]
    names.update({col: ["frequency", "time", "ear"] for col in layout.arrays})
    return names


def lerobot_features(layout: StepLayout) -> dict[str, dict[str, Any]]:
    """meta/info.json `features`: every step column with dtype, shape and names, in row order,
    derived from the step schema's Hugging Face features (so new columns export too)."""
    names = _names(layout)
    feats: dict[str, dict[str, Any]] = {}
    for col, f in layout.hf_features().items():
        kind = f["_type"]
        if kind == "Value":
            feats[col] = {"dtype": f["dtype"], "shape": [1], "names": None}
        elif kind == "List" and "length" in f:
            feats[col] = {"dtype": f["feature"]["dtype"], "shape": [f["length"]], "names": names.get(col)}
        elif kind == "Array3D":
            feats[col] = {"dtype": f["dtype"], "shape": list(f["shape"]), "names": names.get(col)}
        elif kind == "Image":
            img_kind, h, w = layout.images[col]
            feats[col] = {
                "dtype": "image",
                "shape": [h, w, 3 if img_kind == "rgb" else 1],
                "names": ["height", "width", "channels"],
                "info": {"format": "PNG", "unit": "8-bit RGB" if img_kind == "rgb" else "16-bit depth, millimetres along the optical axis, 0 = nothing hit"},
            }
        else:  # LeRobot features have fixed shapes
            raise ExportError(f"column {col!r} ({kind} without a fixed length) has no LeRobot feature")
    return feats


def lerobot_stats(stats: dict[str, dict[str, list[float]]], layout: StepLayout) -> dict[str, dict[str, Any]]:
    """echo-data meta/stats.json -> LeRobot's: image statistics shaped (C, 1, 1) and in the units
    LeRobot returns (RGB in [0, 1] as in echo-data; depth in millimetres, as its 16-bit PNGs decode)."""
    out: dict[str, dict[str, Any]] = {}
    for col, st in stats.items():
        if col in layout.images:
            scale = 1.0 if layout.images[col][0] == "rgb" else 1000.0
            out[col] = {k: (v if k == "count" else [[[x * scale]] for x in v]) for k, v in st.items()}
        else:
            out[col] = dict(st)
    return out


def _check_source(src: Path) -> dict[str, Any]:
    try:
        manifest = load_manifest(src)
    except ManifestError as e:
        raise ExportError(str(e)) from None
    if not manifest.get("complete"):
        raise ExportError(f"{src}: the build is not complete (finish it with `echo-data build --resume`)")
    return manifest


def _data_files(src: Path, dst: Path, manifest: dict[str, Any], layout: StepLayout) -> tuple[list[dict[str, Any]], dict[str, str]]:
    """Step rows regrouped into LeRobot data files under `dst` (each written as soon as it is
    full, so memory holds one file's rows), one record per episode, and the splits."""
    schema = layout.schema()
    n_files = 0
    pending: list[pa.Table] = []
    pending_bytes = 0
    episodes: list[dict[str, Any]] = []
    splits: dict[str, str] = {}
    ep_meta = {(r["split"], r["episode_index"]): r for r in pq.read_table(src / "meta" / "episodes.parquet").to_pylist()}
    n_ep = n_rows = 0

    def close() -> None:
        nonlocal pending, pending_bytes, n_files
        if pending:
            path = dst / DATA_PATH.format(chunk_index=n_files // CHUNKS_SIZE, file_index=n_files % CHUNKS_SIZE)
            _write_parquet(path, pa.concat_tables(pending), ROW_GROUP_ROWS)
            pending, pending_bytes, n_files = [], 0, n_files + 1

    for split in sorted(manifest["splits"], key=SPLIT_KEYS.__getitem__):
        first_ep = n_ep
        for shard in (e for e in manifest["shards"] if e["split"] == split):
            table = pq.read_table(src / shard["file"])
            ep = table.column("episode_index").to_numpy()
            bounds = np.flatnonzero(np.diff(ep)) + 1
            for lo, hi in zip(np.concatenate([[0], bounds]), np.concatenate([bounds, [len(ep)]])):
                rows = table.slice(int(lo), int(hi - lo))
                row = ep_meta[(split, int(ep[lo]))]
                length = rows.num_rows
                for col, values in (("episode_index", np.full(length, n_ep)), ("index", np.arange(n_rows, n_rows + length))):
                    i = rows.schema.get_field_index(col)
                    rows = rows.set_column(i, col, pa.array(values.astype(np.int64)))
                if pending and pending_bytes + rows.nbytes > DATA_FILES_SIZE_IN_MB * 2**20:
                    close()
                pending.append(conform(rows, schema))
                pending_bytes += rows.nbytes
                k = n_files
                episodes.append(
                    {
                        "episode_index": n_ep,
                        "tasks": [TASKS[row["setting"]]],
                        "length": length,
                        "data/chunk_index": k // CHUNKS_SIZE,
                        "data/file_index": k % CHUNKS_SIZE,
                        "dataset_from_index": n_rows,
                        "dataset_to_index": n_rows + length,
                        "meta/episodes/chunk_index": 0,
                        "meta/episodes/file_index": 0,
                        "split": split,
                        "episode_id": row["episode_id"],
                        "setting": row["setting"],
                        "seed": row["seed"],
                        "success": row["success"],
                        "truncated": row.get("truncated_at") is not None,  # cut by outputs.max_frames after `length` frames
                        "audio_path": row["audio_path"],
                        "audio_sample_rate": int(manifest["audio"]["sample_rate"]),
                        "audio_samples": row["audio_samples"],
                        "audio_first_offset": int(rows.column("audio_offset")[0].as_py()),
                    }
                )
                n_ep += 1
                n_rows += length
        splits[split] = f"{first_ep}:{n_ep}"
    close()
    return episodes, splits


def _card(info: dict[str, Any], src_card: Path) -> str:
    """README.md of the export: LeRobot-style front matter, then the source dataset's card body."""
    import yaml

    from echo_data.dataset.card import LICENSE, size_category

    front = {
        "license": LICENSE,
        "task_categories": ["robotics"],
        "tags": ["LeRobot", "echo-data", "binaural-audio"],
        "size_categories": [size_category(info["total_frames"])],
        "configs": [{"config_name": "default", "data_files": "data/*/*.parquet"}],
    }
    body = src_card.read_text().split("---\n", 2)[-1] if src_card.is_file() else ""
    return (
        "---\n" + yaml.safe_dump(front, sort_keys=False) + "---\n\n"
        f"LeRobot {info['codebase_version']} export of an echo-data dataset: {info['total_episodes']} episodes, "
        f"{info['total_frames']} frames, splits {info['splits']} (episode ranges). Cameras are image features; "
        "the episode WAVs are under audio/ (see `echo_data` in meta/info.json). The original card follows.\n" + body
    )


def _write_parquet(path: Path, table: pa.Table, row_group: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, path, compression=PARQUET_COMPRESSION, row_group_size=row_group, store_schema=True)


def export_lerobot(src: str | Path, out: str | Path, overwrite: bool = False) -> dict[str, Any]:
    """Write the LeRobot v3.0 dataset of the echo-data dataset `src` to `out`; return meta/info.json.

    Everything is written to a temporary sibling folder first and renamed into place, so `out`
    is either absent, the old export or the whole new one. Raises `ExportError` on bad input."""
    try:
        import pandas as pd
    except ImportError:
        raise ExportError("the LeRobot export needs pandas: pip install pandas") from None
    src, out = Path(src), Path(out)
    manifest = _check_source(src)
    if out.exists() and not (overwrite and out.is_dir()):
        raise ExportError(f"{out} already exists" + ("; use --overwrite to replace it" if out.is_dir() else " and is not a folder"))
    if out.resolve() == src.resolve() or src.resolve() in out.resolve().parents:
        raise ExportError(f"--out {out} lies inside the source dataset {src}")
    layout = StepLayout.from_dict(manifest["layout"])
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        episodes, splits = _data_files(src, tmp, manifest, layout)
        _write_parquet(tmp / EPISODES_PATH.format(chunk_index=0, file_index=0), pa.Table.from_pylist(episodes), 4096)
        tasks = pd.DataFrame({"task_index": np.arange(len(SETTINGS), dtype=np.int64)}, index=pd.Index([TASKS[s] for s in SETTINGS], name="task"))
        (tmp / "meta").mkdir(parents=True, exist_ok=True)
        tasks.to_parquet(tmp / "meta" / "tasks.parquet")
        stats = lerobot_stats(json.loads((src / "meta" / "stats.json").read_text()), layout)
        atomic_write_json(tmp / "meta" / "stats.json", stats)
        src_info = json.loads((src / "meta" / "info.json").read_text())
        info = {
            "codebase_version": CODEBASE_VERSION,
            "robot_type": ROBOT_TYPE,
            "total_episodes": len(episodes),
            "total_frames": sum(e["length"] for e in episodes),
            "total_tasks": len(SETTINGS),
            "chunks_size": CHUNKS_SIZE,
            "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
            "video_files_size_in_mb": 200,
            "fps": layout.fps,
            "splits": splits,
            "data_path": DATA_PATH,
            "video_path": None,
            "features": lerobot_features(layout),
            "echo_data": {
                "source": manifest["name"],
                "recipe_hash": manifest["recipe_hash"],
                "format": manifest["format"],
                "cameras": src_info.get("cameras", {}),
                "audio": {
                    "sample_rate": layout.sample_rate,
                    "channels": 2,
                    "channel_0": "left",
                    "path": "audio/{split}/{episode_id}.wav (each row's audio_path; episode records' audio_path)",
                    "offset": "audio_offset: the sample at which the row's observation was taken",
                },
                "stats_split": src_info.get("stats_split", "train"),
                "cameras_as": "image features (PNG), not videos: 16-bit depth does not survive 8-bit video",
            },
        }
        atomic_write_json(tmp / "meta" / "info.json", info)
        (tmp / "README.md").write_text(_card(info, src / "README.md"))
        for e in episodes:
            dst = tmp / e["audio_path"]
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src / e["audio_path"], dst)
        (tmp / "echo_data_manifest.json").write_bytes(canonical_json({k: manifest[k] for k in ("name", "recipe_hash", "format", "versions", "counts")}))
        if out.exists():
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
        fsync_dir(out.parent)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return info
