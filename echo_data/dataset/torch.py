"""PyTorch datasets over an echo-data dataset: single steps and windowed sequences for BC.

torch is an optional extra (this module imports it only if installed). Both datasets are
map-style and DataLoader-worker-safe: the constructor reads only the small index columns; each
worker process opens the shards it touches lazily (file handles are never shared across
processes) and keeps its decoded row groups cached, so items and batches (`take`) are gathered
from decoded arrays; `StepDataset.shuffled()` is the fast shuffled epoch. Images come back as
float tensors (RGB (3, H, W) in [0, 1], depth (1, H, W) in metres), spectrograms as float32
(F, T, 2), vectors as float32; `Normalize` applies meta/stats.json.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import DatasetMeta, StepReader, episode_spans
from echo_data.dataset.schema import ACTION, CHAIN_SLOTS, POSE_DIM, SKILL_STOP, STATE, VECTOR_COLUMNS, column_to_numpy
from echo_data.records import PRIVILEGED_COLUMNS

_INDEX_COLUMNS = ["episode_index", "frame_index", "setting", "skill"]
_SCALARS = {
    "episode_index": "int64",
    "frame_index": "int64",
    "index": "int64",
    "task_index": "int64",
    "skill_index": "int64",
    "audio_offset": "int64",
    "audio_sample_rate": "int64",
    "timestamp": "float32",
    "done": "bool",
    SKILL_STOP: "int8",
}
_STRINGS = ("setting", "skill", "audio_path")
# Decoded row groups a StepDataset keeps per worker process: at least the shuffle sampler's
# buffer, so a shuffled epoch decodes each row group once per worker (about 10 MB a group of
# 64 steps at 128x128 with mel features).
DECODED_GROUPS = 16
SHUFFLE_BUFFER_GROUPS = 8


def _torch() -> Any:
    try:
        import torch
    except ImportError:
        raise ImportError("echo_data.dataset.torch needs PyTorch: pip install 'echo-data[torch]'") from None
    return torch


class _Shards(StepReader):
    """The shards of one split (the one reader, `dataset.reader.StepReader`) and, per process,
    their decoded row groups in the loaders' form."""

    def __init__(self, root: Path, split: str) -> None:
        super().__init__(root, split)
        self.root = root
        self.layout = self.meta.layout
        self.all_columns = [f.name for f in self.layout.schema()]
        if self.files:  # a dataset built before a column existed (e.g. action.executed) offers what it has
            present = set(self.file_columns(0))
            self.all_columns = [c for c in self.all_columns if c in present]
        self._decoded: OrderedDict[tuple[int, int, tuple[str, ...]], dict[str, Any]] = OrderedDict()
        self.decoded_groups = DECODED_GROUPS

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state.update(_decoded=OrderedDict())
        return state

    def forked(self) -> None:
        self._decoded = OrderedDict()  # a new DataLoader worker decodes its own groups

    def index_columns(self) -> list[dict[str, np.ndarray]]:
        """Small per-row columns of every shard (read once, in the constructor)."""
        return [{c: t.column(c).to_numpy(zero_copy_only=False) for c in _INDEX_COLUMNS} for t in self.index_tables(_INDEX_COLUMNS)]

    def decoded_group(self, shard: int, group: int, columns: Sequence[str]) -> dict[str, Any]:
        """One row group decoded, cached per process: RGB as a uint8 tensor (n, H, W, 3), depth as
        float32 metres (n, 1, H, W), other columns as numpy in their item dtype, strings as lists."""
        self.group_starts(shard)  # resets the caches in a new worker process
        key = (shard, group, tuple(columns))
        hit = self._decoded.get(key)
        if hit is not None:
            self._decoded.move_to_end(key)
            return hit
        from echo_data.dataset.encode import decode_pngs

        torch = _torch()
        table = self.row_group(shard, group, columns)
        out: dict[str, Any] = {}
        for col in columns:
            arr = table.column(col)
            if col in self.layout.images:
                stack = decode_pngs(arr.to_pylist())
                if self.layout.images[col][0] == "rgb":
                    out[col] = torch.from_numpy(stack)
                else:
                    out[col] = torch.from_numpy(stack.astype(np.float32)[:, None] / 1000.0)
            elif col in _STRINGS:
                out[col] = arr.to_pylist()
            elif col in _SCALARS:
                out[col] = arr.to_numpy(zero_copy_only=False).astype(_SCALARS[col])
            else:
                out[col] = column_to_numpy(arr, self.shape(col)).astype(bool if col == "skill_success" else np.float32)
        self._decoded[key] = out
        while len(self._decoded) > self.decoded_groups:
            self._decoded.popitem(last=False)
        return out

    def shape(self, col: str) -> tuple[int, ...]:
        """Per-row shape of a fixed-shape list column."""
        if col in VECTOR_COLUMNS:
            return (VECTOR_COLUMNS[col],)
        if col in PRIVILEGED_COLUMNS:
            return (PRIVILEGED_COLUMNS[col],)
        if col == "skill_success":
            return (CHAIN_SLOTS,)
        if col in self.layout.pose_columns:
            return (POSE_DIM,)
        if col in self.layout.arrays:
            return self.layout.arrays[col]
        raise KeyError(f"unknown column {col!r}")


