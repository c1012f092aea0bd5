"""The one reader of a built dataset: its manifest, the recipe it holds, `meta/episodes.parquet`,
its shard files, one episode's rows, and step rows by row number or window.

Every module that reads a dataset (commands, learners, exports, pictures) comes here, so where a
file lives and how a damaged one is reported is decided once.

`DatasetMeta` is what a dataset says about itself without reading a frame (manifest, step layout,
shard files per split, the step-row schema, statistics). `StepIndex` holds one split's index
columns (episode, skill, skill_index, frame_index) and the segment each row belongs to, a
segment being a run of rows with the same (episode_index, skill_index) (a chain may Navigate
twice). `StepReader` decodes the frames of chosen rows (one row group at a time, PNG through
`encode.decode_png`) and serves windows, LeRobot-style: for a row t and delta indices
(-1, 0, 1, 2) the rows t-1 .. t+2, clamped to the row's segment (or episode) with a mask that is
True where a delta fell outside it (LeRobot's `*_is_pad`). Observation history is negative
deltas, an action chunk deltas 0..k-1.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset.encode import decode_pngs
from echo_data.dataset.manifest import MANIFEST, ManifestError, load_manifest
from echo_data.dataset.schema import StepLayout, column_to_numpy

INDEX_COLUMNS = ("episode_index", "skill", "skill_index", "frame_index")
EPISODES = Path("meta") / "episodes.parquet"  # one record per episode (dataset/writer writes it)


class EpisodeError(ValueError):
    """An episode the dataset does not hold, or holds no steps of: one line naming the dataset."""


def episodes_table(root: Path, columns: Sequence[str] | None = None) -> pa.Table:
    """`meta/episodes.parquet` of the dataset at `root` (all columns, or `columns`)."""
    return pq.read_table(Path(root) / EPISODES, columns=list(columns) if columns is not None else None)


def episode_records(root: Path, columns: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The episode records as dicts, in the file's order (split, then index)."""
    return list(episodes_table(root, columns).to_pylist())


