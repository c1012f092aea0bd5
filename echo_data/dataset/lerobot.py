"""`echo-data export --format lerobot`: an echo-data dataset as a LeRobot (codebase v3.0) dataset.

LeRobot v3.0 keeps many episodes per Parquet file under `data/chunk-XXX/file-XXX.parquet`,
episode records (with per-episode `stats/*`) under `meta/episodes/chunk-XXX/file-XXX.parquet`,
the task strings in `meta/tasks.parquet` (index = task, column `task_index`), normalisation
statistics in `meta/stats.json` and the schema in `meta/info.json` (features listed in the data
files' column order: LeRobot casts the Parquet rows to the schema it builds from that list when
it selects episodes). Episodes are numbered across the whole export (train first, then val,
test), `index` counts frames over the whole export, and the echo-data splits become LeRobot's
`splits` ("start:end" episode ranges).

One split per export, train unless `split=` names another: LeRobot's readers (`lerobot-train`,
`LeRobotDataset` without `episodes=`) take every episode in the folder, so a folder that held the
test split would train on it. Evaluate on `--split test` written to a folder of its own.

Policy-ready names. LeRobot's policies type a feature by its name (`lerobot.datasets.utils.
dataset_to_policy_features`): dtype image/video -> a camera, `observation.environment_state` ->
the environment state, any other `observation*` -> a state input, any `action*` -> an action
output; everything else is carried but never given to a policy. Stock ACT and Diffusion read only
`observation.state`, the cameras and `observation.environment_state`. So each echo-data column is
exported by one rule for its kind (`lerobot_name`):

- `action` stays `action`, the only action feature; every other `action.*` column (what was
  executed, the end-effector form) becomes `extra.action.*`.
- `observation.environment_state`, which ACT and Diffusion read with no config change, is a
  compact, standardised copy of the audio feature the project's learners use (the SoundSpaces
  spectrogram of the last second, else the log-mel): mean-pooled over (frequency, time) blocks to
  at most `ENV_STATE_MAX` values a step (Diffusion feeds it to every FiLM layer: the full 3,380
  values made ~40 % of its parameters), then standardised per value with the train split's mean
  and std (`ENV_STATE_MIN_STD` floors a std), because the stock configs' normalisation mapping
  has no entry for the environment state and passes it raw (the spectrogram's values are ~0.01).
  `info.json` `echo_data.environment_state` holds the pooling, the mean and the std. The full audio
  columns and every privileged column (`observation.privileged.*`, what only the simulator knows)
  become `extra.<echo-data name>`. Stripping `extra.` gives back echo-data's column name.
- Cameras keep their names. RGB is an 8-bit RGB image (PNG in the rows, or with `video=("rgb",)`
  a video encoded as LeRobot's own recorder encodes one: `VIDEO_ENCODING`, AV1, a keyframe every 2
  frames; episodes share MP4 files, each at its `from_timestamp`..`to_timestamp`, as LeRobot v3.0
  keeps them). Depth is an 8-bit grey image repeated
  over three channels, 0..`range_m` mapped linearly to 0..255 (the range per camera is the train
  split's 99th-percentile depth rounded up to 0.5 m, so the farthest 1 % saturate at 255 and the
  rest keep fine steps; in `info.json` `echo_data.depth_images`):
  Diffusion requires every camera to have one shape and ACT's ResNet takes three channels. The
  exact 16-bit millimetres stay in the echo-data dataset and its robomimic/Zarr exports.

Audio beyond the features: each frame carries `audio_path`, `audio_sample_rate`, `audio_offset`;
the episode WAVs are copied to `audio/{split}/{episode_id}.wav` (the path the rows name, relative
to the export root). Array features are flattened to one vector (LeRobot's tools turn features of
more than one dimension into `datasets` Array2D/3D columns that pandas cannot concatenate, which
breaks `aggregate_datasets`); the original shapes are in `info.json` `echo_data.audio.shapes`.
Statistics are per value (per channel for cameras), as LeRobot's `compute_episode_stats` makes them.

A data file holds the episodes of one split only (a new file starts at each split), so a reader
that loads whole files for a selection of episodes never pulls in another split's frames.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset.episode_arrays import (
    ExportError,
    check_out_folder,
    check_source,
    column_values,
    decode_images,
    depth_ranges,
    export_splits,
)
from echo_data.dataset.lerobot_audio import (  # noqa: F401 (names the export's users import from here)
    AUDIO_FOR_POLICY,
    ENV_STATE,
    ENV_STATE_MAX,
    ENV_STATE_MIN_STD,
    audio_pool,
    audio_standardisation,
    environment_state,
    policy_audio,
    pooled_audio,
)
from echo_data.dataset.lerobot_media import VideoFiles, VideoLayout, depth_image, options, png_cells
from echo_data.dataset.reader import episode_spans, episodes_table, split_tables
from echo_data.dataset.schema import (
    ACTION,
    ACTION_EXECUTED,
    CAMERA_POSES,
    CHAIN_SLOTS,
    IMAGE_COLUMNS,
    PARQUET_COMPRESSION,
    ROW_GROUP_ROWS,
    STATE,
    StepLayout,
    is_privileged,
)
from echo_data.dataset.shards import conform
from echo_data.dataset.stats import episode_feature_values, finalize, merge, summarize
from echo_data.dataset.storage import atomic_write_bytes, canonical_json, fsync_dir
from echo_data.dataset.written import mark_export, replace_folder
from echo_data.media import LEROBOT_VIDEO, VideoEncoding
from echo_data.recipe import SETTINGS
from echo_data.records import ACTION_NAMES, EE_ACTION_NAMES, PRIVILEGED_PREFIX, STATE_NAMES

CODEBASE_VERSION = "v3.0"
KIND = "lerobot export"  # the folder marker's kind (echo_data.dataset.written)
CHUNKS_SIZE = 1000  # files per chunk folder (LeRobot's default)
DATA_FILES_SIZE_IN_MB = 100  # a data file is closed once its rows reach this size
VIDEO_FILES_SIZE_IN_MB = 200  # a video file takes episodes until the next would bring it to this size (LeRobot's default)
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
ROBOT_TYPE = "echo_data_fetchlike"
EXTRA_PREFIX = "extra."  # carried, never a policy input or output (see the module docstring)
VIDEO_CAMERAS = {"rgb": IMAGE_COLUMNS["head_rgb"]}  # --video choices -> the column stored as MP4
VIDEO_ENCODING: VideoEncoding = LEROBOT_VIDEO  # codec, pixel format, GOP, quality: LeRobot's encoder's (echo_data.media)
# The natural-language task of each setting (LeRobot's `task`; index = echo-data's task_index).
TASKS = {
    "object_relocation": "Find the sounding object, pick it up and put it where it belongs.",
    "state_transition": "Attend to the sound: open the door for the doorbell or turn off the running faucet.",
    "multi_event": "Handle every sound event in order of priority.",
}


def _names(col: str) -> list[str] | None:
    """Element names of a vector feature (LeRobot's `names`), by the column's kind."""
    if col.startswith(ACTION + ".ee"):
        return list(EE_ACTION_NAMES)
    if col in (ACTION, ACTION_EXECUTED):
        return list(ACTION_NAMES)
    if col == STATE:
        return list(STATE_NAMES)
    if col in CAMERA_POSES.values():
        return [f"T{r}{c}" for r in range(4) for c in range(4)]
    if col == "skill_success":
        return [f"chain_{k}" for k in range(CHAIN_SLOTS)]
    return None


def lerobot_name(col: str, layout: StepLayout) -> str:
    """The LeRobot feature name of an echo-data column: one rule per kind (module docstring)."""
    if col.startswith(ACTION + ".") or col.startswith(PRIVILEGED_PREFIX) or col in layout.arrays:
        return EXTRA_PREFIX + col
    return col


def lerobot_features(layout: StepLayout, video: tuple[str, ...] = (), env_state: int = 0) -> dict[str, dict[str, Any]]:
    """meta/info.json `features`: every step column with dtype, shape and names, in the export's
    column order (video features last: they are not data columns), derived from the step
    schema's Hugging Face features (so new columns export too), then ENV_STATE (`env_state`
    values; 0: none)."""
    videos = {VIDEO_CAMERAS[v] for v in video}
    feats: dict[str, dict[str, Any]] = {}
    moved: dict[str, dict[str, Any]] = {}
    for col, f in layout.hf_features().items():
        kind, name = f["_type"], lerobot_name(col, layout)
        if kind == "Value":
            feats[name] = {"dtype": f["dtype"], "shape": [1], "names": None}
        elif kind == "List" and "length" in f:
            feats[name] = {"dtype": f["feature"]["dtype"], "shape": [f["length"]], "names": _names(col)}
            if is_privileged(col):  # simulator-only: a policy config must name it to read it
                feats[name]["info"] = {"privileged": True}
        elif kind == "Array3D":
            feats[name] = {"dtype": f["dtype"], "shape": [int(np.prod(f["shape"]))], "names": None}
        elif kind == "Image":
            img_kind, h, w = layout.images[col]
            if col in videos:
                moved[col] = {
                    "dtype": "video",
                    "shape": [h, w, 3],
                    "names": ["height", "width", "channels"],
                    "info": {
                        "video.height": h, "video.width": w, "video.codec": VIDEO_ENCODING.codec, "video.pix_fmt": VIDEO_ENCODING.pix_fmt,
                        "video.is_depth_map": False, "video.fps": layout.fps, "video.channels": 3, "has_audio": False,
                    },
                }
                continue
            unit = "8-bit RGB" if img_kind == "rgb" else "8-bit depth x3: value / 255 * echo_data.depth_images range_m = metres along the optical axis"
            feats[name] = {"dtype": "image", "shape": [h, w, 3], "names": ["height", "width", "channels"], "info": {"format": "PNG", "unit": unit}}
        else:  # LeRobot features have fixed shapes
            raise ExportError(f"column {col!r} ({kind} without a fixed length) has no LeRobot feature")
    if env_state:
        feats[ENV_STATE] = {"dtype": "float32", "shape": [env_state], "names": None}
    return {**feats, **moved}


def _hf_features(layout: StepLayout, video: tuple[str, ...], env_state: int) -> dict[str, Any]:
    """The `huggingface` schema metadata of the export's data files (what `datasets` reads)."""
    videos = {VIDEO_CAMERAS[v] for v in video}
    out: dict[str, Any] = {}
    for col, f in layout.hf_features().items():
        if col in videos:
            continue
        if f["_type"] == "Array3D":
            f = {"feature": {"dtype": f["dtype"], "_type": "Value"}, "length": int(np.prod(f["shape"])), "_type": "List"}
        elif _single(f):  # LeRobot reads a feature of shape (1,) as one value per frame
            f = dict(f["feature"])
        out[lerobot_name(col, layout)] = f
    if env_state:
        out[ENV_STATE] = {"feature": {"dtype": "float32", "_type": "Value"}, "length": env_state, "_type": "List"}
    return out