def _check_columns(shards: _Shards, columns: Sequence[str] | None, default: Sequence[str]) -> list[str]:
    cols = list(default if columns is None else columns)
    unknown = [c for c in cols if c not in shards.all_columns]
    if unknown:
        raise ValueError(f"unknown columns {unknown}; available: {shards.all_columns}")
    return cols


class StepDataset:
    """One item per control step: {column: tensor} (strings stay strings).

    `setting` / `skill` filter rows (e.g. skill="Pick"); `columns` defaults to every column
    (all fixed-shape, so the default DataLoader collate batches them).
    """

    def __init__(
        self,
        root: str | Path,
        split: str = "train",
        setting: str | None = None,
        skill: str | None = None,
        columns: Sequence[str] | None = None,
    ) -> None:
        self.shards = _Shards(Path(root), split)
        self.columns = _check_columns(self.shards, columns, self.shards.all_columns)
        shard_ids, local = [], []
        for i, cols in enumerate(self.shards.index_columns()):
            keep = np.ones(len(cols["episode_index"]), dtype=bool)
            if setting is not None:
                keep &= cols["setting"] == setting
            if skill is not None:
                keep &= cols["skill"] == skill
            rows = np.flatnonzero(keep)
            shard_ids.append(np.full(len(rows), i, dtype=np.int32))
            local.append(rows)
        self._shard = np.concatenate(shard_ids) if shard_ids else np.zeros(0, np.int32)
        self._row = np.concatenate(local) if local else np.zeros(0, np.int64)
        self._group = np.zeros(len(self._row), dtype=np.int64)  # row group of each item
        for i in range(len(self.shards.files)):
            mine = self._shard == i
            self._group[mine] = np.searchsorted(self.shards.group_starts(i), self._row[mine], side="right") - 1

    def __len__(self) -> int:
        return len(self._row)

    def __getitem__(self, i: int) -> dict[str, Any]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(i)
        return {k: v[0] for k, v in self.take([i]).items()}

    def take(self, indices: Sequence[int] | np.ndarray) -> dict[str, Any]:
        """A batch of items at once (what `default_collate` would make of `[self[i] for i in
        indices]`), gathered from the cached row groups with one indexing per column."""
        torch = _torch()
        idx = np.asarray(indices, dtype=np.int64)
        key = self._shard[idx].astype(np.int64) * (1 << 32) + self._group[idx]
        order = np.argsort(key, kind="stable")
        parts: dict[str, list[Any]] = {c: [] for c in self.columns}
        for k in np.unique(key):
            shard, group = int(k >> 32), int(k & 0xFFFFFFFF)
            local = self._row[idx[order[key[order] == k]]] - self.shards.group_starts(shard)[group]
            decoded = self.shards.decoded_group(shard, group, self.columns)
            for c in self.columns:
                v = decoded[c]
                parts[c].append([v[j] for j in local] if c in _STRINGS else v[torch.from_numpy(local)] if isinstance(v, torch.Tensor) else v[local])
        back = np.argsort(order)  # rows were gathered group by group: restore the asked order
        images = self.shards.layout.images
        out: dict[str, Any] = {}
        for c, ps in parts.items():
            if c in _STRINGS:
                flat = [x for p in ps for x in p]
                out[c] = [flat[j] for j in back]
            elif c in images:
                t = torch.cat(ps)[torch.from_numpy(back)]
                out[c] = t.permute(0, 3, 1, 2).float().div(255.0) if images[c][0] == "rgb" else t
            else:
                out[c] = torch.from_numpy(np.concatenate(ps)[back])
        return out

    def shuffled(self, seed: int = 0, buffer_groups: int = SHUFFLE_BUFFER_GROUPS, batch_size: int | None = None) -> ShuffledSteps:
        """This dataset in shuffled order for fast training epochs (see `ShuffledSteps`)."""
        return ShuffledSteps(self, seed, buffer_groups, batch_size)