def episode_rows(root: Path, split: str, index: int) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Episode `index` of `split`: its record and its step rows in order."""
    import pyarrow.compute as pc

    root = Path(root)
    m = load_manifest(root)
    episodes = episodes_table(root)
    found = episodes.filter(pc.and_(pc.equal(episodes["split"], split), pc.equal(episodes["episode_index"], index))).to_pylist()
    if not found:
        n = m["counts"]["episodes"].get(split, 0)
        raise EpisodeError(f"{root}: no {split} episode {index} (the {split} split has {n} episodes: 0..{n - 1})")
    ep = found[0]
    table = pq.read_table(root / "data" / ep["shard"], filters=[("episode_index", "=", index)])
    return ep, table.to_pylist()


def split_shards(manifest: dict[str, Any], split: str) -> list[dict[str, Any]]:
    """The manifest's entries of `split`'s shard files, in order (where every reader finds shards)."""
    return [e for e in manifest["shards"] if e["split"] == split]


def dataset_manifest(root: Path, split: str | None = None, why: str = "") -> dict[str, Any]:
    """The checked manifest of the dataset at `root` (`manifest.load_manifest`); with `split`, a
    dataset without that split is refused in one line ending in `why`."""
    root = Path(root)
    if not (root / MANIFEST).is_file():
        raise ManifestError(f"{root}: not an echo-data dataset (no {MANIFEST})")
    m = load_manifest(root)
    if split is not None and split not in m["splits"]:
        raise ManifestError(f"{root / MANIFEST}: no {split!r} split{' ' + why if why else ''}")
    return m


def dataset_recipe(root: Path) -> tuple[Any, int]:
    """The recipe a dataset was built from (its manifest's copy) and its train episode count."""
    from echo_data.recipe import recipe_from_mapping

    m = dataset_manifest(Path(root))
    return recipe_from_mapping(m["recipe"], source=str(Path(root) / MANIFEST)), int(m["splits"].get("train", {}).get("episodes", 0))


@dataclass(frozen=True)
class DatasetMeta:
    """A dataset's description, read without decoding frames."""

    root: Path
    manifest: dict[str, Any]
    layout: StepLayout

    @staticmethod
    def of(root: Path | str) -> DatasetMeta:
        root = Path(root)
        manifest = load_manifest(root)
        return DatasetMeta(root, manifest, StepLayout.from_dict(manifest["layout"]))

    @property
    def splits(self) -> list[str]:
        return list(self.manifest["splits"])

    def files(self, split: str) -> list[Path]:
        """The split's shard files in order (ValueError naming the split when it has none)."""
        if split not in self.manifest["splits"]:
            raise ValueError(f"{self.root}: no split {split!r} (has {', '.join(self.manifest['splits'])})")
        return [self.root / e["file"] for e in split_shards(self.manifest, split)]

    @cached_property
    def schema(self) -> pa.Schema:
        """The step rows' Arrow schema (from the first shard's footer)."""
        for e in self.manifest["shards"]:
            return pq.read_schema(self.root / e["file"])
        return pa.schema([])

    @property
    def columns(self) -> list[str]:
        return list(self.schema.names)

    def vector_size(self, column: str) -> int | None:
        """Entries of a fixed-size float-list column (None: no such column or not a vector)."""
        if column not in self.schema.names:
            return None
        t = self.schema.field(column).type
        if isinstance(t, pa.BaseExtensionType):
            t = t.storage_type
        return int(t.list_size) if pa.types.is_fixed_size_list(t) else None

    def stats(self) -> dict[str, Any]:
        return json.loads((self.root / "meta" / "stats.json").read_text())


@dataclass
class StepIndex:
    """One split's index columns (rows in shard order) and where each row sits on disk."""

    episode: np.ndarray  # (n,) episode_index
    skill: np.ndarray  # (n,) skill name
    skill_index: np.ndarray  # (n,) position of the skill in the episode's chain
    frame: np.ndarray  # (n,) frame_index
    shard: np.ndarray  # (n,) position of the row's file in the split's file list
    local: np.ndarray  # (n,) row within that file

    def __len__(self) -> int:
        return len(self.episode)

    @cached_property
    def segment(self) -> np.ndarray:
        """(n,) segment id: runs of equal (episode, skill_index), numbered over the split."""
        ep, si = self.episode, self.skill_index
        new = np.concatenate([[True], (ep[1:] != ep[:-1]) | (si[1:] != si[:-1])]) if len(ep) else np.zeros(0, bool)
        return np.cumsum(new) - 1

    def bounds(self, within: str = "segment") -> tuple[np.ndarray, np.ndarray]:
        """(first, last) row of each row's segment or episode (inclusive)."""
        key = self.segment if within == "segment" else self.episode
        if within not in ("segment", "episode"):
            raise ValueError(f"within: {within!r} is not segment or episode")
        new = np.concatenate([[True], key[1:] != key[:-1]]) if len(key) else np.zeros(0, bool)
        run = np.cumsum(new) - 1
        starts = np.flatnonzero(new)
        ends = np.concatenate([starts[1:], [len(key)]]) - 1
        return starts[run], ends[run]

    def window(self, rows: np.ndarray, deltas: Sequence[int], within: str = "segment") -> tuple[np.ndarray, np.ndarray]:
        """Row numbers rows[i] + deltas[j] clamped to the row's segment (or episode), (n, len(deltas)),
        and the pad mask (True where the delta fell outside)."""
        first, last = self.bounds(within)
        rows = np.asarray(rows, dtype=np.int64)
        t = rows[:, None] + np.asarray(deltas, dtype=np.int64)[None, :]
        lo, hi = first[rows][:, None], last[rows][:, None]
        return np.clip(t, lo, hi), (t < lo) | (t > hi)


class StepReader:
    """Frames of one split, decoded on request: `read(columns, rows)` and `windows(...)`."""

    def __init__(self, root: Path | str, split: str, meta: DatasetMeta | None = None) -> None:
        self.meta = meta or DatasetMeta.of(root)
        self.split = split
        self.files = self.meta.files(split)
        self._pf: dict[int, pq.ParquetFile] = {}

    def _file(self, i: int) -> pq.ParquetFile:
        if i not in self._pf:
            self._pf[i] = pq.ParquetFile(self.files[i])
        return self._pf[i]

    @cached_property
    def index(self) -> StepIndex:
        parts: dict[str, list[np.ndarray]] = {c: [] for c in ("episode", "skill", "skill_index", "frame", "shard", "local")}
        for i, f in enumerate(self.files):
            t = pq.read_table(f, columns=list(INDEX_COLUMNS))
            n = t.num_rows
            parts["episode"].append(t.column("episode_index").to_numpy())
            parts["skill"].append(np.asarray(t.column("skill").to_pylist(), dtype=object))
            parts["skill_index"].append(t.column("skill_index").to_numpy())
            parts["frame"].append(t.column("frame_index").to_numpy())
            parts["shard"].append(np.full(n, i, dtype=np.int64))
            parts["local"].append(np.arange(n, dtype=np.int64))
        cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in parts.items()}
        return StepIndex(cat["episode"], cat["skill"], cat["skill_index"], cat["frame"], cat["shard"], cat["local"])

    def decode(self, table: pa.Table, columns: Sequence[str]) -> dict[str, np.ndarray]:
        """Arrow rows -> {column: (rows, ...)}: images as stored (uint8 RGB, uint16 mm depth),
        fixed-shape float columns as float32, other columns as numpy."""
        out: dict[str, np.ndarray] = {}
        arrays = self.meta.layout.arrays
        for col in columns:
            data = table.column(col)
            if col in self.meta.layout.images:
                out[col] = decode_pngs(data.to_pylist())
            elif col in arrays:
                out[col] = column_to_numpy(data, arrays[col]).astype(np.float32)
            else:
                size = self.meta.vector_size(col)
                out[col] = column_to_numpy(data, (size,)).astype(np.float32) if size is not None else np.asarray(data.to_pylist())
        return out

    def read(self, columns: Sequence[str], rows: np.ndarray | None = None, tick: Callable[[int], object] | None = None) -> dict[str, np.ndarray]:
        """Columns of split rows `rows` (global row numbers, any order; None = all), decoded one row
        group at a time so memory holds only the rows asked for."""
        idx = self.index
        rows = np.arange(len(idx)) if rows is None else np.asarray(rows, dtype=np.int64)
        parts: dict[str, list[np.ndarray]] = {c: [] for c in columns}
        order: list[np.ndarray] = []
        for shard in np.unique(idx.shard[rows]):
            pf = self._file(int(shard))
            sizes = [pf.metadata.row_group(g).num_rows for g in range(pf.num_row_groups)]
            group_start = np.concatenate([[0], np.cumsum(sizes)])
            mine = np.flatnonzero(idx.shard[rows] == shard)
            local = idx.local[rows[mine]]
            group_of = np.searchsorted(group_start, local, side="right") - 1
            for g in np.unique(group_of):
                sel = mine[group_of == g]
                table = pf.read_row_group(int(g), columns=list(columns)).take(pa.array(idx.local[rows[sel]] - group_start[g]))
                for c, v in self.decode(table, columns).items():
                    parts[c].append(v)
                order.append(sel)
                if tick is not None:
                    tick(len(sel))
        if not order:
            return {c: np.zeros((0,)) for c in columns}
        back = np.argsort(np.concatenate(order), kind="stable")
        return {c: np.concatenate(v)[back] for c, v in parts.items()}

    def windows(self, rows: np.ndarray, deltas: dict[str, Sequence[int]], within: str = "segment") -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """For each column its rows rows[i] + delta, (n, len(deltas), ...), and the pad masks
        (n, len(deltas)): LeRobot's `delta_timestamps` in frames, clamped within a segment."""
        values, pads = {}, {}
        for col, d in deltas.items():
            at, pad = self.index.window(rows, d, within)
            flat = self.read([col], at.reshape(-1))[col]
            values[col] = flat.reshape(*at.shape, *flat.shape[1:])
            pads[col] = pad
        return values, pads