def _single(f: dict[str, Any]) -> bool:
    """A fixed-length list of one element (e.g. `observation.privileged.joint_angle`)."""
    return f.get("_type") == "List" and f.get("length") == 1


def _export_rows(
    rows: pa.Table, layout: StepLayout, video: tuple[str, ...], hf: dict[str, Any], depth: dict[str, np.ndarray], env: np.ndarray | None
) -> pa.Table:
    """Step rows of one episode in the export's columns (named by `lerobot_name`): arrays
    flattened, depth as its 8-bit images (`depth`, by column), video cameras dropped, then the
    ENV_STATE values `env` (None: none)."""
    videos = {VIDEO_CAMERAS[v] for v in video}
    arrays, fields = [], []
    for col in rows.column_names:
        if col in videos:
            continue
        data = rows.column(col).combine_chunks()
        if col in layout.arrays:
            flat = column_values(rows.column(col), rows.num_rows).astype(np.float32).ravel()
            data = pa.FixedSizeListArray.from_arrays(pa.array(flat), int(np.prod(layout.arrays[col])))
        elif col in depth:
            data = png_cells(depth[col])
        elif pa.types.is_fixed_size_list(data.type) and data.type.list_size == 1:
            data = data.flatten()  # as `_hf_features` declares it: one value per frame
        arrays.append(data)
        fields.append(pa.field(lerobot_name(col, layout), data.type))
    if env is not None:
        arrays.append(pa.FixedSizeListArray.from_arrays(pa.array(env.ravel()), env.shape[1]))
        fields.append(pa.field(ENV_STATE, arrays[-1].type))
    schema = pa.schema(fields, metadata={"huggingface": json.dumps({"info": {"features": hf}})})
    return pa.Table.from_arrays(arrays, schema=schema)