try:  # the iterable form needs torch's base class (torch stays an optional extra)
    from torch.utils.data import IterableDataset as _IterableBase
except ImportError:  # pragma: no cover - without torch nothing here can be iterated anyway
    _IterableBase = object  # type: ignore[assignment,misc]


class ShuffledSteps(_IterableBase):
    """A `StepDataset` shuffled by row groups with a buffer, for DataLoader epochs.

    Row groups come in a random order (seed, epoch) and are dealt to DataLoader workers in turn,
    so each worker decodes only its own groups, once per epoch; a worker takes `buffer_groups`
    of them at a time and yields their steps in random order. Uniform shuffling instead decodes
    a whole row group for nearly every item once the data outgrows the workers' caches. Each
    `iter()` is a new epoch with a new order; every step comes exactly once per epoch.

    With `batch_size`, whole batches are yielded (gathered column by column, much cheaper than
    collating items): use `DataLoader(..., batch_size=None)`. A worker's last batch of an epoch
    may be smaller."""

    def __init__(self, dataset: StepDataset, seed: int = 0, buffer_groups: int = SHUFFLE_BUFFER_GROUPS, batch_size: int | None = None) -> None:
        if not 1 <= buffer_groups <= dataset.shards.decoded_groups:
            raise ValueError(f"buffer_groups must be 1..{dataset.shards.decoded_groups} (the decoded groups a worker keeps), got {buffer_groups}")
        if batch_size is not None and batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        self.dataset, self.seed, self.buffer, self.epoch, self.batch_size = dataset, seed, buffer_groups, 0, batch_size
        key = dataset._shard.astype(np.int64) * (1 << 32) + dataset._group
        self._groups = [np.flatnonzero(key == k) for k in np.unique(key)]

    def __len__(self) -> int:
        """Items per epoch (batches are counted as their items)."""
        return len(self.dataset)

    def __iter__(self) -> Iterator[Any]:
        torch = _torch()
        info = torch.utils.data.get_worker_info()
        worker, workers = (info.id, info.num_workers) if info is not None else (0, 1)
        order = np.random.default_rng([self.seed, self.epoch]).permutation(len(self._groups))
        rng = np.random.default_rng([self.seed, self.epoch, worker])
        self.epoch += 1
        mine = order[worker::workers]
        for w in range(0, len(mine), self.buffer):
            window = rng.permutation(np.concatenate([self._groups[g] for g in mine[w : w + self.buffer]]))
            if self.batch_size is None:
                yield from (self.dataset[int(i)] for i in window)
            else:
                for b in range(0, len(window), self.batch_size):
                    yield self.dataset.take(window[b : b + self.batch_size])


