"""`echo-data export --format robomimic`: one HDF5 file in robomimic's dataset layout.

robomimic (and LIBERO, ManiSkill's demo tools) read demonstrations as
`data/demo_N/{actions (T, A), rewards (T,), dones (T,), obs/<key> (T, ...), next_obs/<key>}`, with
`data` attributes `total` (frames) and `env_args` (JSON: env_name, type, env_kwargs), each demo's
`num_samples`, and filter keys `mask/<name>` (arrays of demo names; robomimic trains on
`mask/train` and validates on `mask/valid`). Here demo N is the N-th stored episode, train first;
echo-data's val split is `mask/valid` and its test split `mask/test` (never train or tune on it).

Observations (`obs/`): `state` (25), `head_rgb` (H, W, 3) uint8, `head_depth` / `wrist_depth`
(H, W, 1) float32 depth as a fraction of the camera's range (`metres = value * range`, the range
by key in the `data` attribute `depth_range_m` (JSON): the train split's farthest depth rounded up
to 0.5 m; not an attribute of each depth dataset, because an attribute write that fails on a
full disk crashes h5py at close, see `_KeepsFirstWriteError`): robomimic's `depth` modality divides by 1 and
clips to [0, 1], so millimetres would reach its models as a constant 1.0. `spectrogram` and `mel` of the last second (F, time, ear),
`camera_pose_head` / `camera_pose_wrist` (4, 4). Large observations are chunked one frame per
chunk: robomimic reads one random step at a time, and a chunk holding a whole trajectory made each
read decompress all of it. `next_obs/<key>` (only with `next_obs=True`: robomimic's BC and
`get_dataset_info` do not need them; offline RL does) are HDF5 virtual datasets over `obs/<key>`
shifted by one step (the last step repeats). Rewards are sparse: 1 on an episode's last step when
it succeeded. Each demo's attributes carry its echo-data id, split, setting, seed, and
`audio_path`: the episode's binaural WAV, relative to the source dataset folder named in `data`
attribute `source_dataset`.

Actions: robomimic's models squash their outputs to [-1, 1] and its `get_dataset_info` refuses
anything outside, so `actions` are echo-data's `action` mapped per dimension from the train
split's [min, max] (the source's meta/stats.json) to [-1, 1], clipped there (a val/test step
outside the train range; the count is `data` attribute `actions_clipped`, and `export` prints it). `data` attribute
`action_normalization` (JSON) holds `low`, `high`, the names and the inverse
`action = low + (actions + 1) / 2 * (high - low)`; a dimension the train split never moves
(high == low) maps to 0. `split=` writes one split only (its own file; masks name its demos).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.episode_arrays import EpisodeArrays, check_out_file, check_source, depth_ranges, export_splits, iter_episodes
from echo_data.dataset.episode_arrays import ExportError as ExportError  # the CLI catches `module.ExportError`
from echo_data.dataset.schema import ACTION, ACTION_EE, CAMERA_POSES, IMAGE_COLUMNS, MEL, SPECTROGRAM, STATE, StepLayout
from echo_data.records import ACTION_NAMES, PRIVILEGED_COLUMNS, PRIVILEGED_PREFIX

# echo-data column -> robomimic observation key
OBS_KEYS = {
    STATE: "state",
    IMAGE_COLUMNS["head_rgb"]: "head_rgb",
    IMAGE_COLUMNS["head_depth"]: "head_depth",
    IMAGE_COLUMNS["wrist_depth"]: "wrist_depth",
    SPECTROGRAM: "spectrogram",
    MEL: "mel",
    CAMERA_POSES["head"]: "camera_pose_head",
    CAMERA_POSES["wrist"]: "camera_pose_wrist",
    # simulator-only observations: a robomimic config reads them only if it lists them
    **{col: "privileged_" + col.removeprefix(PRIVILEGED_PREFIX) for col in PRIVILEGED_COLUMNS},
}
MASKS = {"train": "train", "val": "valid", "test": "test"}
COMPRESSION = "lzf"  # fast, built into h5py: images and spectrograms compress, readers need nothing extra
CHUNK_FRAMES = 1  # frames per HDF5 chunk of a large observation (robomimic reads one random frame at a time)


def _obs(ep: EpisodeArrays, depth_range_m: dict[str, float]) -> dict[str, np.ndarray]:
    """robomimic observation key -> (T, ...) array; depth as a fraction of its range (module docstring)."""
    out = {}
    for col, key in OBS_KEYS.items():
        if col in ep.columns:
            x = ep.columns[col]
            if col in depth_range_m:  # robomimic's depth modality is (H, W, 1) in [0, 1]
                x = (x.astype(np.float32) / np.float32(1000.0 * depth_range_m[col]))[..., None]
            elif col in CAMERA_POSES.values():
                x = x.reshape(len(x), 4, 4)
            out[key] = x
    return out


def action_range(src: Path) -> tuple[np.ndarray, np.ndarray]:
    """Per action dimension, the train split's (low, high): the source's meta/stats.json."""
    st = json.loads((src / "meta" / "stats.json").read_text())[ACTION]
    return np.asarray(st["min"], np.float64), np.asarray(st["max"], np.float64)


def normalize_actions(a: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, int]:
    """Actions -> [-1, 1] per dimension (module docstring) and how many values were clipped."""
    span = high - low
    x = np.where(span > 0, 2.0 * (a - low) / np.where(span > 0, span, 1.0) - 1.0, 0.0)
    clipped = int(np.count_nonzero((x < -1.0) | (x > 1.0)))
    return np.clip(x, -1.0, 1.0).astype(np.float32), clipped


def _write_demo(data: Any, name: str, ep: EpisodeArrays, actions: np.ndarray, next_obs: bool, depth_range_m: dict[str, float]) -> None:
    import h5py

    g = data.create_group(name)
    n = ep.length
    g.create_dataset("actions", data=actions)
    if ACTION_EE in ep.columns:  # the end-effector form (docs/action_spaces.md), unnormalised, for an ee-space policy
        g.create_dataset("actions_ee", data=ep.columns[ACTION_EE].astype(np.float32))
    rewards = np.zeros(n, np.float32)
    rewards[-1] = float(bool(ep.record["success"]))
    g.create_dataset("rewards", data=rewards)
    g.create_dataset("dones", data=ep.columns["done"].astype(np.int64))
    obs = g.create_group("obs")
    nxt = g.create_group("next_obs") if next_obs else None
    for key, x in _obs(ep, depth_range_m).items():
        big = x[0].size > 64
        d = obs.create_dataset(key, data=x, chunks=(min(CHUNK_FRAMES, n), *x.shape[1:]) if big else None, compression=COMPRESSION if big else None)
        if nxt is None:
            continue
        layout = h5py.VirtualLayout(shape=x.shape, dtype=x.dtype)
        source = h5py.VirtualSource(".", d.name, shape=x.shape, dtype=x.dtype)  # "." = this file, whatever its name
        if n > 1:
            layout[: n - 1] = source[1:]
        layout[n - 1] = source[n - 1]
        nxt.create_virtual_dataset(key, layout)
    g.attrs.update(
        num_samples=n,
        episode_id=ep.record["episode_id"],
        split=ep.split,
        setting=ep.record["setting"],
        seed=int(ep.record["seed"]),
        success=bool(ep.record["success"]),
        audio_path=ep.record["audio_path"],
        audio_sample_rate=int(ep.columns["audio_sample_rate"][0]),
        audio_offsets=ep.columns["audio_offset"].astype(np.int64),
        skills=json.dumps(ep.strings.get("skill", [])),
    )


class _KeepsFirstWriteError:
    """The file object h5py writes through (its `fileobj` driver). A failed write (full disk,
    quota, file size limit) is recorded and later writes are dropped, so HDF5 never sees an
    error: when HDF5's own writes fail, h5py 3 crashes at close (SIGSEGV, measured under
    RLIMIT_FSIZE). The export asks `check` after each demo and after the close, and raises the
    recorded `OSError` (the temporary file is then removed)."""

    def __init__(self, raw: Any) -> None:
        self.raw = raw
        self.error: OSError | None = None

    def write(self, b: Any) -> int:
        n = len(memoryview(b).cast("B"))
        if self.error is None:
            try:
                return int(self.raw.write(b))
            except OSError as e:
                self.error = e
        return n

    def flush(self) -> None:
        if self.error is None:
            try:
                self.raw.flush()
            except OSError as e:
                self.error = e

    def truncate(self, size: int | None = None) -> int:
        if self.error is None:
            try:
                return int(self.raw.truncate(size))
            except OSError as e:
                self.error = e
        return size or 0

    def __getattr__(self, name: str) -> Any:  # read, readinto, seek, tell: the real file's
        return getattr(self.raw, name)

    def check(self) -> None:
        """Raise the first write error, if a write failed."""
        if self.error is not None:
            raise self.error


def export_robomimic(
    src: str | Path,
    out: str | Path,
    overwrite: bool = False,
    split: str | None = None,
    next_obs: bool = False,
    progress: Callable[[int], None] = lambda n: None,
) -> dict[str, Any]:
    """Write the robomimic HDF5 of the echo-data dataset `src` (or of its split `split`) to the
    file `out` (written to a temporary name, then renamed); return a summary. `progress(1)` is
    called after each episode. Raises ExportError on bad input."""
    import h5py

    src, out = Path(src), Path(out)
    manifest = check_source(src)
    splits = export_splits(manifest, split)
    check_out_file(src, out, overwrite)
    layout = StepLayout.from_dict(manifest["layout"])
    low, high = action_range(src)
    depth_range_m = depth_ranges(src, layout, "max")
    clipped = 0
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    masks: dict[str, list[str]] = {}
    total = 0
    try:
        with open(tmp, "wb+") as raw:
            guard = _KeepsFirstWriteError(raw)
            with h5py.File(guard, "w") as f:
                data = f.create_group("data")
                for i, ep in enumerate(iter_episodes(src, manifest, splits)):
                    actions, n_clipped = normalize_actions(ep.columns[ACTION].astype(np.float64), low, high)
                    clipped += n_clipped
                    _write_demo(data, f"demo_{i}", ep, actions, next_obs, depth_range_m)
                    guard.check()  # a full disk stops the export at the demo it fills
                    masks.setdefault(MASKS[ep.split], []).append(f"demo_{i}")
                    total += ep.length
                    progress(1)
                env_kwargs = {"recipe": manifest["name"], "recipe_hash": manifest["recipe_hash"], "control_hz": layout.fps, "sample_rate": layout.sample_rate}
                data.attrs.update(
                    total=total,
                    env_args=json.dumps({"env_name": "EchoData", "type": 4, "env_kwargs": env_kwargs}),  # type 4: not a robomimic-built env
                    source_dataset=f"out/{manifest['name']}",
                    echo_data_format=manifest["format"],
                    obs_keys=json.dumps(sorted(set(OBS_KEYS.values()) & set(data["demo_0"]["obs"].keys())) if len(data) else "[]"),
                    action_normalization=json.dumps({
                        "low": low.tolist(), "high": high.tolist(), "names": list(ACTION_NAMES), "from": "train split min/max (source meta/stats.json)",
                        "inverse": "action = low + (actions + 1) / 2 * (high - low); dimensions with high == low are stored as 0",
                    }),
                    actions_clipped=clipped,
                    depth_range_m=json.dumps({OBS_KEYS[col]: r for col, r in depth_range_m.items()}),
                    splits=json.dumps(splits),
                )
                mask = f.create_group("mask")
                for name, demos in masks.items():
                    mask.create_dataset(name, data=np.array(demos, dtype="S"))
            guard.check()  # what the flush and the close wrote
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return {
        "codebase_version": "robomimic HDF5", "total_episodes": sum(len(v) for v in masks.values()), "total_frames": total,
        "splits": {k: len(v) for k, v in masks.items()},
        "notes": [f"{clipped} action values outside the train split's range clipped to [-1, 1] (data attribute actions_clipped)"],
    }