def episode_summaries(
    rows: pa.Table, layout: StepLayout, features: dict[str, dict[str, Any]], depth: dict[str, np.ndarray], env: np.ndarray | None
) -> dict[str, dict[str, Any]]:
    """Mergeable summaries (echo_data.dataset.stats) of one episode's numeric features, by export
    name, in LeRobot's units: every camera per channel in [0, 1] (as its 8-bit images decode;
    `depth` holds the depth images), vectors and flattened arrays per element (as LeRobot's
    `compute_episode_stats` does), ENV_STATE (`env`) per value."""
    n = rows.num_rows
    out: dict[str, dict[str, Any]] = {}
    for col in rows.column_names:
        name = lerobot_name(col, layout)
        feat = features.get(name)
        if feat is None or feat["dtype"] == "string":
            continue
        if col in layout.images:
            pixels = depth[col] if col in depth else decode_images(rows.column(col))
            values = episode_feature_values(np.zeros((n, 0)), np.zeros((n, 0)), {col: ("rgb", pixels)}, {})[col]
        else:
            values = column_values(rows.column(col), n).astype(np.float64).reshape(n, -1)
        out[name] = summarize(values, n)
    if env is not None:
        out[ENV_STATE] = summarize(env, n)
    return out


def lerobot_stats(summary: dict[str, Any], feature: dict[str, Any]) -> dict[str, Any]:
    """A summary -> LeRobot's record (min/max/mean/std/count/q01..q99): images shaped (C, 1, 1)."""
    st = finalize(summary)
    if feature["dtype"] in ("image", "video"):
        return {k: (v if k == "count" else [[[x]] for x in v]) for k, v in st.items()}
    return dict(st)