class SequenceDataset:
    """Windows for behaviour cloning: for each step t, observations of steps t-history+1..t and
    actions of steps t..t+action_chunk-1, clamped to the episode (with `observation_is_pad` /
    `action_is_pad` masks, LeRobot style). Windows never cross episodes (nor shards).
    `action`: the column the chunk is read from (`action`, or its end-effector form `action.ee`),
    returned under its own name."""

    def __init__(
        self,
        root: str | Path,
        split: str = "train",
        history: int = 2,
        action_chunk: int = 8,
        setting: str | None = None,
        skill: str | None = None,
        observations: Sequence[str] | None = None,
        action: str = ACTION,
    ) -> None:
        if history < 1 or action_chunk < 1:
            raise ValueError("history and action_chunk must be >= 1")
        self.history, self.action_chunk = history, action_chunk
        self.shards = _Shards(Path(root), split)
        default_obs = [STATE] + list(self.shards.layout.images) + list(self.shards.layout.arrays)
        self.observations = _check_columns(self.shards, observations, default_obs)
        # every step of the split, in shard order: windows are gathered from it
        self.action = _check_columns(self.shards, [action], [])[0]
        self._steps = StepDataset(root, split, columns=list(dict.fromkeys(self.observations + [self.action, "episode_index", "frame_index", "index"])))
        self._offset = np.concatenate([[0], np.cumsum([len(c["episode_index"]) for c in self.shards.index_columns()])])
        shard_parts: list[np.ndarray] = []
        row_parts: list[np.ndarray] = []
        first_parts: list[np.ndarray] = []
        last_parts: list[np.ndarray] = []
        for i, cols in enumerate(self.shards.index_columns()):
            for s, e in episode_spans(cols["episode_index"]):
                keep = np.ones(e - s, dtype=bool)
                if setting is not None:
                    keep &= cols["setting"][s:e] == setting
                if skill is not None:
                    keep &= cols["skill"][s:e] == skill
                rows = s + np.flatnonzero(keep)
                shard_parts.append(np.full(len(rows), i, dtype=np.int32))
                row_parts.append(rows)
                first_parts.append(np.full(len(rows), s))
                last_parts.append(np.full(len(rows), e - 1))
        cat = lambda parts, dt: np.concatenate(parts).astype(dt) if parts else np.zeros(0, dt)  # noqa: E731
        self._shard = cat(shard_parts, np.int32)
        self._row, self._first, self._last = (cat(x, np.int64) for x in (row_parts, first_parts, last_parts))

    def __len__(self) -> int:
        return len(self._row)

    def __getitem__(self, i: int) -> dict[str, Any]:
        torch = _torch()
        if not 0 <= i < len(self):
            raise IndexError(i)
        t, first, last, shard = int(self._row[i]), int(self._first[i]), int(self._last[i]), int(self._shard[i])
        obs_rows = np.arange(t - self.history + 1, t + 1)
        act_rows = np.arange(t, t + self.action_chunk)
        obs_pad = obs_rows < first
        act_pad = act_rows > last
        base = int(self._offset[shard])
        obs = self._steps.take(base + obs_rows.clip(first, last))  # its last row is step t
        item = {c: obs[c] for c in self.observations}
        item[self.action] = self._steps.take(base + act_rows.clip(first, last))[self.action]
        item.update({k: obs[k][-1] for k in ("episode_index", "frame_index", "index")})
        item["observation_is_pad"] = torch.from_numpy(obs_pad)
        item["action_is_pad"] = torch.from_numpy(act_pad)
        return item


class Normalize:
    """Normalisation from meta/stats.json (train split) as a transform on items or batches.

    mode "mean_std": (x - mean) / std; "min_max": to [-1, 1] (LeRobot's conventions). Statistics
    are in the loaders' units (RGB in [0, 1], depth in metres) and shaped to broadcast: images
    per channel (C, 1, 1) as the loaders return (C, H, W); spectrograms per ear (last axis);
    vectors per element. Columns without statistics pass through; `inverse` undoes it (e.g. to
    turn a predicted action back into robot units)."""

    def __init__(self, root: str | Path, mode: str = "mean_std", columns: Sequence[str] | None = None, eps: float = 1e-8) -> None:
        import json

        if mode not in ("mean_std", "min_max"):
            raise ValueError(f"mode must be mean_std or min_max, got {mode!r}")
        torch = _torch()
        stats = json.loads((Path(root) / "meta" / "stats.json").read_text())
        layout = DatasetMeta.of(root).layout
        self.mode = mode
        self.params: dict[str, tuple[Any, Any]] = {}
        for col, st in stats.items():
            if columns is not None and col not in columns:
                continue
            a, b = (st["mean"], st["std"]) if mode == "mean_std" else (st["min"], st["max"])
            a, b = torch.tensor(a, dtype=torch.float32), torch.tensor(b, dtype=torch.float32)
            scale = b.clamp_min(eps) if mode == "mean_std" else ((b - a) / 2).clamp_min(eps)
            shift = a if mode == "mean_std" else (a + b) / 2
            if col in layout.images:
                shift, scale = shift.reshape(-1, 1, 1), scale.reshape(-1, 1, 1)
            self.params[col] = (shift, scale)

    def __call__(self, item: dict[str, Any]) -> dict[str, Any]:
        out = dict(item)
        for col, (shift, scale) in self.params.items():
            if col in out:
                out[col] = (out[col] - shift) / scale
        return out

    def inverse(self, column: str, x: Any) -> Any:
        """Undo the normalisation of one column."""
        shift, scale = self.params[column]
        return x * scale + shift
