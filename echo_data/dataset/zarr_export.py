"""`echo-data export --format zarr`: a Diffusion Policy replay buffer (one Zarr folder).

Diffusion Policy's `ReplayBuffer` reads `data/<key>` arrays that concatenate every episode's steps
along axis 0 and `meta/episode_ends` (int64, the exclusive end row of each episode). The store is
written in Zarr format 2, which both Diffusion Policy's zarr 2 and zarr 3 open. Episodes are in
train, val, test order; `meta/episode_split` (int8: 0 train, 1 val, 2 test) says which split each
belongs to. Diffusion Policy's datasets do not read it: they draw their validation episodes at
random (`val_ratio`) from every episode in the buffer and train on the rest, so a buffer holding
the test split trains on test episodes. Export one buffer per split (`split=`, CLI `--split
train`) and give Diffusion Policy only the train (or train + val) buffer.

Arrays: `action` (N, 12), `action_ee` (N, 11, the end-effector form), `state` (N, 25), `head_rgb` (N, H, W, 3) uint8, `head_depth` /
`wrist_depth` (N, H, W) uint16 millimetres, `spectrogram`, `mel` (N, F, time, ear), `camera_pose_head`
/ `camera_pose_wrist` (N, 4, 4), `timestamp`, `frame_index`, `skill_index`, `audio_offset`, `done`,
`skill_success`, `skill_stop`, and the simulator-only `privileged_*` observations (read only when named).
Chunks along axis 0 hold `chunk_steps` rows: the median episode length, so one
chunk is about one episode (a regular chunk grid cannot follow each episode's own length); the other
axes are whole. The root attributes list each episode's id, split, setting and WAV (`audio_path`,
relative to the source dataset folder `source_dataset`).
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.episode_arrays import ExportError as ExportError  # the CLI catches `module.ExportError`
from echo_data.dataset.episode_arrays import check_out_folder, check_source, export_splits, iter_episodes
from echo_data.dataset.reader import episodes_table
from echo_data.dataset.robomimic import OBS_KEYS
from echo_data.dataset.schema import ACTION, ACTION_EE, CAMERA_POSES, SKILL_STOP
from echo_data.dataset.written import mark_export, replace_folder
from echo_data.episode import SPLIT_KEYS
from echo_data.records import PRIVILEGED_COLUMNS

SPLIT_CODES = {"train": 0, "val": 1, "test": 2}
EXTRA = ("timestamp", "frame_index", "skill_index", "audio_offset", "done", "skill_success", SKILL_STOP)
KEYS = {ACTION: "action", ACTION_EE: "action_ee", **OBS_KEYS, **{c: c for c in EXTRA}}
KIND = "zarr export"  # the folder marker's kind (echo_data.dataset.written)
FORMAT = "Diffusion Policy replay buffer (Zarr format 2)"


def _as_stored(col: str, x: np.ndarray) -> np.ndarray:
    if col in CAMERA_POSES.values():
        return x.reshape(len(x), 4, 4)
    return x


def _remove(tmp: Path, tries: int = 20, settle: float = 0.05) -> None:
    """Remove the temporary folder, and again until it stays gone. Why: zarr 3 writes chunks from
    its own event-loop thread, and when one write fails (a full disk) the call raises while the
    others are still in flight and can recreate chunk folders after a first rmtree (measured: a
    `.export.tmp-PID` left in 1 of 3 runs of tests/test_faults_disk.py's zarr case)."""
    for _ in range(tries):
        shutil.rmtree(tmp, ignore_errors=True)
        time.sleep(settle)
        if not tmp.exists():
            return


def export_zarr(
    src: str | Path, out: str | Path, overwrite: bool = False, split: str | None = None, progress: Callable[[int], None] = lambda n: None
) -> dict[str, Any]:
    """Write the replay buffer of the echo-data dataset `src` (or of its split `split`) to the
    folder `out` (built in a temporary sibling, then renamed); return a summary. `progress(1)` is
    called after each episode. Raises ExportError on bad input."""
    import zarr

    src, out = Path(src), Path(out)
    manifest = check_source(src)
    chosen = export_splits(manifest, split)
    check_out_folder(src, out, overwrite, KIND)
    eps = episodes_table(src, ["n_steps", "split"]).to_pydict()
    lengths = np.asarray([n for n, s in zip(eps["n_steps"], eps["split"]) if s in chosen], np.int64)
    chunk_steps = max(1, int(np.median(lengths)))
    total = int(lengths.sum())
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        root = zarr.open_group(str(tmp), mode="w", zarr_format=2)
        data = root.create_group("data")
        arrays: dict[str, Any] = {}
        ends: list[int] = []
        splits: list[int] = []
        episodes: list[dict[str, Any]] = []
        row = 0
        for ep in iter_episodes(src, manifest, chosen):
            n = ep.length
            for col, key in KEYS.items():
                if col not in ep.columns:
                    continue
                x = _as_stored(col, ep.columns[col])
                if key not in arrays:
                    arrays[key] = data.create_array(key, shape=(total, *x.shape[1:]), dtype=x.dtype, chunks=(chunk_steps, *x.shape[1:]))
                arrays[key][row : row + n] = x
            row += n
            ends.append(row)
            splits.append(SPLIT_CODES[ep.split])
            episodes.append({k: ep.record[k] for k in ("episode_id", "setting", "seed", "success", "audio_path")} | {"split": ep.split})
            progress(1)
        meta = root.create_group("meta")
        meta.create_array("episode_ends", data=np.asarray(ends, np.int64), chunks=(max(len(ends), 1),))
        meta.create_array("episode_split", data=np.asarray(splits, np.int8), chunks=(max(len(splits), 1),))
        root.attrs.update(
            {
                "source_dataset": f"out/{manifest['name']}",
                "echo_data_format": manifest["format"],
                "recipe_hash": manifest["recipe_hash"],
                "fps": manifest["layout"]["fps"],
                "chunk_steps": chunk_steps,
                "split_codes": SPLIT_CODES,
                "splits": chosen,
                "units": {"head_depth": "uint16 millimetres", "wrist_depth": "uint16 millimetres", "head_rgb": "uint8 RGB",
                          "camera_pose_head": "camera-to-world, OpenCV axes"},
                "episodes": episodes,
                "privileged": [OBS_KEYS[c] for c in PRIVILEGED_COLUMNS],  # simulator-only observations
            }
        )
        mark_export(tmp, KIND, FORMAT, zarr=True)  # in .zattrs: zarr lists the tree without a warning
        replace_folder(tmp, out, KIND)
    finally:
        _remove(tmp)
    counts = {s: splits.count(c) for s, c in sorted(SPLIT_CODES.items(), key=lambda kv: SPLIT_KEYS[kv[0]]) if splits.count(c)}
    return {"codebase_version": FORMAT, "total_episodes": len(ends), "total_frames": row, "splits": counts}