def _flat_stats(stats: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Per-episode statistics as LeRobot stores them in meta/episodes: `stats/{feature}/{stat}`."""
    return {f"stats/{k}/{s}": v for k, st in stats.items() for s, v in st.items()}


def _data_files(
    src: Path,
    dst: Path,
    manifest: dict[str, Any],
    layout: StepLayout,
    video: tuple[str, ...],
    features: dict[str, dict[str, Any]],
    ranges: dict[str, float],
    splits_out: list[str],
    env_recipe: dict[str, Any] | None,
    progress: Callable[[int], None] = lambda n: None,
) -> tuple[list[dict[str, Any]], dict[str, str], dict[str, dict[str, Any]]]:
    """Step rows of the splits `splits_out` regrouped into LeRobot data files under `dst` (each
    written as soon as it is full, so memory holds one file's rows), one record per episode, the
    splits, and the merged summaries of the exported episodes (meta/stats.json)."""
    hf = _hf_features(layout, video, len(env_recipe["mean"]) if env_recipe else 0)
    n_files = 0
    pending: list[pa.Table] = []
    pending_bytes = 0
    episodes: list[dict[str, Any]] = []
    splits: dict[str, str] = {}
    train: list[dict[str, dict[str, Any]]] = []
    ep_meta = {(r["split"], r["episode_index"]): r for r in episodes_table(src).to_pylist()}
    n_ep = n_rows = 0

    files = VideoLayout(VIDEO_PATH, CHUNKS_SIZE, VIDEO_FILES_SIZE_IN_MB, VIDEO_ENCODING)  # read now: a caller may have changed them
    videos = [VideoFiles(dst, VIDEO_CAMERAS[v], layout.fps, files) for v in video]

    def close() -> None:
        nonlocal pending, pending_bytes, n_files
        if pending:
            path = dst / DATA_PATH.format(chunk_index=n_files // CHUNKS_SIZE, file_index=n_files % CHUNKS_SIZE)
            _write_parquet(path, pa.concat_tables(pending), ROW_GROUP_ROWS)
            pending, pending_bytes, n_files = [], 0, n_files + 1

    for split in splits_out:
        close()  # a data file never holds two splits, nor does a video file
        for vf in videos:
            vf.close()
        first_ep = n_ep
        for stored in split_tables(src, manifest, split):
            table = conform(stored, layout.schema())
            ep = table.column("episode_index").to_numpy()
            for lo, hi in episode_spans(ep):
                rows = table.slice(lo, hi - lo)
                row = ep_meta[(split, int(ep[lo]))]
                length = rows.num_rows
                for col, values in (("episode_index", np.full(length, n_ep)), ("index", np.arange(n_rows, n_rows + length))):
                    i = rows.schema.get_field_index(col)
                    rows = rows.set_column(i, col, pa.array(values.astype(np.int64)))
                depth = {col: depth_image(decode_images(rows.column(col)), r) for col, r in ranges.items()}
                env = None
                if env_recipe is not None:
                    col, shape = env_recipe["from"], tuple(env_recipe["shape"])
                    env = environment_state(column_values(rows.column(col), rows.num_rows).reshape(rows.num_rows, *shape), env_recipe)
                summaries = episode_summaries(rows, layout, features, depth, env)
                train.append(summaries)
                out_rows = _export_rows(rows, layout, video, hf, depth, env)
                if pending and pending_bytes + out_rows.nbytes > DATA_FILES_SIZE_IN_MB * 2**20:
                    close()
                pending.append(out_rows)
                pending_bytes += out_rows.nbytes
                k = n_files
                record: dict[str, Any] = {
                    "episode_index": n_ep,
                    "tasks": [TASKS[row["setting"]]],
                    "length": length,
                    "data/chunk_index": k // CHUNKS_SIZE,
                    "data/file_index": k % CHUNKS_SIZE,
                    "dataset_from_index": n_rows,
                    "dataset_to_index": n_rows + length,
                }
                for vf in videos:
                    record.update(vf.add(rows))
                record.update({
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
                    **_flat_stats({k: lerobot_stats(s, features[k]) for k, s in summaries.items()}),
                })
                episodes.append(record)
                n_ep += 1
                n_rows += length
                progress(1)
        splits[split] = f"{first_ep}:{n_ep}"
    close()
    for vf in videos:
        vf.close()
    merged = {k: merge([t[k] for t in train]) for k in train[0]} if train else {}
    return episodes, splits, merged


def _write_parquet(path: Path, table: pa.Table, row_group: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, path, compression=PARQUET_COMPRESSION, row_group_size=row_group, store_schema=True)


def _provenance(manifest: dict[str, Any], src: Path, layout: StepLayout, ranges: dict[str, float], env_recipe: dict[str, Any] | None,
                stats_split: str, video: tuple[str, ...]) -> dict[str, Any]:
    """info.json's `echo_data` block: where the export came from and how to read what LeRobot's
    format does not say (renamed columns, the environment state, depth, audio, the cameras)."""
    return {
                    "source": manifest["name"],
                    "recipe_hash": manifest["recipe_hash"],
                    "format": manifest["format"],
                    "cameras": json.loads((src / "meta" / "info.json").read_text()).get("cameras", {}),
                    # LeRobot name -> echo-data column, for every column whose name changed
                    "renamed": {n: c for c in layout.hf_features() if (n := lerobot_name(c, layout)) != c},
                    "environment_state": env_recipe,
                    "depth_images": {
                        col: {"range_m": r, "decode": "metres = pixel / 255 * range_m (any channel; 255 = range_m or farther, 0 = nothing hit or nearer than half a step)"}
                        for col, r in ranges.items()
                    },
                    "audio": {
                        "sample_rate": layout.sample_rate,
                        "channels": 2,
                        "channel_0": "left",
                        "path": "audio/{split}/{episode_id}.wav (each row's audio_path; episode records' audio_path)",
                        "offset": "audio_offset: the sample at which the row's observation was taken",
                        "shapes": {lerobot_name(col, layout): list(shape) for col, shape in layout.arrays.items()},
                        "flattened": "row-major (frequency, time, ear): reshape a frame's vector to `shapes`",
                    },
                    "stats_split": stats_split,
                    "cameras_as": (f"head RGB as {VIDEO_ENCODING.codec} video ({VIDEO_ENCODING.encoder}, {options(VIDEO_ENCODING)}), as LeRobot encodes; " if video else "")
                    + "depth as 8-bit 3-channel PNG images (every camera one shape, as Diffusion requires); exact millimetres in the echo-data dataset",
                }


def export_lerobot(
    src: str | Path,
    out: str | Path,
    overwrite: bool = False,
    video: tuple[str, ...] = (),
    split: str | None = None,
    progress: Callable[[int], None] = lambda n: None,
) -> dict[str, Any]:
    """Write the LeRobot v3.0 dataset of the split `split` (default train) of the echo-data
    dataset `src` to `out`; return meta/info.json.

    `video` names cameras stored as MP4 video features (only "rgb": head RGB); `progress(1)` is
    called after each episode. Everything is
    written to a temporary sibling folder first and renamed into place, so `out` is either
    absent, the old export or the whole new one. Raises `ExportError` on bad input."""
    try:
        import pandas as pd
    except ImportError:
        raise ExportError("the LeRobot export needs pandas: pip install pandas") from None
    src, out = Path(src), Path(out)
    manifest = check_source(src)
    if split is None and "train" not in manifest["splits"]:
        raise ExportError(f"{src} has no train split: name the split to export with --split ({', '.join(manifest['splits'])})")
    splits_out = export_splits(manifest, split or "train")
    check_out_folder(src, out, overwrite, KIND)
    layout = StepLayout.from_dict(manifest["layout"])
    for v in video:
        if v not in VIDEO_CAMERAS:
            raise ExportError(f"--video {v}: unknown camera (choose from {', '.join(VIDEO_CAMERAS)}; depth stays PNG)")
        if VIDEO_CAMERAS[v] not in layout.images:
            raise ExportError(f"--video {v}: {src} has no {VIDEO_CAMERAS[v]} column")
        _, h, w = layout.images[VIDEO_CAMERAS[v]]
        if h % 2 or w % 2:
            raise ExportError(f"--video {v}: {w} x {h} images; video in {VIDEO_ENCODING.pix_fmt} needs even sides")
    audio_col = policy_audio(layout)
    env_recipe = audio_standardisation(src, manifest, audio_col, layout.arrays[audio_col]) if audio_col else None
    features = lerobot_features(layout, video, len(env_recipe["mean"]) if env_recipe else 0)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        ranges = depth_ranges(src, layout)
        episodes, splits, merged = _data_files(src, tmp, manifest, layout, video, features, ranges, splits_out, env_recipe, progress)
        _write_parquet(tmp / EPISODES_PATH.format(chunk_index=0, file_index=0), pa.Table.from_pylist(episodes), 4096)
        tasks = pd.DataFrame({"task_index": np.arange(len(SETTINGS), dtype=np.int64)}, index=pd.Index([TASKS[s] for s in SETTINGS], name="task"))
        (tmp / "meta").mkdir(parents=True, exist_ok=True)
        tasks.to_parquet(tmp / "meta" / "tasks.parquet")
        atomic_write_bytes(tmp / "meta" / "stats.json", canonical_json({k: lerobot_stats(s, features[k]) for k, s in merged.items()}))
        info = {
            "codebase_version": CODEBASE_VERSION,
            "robot_type": ROBOT_TYPE,
            "total_episodes": len(episodes),
            "total_frames": sum(e["length"] for e in episodes),
            "total_tasks": len(SETTINGS),
            "chunks_size": CHUNKS_SIZE,
            "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
            "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB,
            "fps": layout.fps,
            "splits": splits,
            "data_path": DATA_PATH,
            "video_path": VIDEO_PATH if video else None,
            "features": features,
            "echo_data": _provenance(manifest, src, layout, ranges, env_recipe, splits_out[0], video),
        }
        # column order, not sorted: LeRobot builds its Arrow schema from this order
        atomic_write_bytes(tmp / "meta" / "info.json", (json.dumps(info, indent=4) + "\n").encode())
        from echo_data.dataset.audio import write_audio_tables
        from echo_data.dataset.card import export_card

        for e in episodes:
            dst = tmp / e["audio_path"]
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src / e["audio_path"], dst)
        write_audio_tables(tmp, episodes)  # the card's playable `audio` config, in the export's episode numbering
        (tmp / "README.md").write_text(export_card(info, src / "README.md", tmp))
        (tmp / "echo_data_manifest.json").write_bytes(canonical_json({k: manifest[k] for k in ("name", "recipe_hash", "format", "versions", "counts")}))
        mark_export(tmp, KIND, CODEBASE_VERSION)
        replace_folder(tmp, out, KIND)
        fsync_dir(out.parent)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return info
