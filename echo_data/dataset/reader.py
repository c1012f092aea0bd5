"""The one reader of a built dataset: its manifest, the recipe it holds, `meta/episodes.parquet`,
its shard files, one episode's rows, step rows by row number, row group, episode or window, and
an episode's WAV.

Every module that reads a dataset (commands, learners, exports, pictures, the torch loaders)
comes here, so where a file lives and how a damaged one is reported is decided once;
tests/test_reader.py fails when a module elsewhere opens a dataset's files itself. The
exceptions, and why: the writers (`manifest.py` owns the manifest's format and loads it through
`load_manifest`, which `read_manifest` here is; `shards.py` reads back the record a shard carries
for the build that wrote it; `app/build.py` resumes from its own manifest; `written.py` reads a
manifest of any format before `--overwrite` replaces it) and `validate.py`, whose job is to read
the raw files and bytes to check them, so it must not go through the reader it checks.

`DatasetMeta` is what a dataset says about itself without reading a frame (manifest, step layout,
shard files per split, the step-row schema, statistics). `StepIndex` holds one split's index
columns (episode, skill, skill_index, frame_index) and the segment each row belongs to, a
segment being a run of rows with the same (episode_index, skill_index) (a chain may Navigate
twice). `StepReader` is the one row reader of a split: it finds the split's shards and reads the
chosen columns only (Parquet column projection), a whole shard, one row group or the row groups
holding chosen rows at a time, per episode (`episodes`) or as batches (`batches`, `read`); the
torch loaders (`dataset.torch`), training's rows (`learn.data`) and the array exports
(`episode_arrays.iter_episodes`) are views of it. It decodes the frames of chosen rows (PNG
through `encode.decode_png`) and serves windows, LeRobot-style: for a row t and delta indices
(-1, 0, 1, 2) the rows t-1 .. t+2, clamped to the row's segment (or episode) with a mask that is
True where a delta fell outside it (LeRobot's `*_is_pad`). Observation history is negative
deltas, an action chunk deltas 0..k-1. File handles are per process: a reader sent to a
DataLoader worker (pickled or forked) opens its own.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterator, Sequence
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


def is_dataset(root: Path) -> bool:
    """Whether `root` holds a dataset's manifest (what a command checks before it says more)."""
    return (Path(root) / MANIFEST).is_file()


def has_episode_records(root: Path) -> bool:
    """Whether `root` holds `meta/episodes.parquet` (an unfinished build does not yet)."""
    return (Path(root) / EPISODES).is_file()


def read_manifest(root: Path) -> dict[str, Any]:
    """The manifest of the dataset at `root`, its shape checked (`manifest.load_manifest`: one
    `ManifestError` naming the file and key)."""
    return load_manifest(Path(root))


def episode_audio(root: Path, record: dict[str, Any]) -> tuple[np.ndarray, int]:
    """The whole binaural WAV of an episode record (its `audio_path`): float32 (n, 2) and the rate."""
    import soundfile as sf

    audio, sr = sf.read(Path(root) / record["audio_path"], dtype="float32", always_2d=True)
    return audio, int(sr)


def audio_samples(root: Path | str, audio_path: str, start: int, stop: int, rate: int) -> np.ndarray:
    """Samples [start, stop) of an episode WAV (`audio_path`, relative to the dataset) as float32
    (n, channels), zeros outside the recording; reads only those samples. ValueError when the file's
    rate is not `rate` (what the step row says)."""
    import soundfile as sf

    path = Path(root) / audio_path
    with sf.SoundFile(path) as f:
        if f.samplerate != rate:
            raise ValueError(f"{path}: sample rate {f.samplerate}, the step row says {rate}")
        lo, hi = max(start, 0), min(stop, f.frames)
        out = np.zeros((stop - start, f.channels), dtype=np.float32)
        if hi > lo:
            f.seek(lo)
            out[lo - start : hi - start] = f.read(hi - lo, dtype="float32", always_2d=True)
    return out


def episode_spans(episode: np.ndarray) -> list[tuple[int, int]]:
    """(first, end) rows of each run of equal `episode` values: the episodes of a shard's rows."""
    bounds = np.flatnonzero(np.diff(episode)) + 1
    return [(int(lo), int(hi)) for lo, hi in zip(np.concatenate([[0], bounds]), np.concatenate([bounds, [len(episode)]]))]


def split_tables(root: Path, manifest: dict[str, Any], split: str, columns: Sequence[str] | None = None) -> Iterator[pa.Table]:
    """Each shard of `split` as one table (all columns, or `columns`), in order: one shard in memory."""
    reader = StepReader(root, split, DatasetMeta.from_manifest(root, manifest))
    yield from (reader.shard_table(i, columns) for i in range(len(reader.files)))


def split_shards(manifest: dict[str, Any], split: str) -> list[dict[str, Any]]:
    """The manifest's entries of `split`'s shard files, in order (where every reader finds shards)."""
    return [e for e in manifest["shards"] if e["split"] == split]


def dataset_manifest(root: Path, split: str | None = None, why: str = "") -> dict[str, Any]:
    """The checked manifest of the dataset at `root` (`manifest.load_manifest`); with `split`, a
    dataset without that split is refused in one line ending in `why`."""
    root = Path(root)
    if not is_dataset(root):
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


def vector_size(schema: pa.Schema, column: str) -> int | None:
    """Entries of a fixed-size float-list column of `schema` (None: no such column or not a vector)."""
    if column not in schema.names:
        return None
    t = schema.field(column).type
    if isinstance(t, pa.BaseExtensionType):
        t = t.storage_type
    return int(t.list_size) if pa.types.is_fixed_size_list(t) else None


@dataclass(frozen=True)
class DatasetMeta:
    """A dataset's description, read without decoding frames."""

    root: Path
    manifest: dict[str, Any]
    layout: StepLayout

    @staticmethod
    def of(root: Path | str) -> DatasetMeta:
        root = Path(root)
        return DatasetMeta.from_manifest(root, load_manifest(root))

    @staticmethod
    def from_manifest(root: Path | str, manifest: dict[str, Any]) -> DatasetMeta:
        """The description from a manifest already read (an export holds it)."""
        return DatasetMeta(Path(root), manifest, StepLayout.from_dict(manifest["layout"]))

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
        return vector_size(self.schema, column)

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
    """The step rows of one split: its shard files, read with column projection a shard, a row
    group or an episode at a time (`shard_table`, `row_group`, `batches`, `episodes`), and its
    frames decoded on request (`read(columns, rows)`, `windows(...)`)."""

    def __init__(self, root: Path | str, split: str, meta: DatasetMeta | None = None) -> None:
        self.meta = meta or DatasetMeta.of(root)
        self.split = split
        self.files = self.meta.files(split)
        self._pid: int | None = None
        self._pf: dict[int, tuple[pq.ParquetFile, np.ndarray]] = {}

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.update(_pid=None, _pf={})  # file handles never travel to another process
        return state

    def forked(self) -> None:
        """Called when this reader first reads in a new process (a DataLoader worker): a view
        drops what it cached in the parent here."""

    def _open(self, shard: int) -> tuple[pq.ParquetFile, np.ndarray]:
        if self._pid != os.getpid():  # a new process: never reuse the parent's handles
            self._pid, self._pf = os.getpid(), {}
            self.forked()
        if shard not in self._pf:
            pf = pq.ParquetFile(self.files[shard])
            sizes = [pf.metadata.row_group(g).num_rows for g in range(pf.num_row_groups)]
            self._pf[shard] = (pf, np.concatenate([[0], np.cumsum(sizes)]))
        return self._pf[shard]

    def _file(self, shard: int) -> pq.ParquetFile:
        return self._open(shard)[0]

    def group_starts(self, shard: int) -> np.ndarray:
        """First shard-local row of each row group of a shard, plus its row count at the end."""
        return self._open(shard)[1]

    @cached_property
    def offsets(self) -> np.ndarray:
        """The split's first row number of each shard, plus its row count at the end (from the
        files' footers: no column is read)."""
        return np.concatenate([[0], np.cumsum([self.group_starts(i)[-1] for i in range(len(self.files))])]).astype(np.int64)

    def file_columns(self, shard: int) -> list[str]:
        """The columns a shard file stores (its footer)."""
        return list(self._file(shard).schema_arrow.names)

    def row_group(self, shard: int, group: int, columns: Sequence[str]) -> pa.Table:
        """One row group of a shard, only `columns`."""
        return self._file(shard).read_row_group(group, columns=list(columns))

    def shard_table(self, shard: int, columns: Sequence[str] | None = None) -> pa.Table:
        """A whole shard (all columns, or `columns`)."""
        return pq.read_table(self.files[shard], columns=list(columns) if columns is not None else None)

    def index_tables(self, columns: Sequence[str]) -> list[pa.Table]:
        """Small per-row columns of every shard, one table per shard (only those column chunks are read)."""
        return [self._file(i).read(columns=list(columns)) for i in range(len(self.files))]

    def episodes(self, columns: Sequence[str] | None = None) -> Iterator[pa.Table]:
        """Each episode's rows (all columns, or `columns` plus episode_index), in shard order,
        one shard in memory at a time."""
        cols = None if columns is None else list(dict.fromkeys([*columns, "episode_index"]))
        for i in range(len(self.files)):
            table = self.shard_table(i, cols)
            for lo, hi in episode_spans(table.column("episode_index").to_numpy()):
                yield table.slice(lo, hi - lo)

    def batches(self, rows: np.ndarray, columns: Sequence[str]) -> Iterator[tuple[np.ndarray, pa.Table]]:
        """The split rows `rows` (global row numbers, any order) a row group at a time, each row
        group read once: (positions in `rows`, their `columns` in that order)."""
        rows = np.asarray(rows, dtype=np.int64)
        shard_of = np.searchsorted(self.offsets, rows, side="right") - 1
        for shard in np.unique(shard_of):
            group_start = self.group_starts(int(shard))
            mine = np.flatnonzero(shard_of == shard)
            local = rows[mine] - self.offsets[shard]
            group_of = np.searchsorted(group_start, local, side="right") - 1
            for g in np.unique(group_of):
                sel = mine[group_of == g]
                yield sel, self.row_group(int(shard), int(g), columns).take(pa.array(local[group_of == g] - group_start[g]))

    @cached_property
    def index(self) -> StepIndex:
        parts: dict[str, list[np.ndarray]] = {c: [] for c in ("episode", "skill", "skill_index", "frame", "shard", "local")}
        for i, t in enumerate(self.index_tables(INDEX_COLUMNS)):
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
                size = vector_size(table.schema, col)  # the rows' own schema: no footer read
                out[col] = column_to_numpy(data, (size,)).astype(np.float32) if size is not None else np.asarray(data.to_pylist())
        return out

    def read(self, columns: Sequence[str], rows: np.ndarray | None = None, tick: Callable[[int], object] | None = None) -> dict[str, np.ndarray]:
        """Columns of split rows `rows` (global row numbers, any order; None = all), decoded one row
        group at a time so memory holds only the rows asked for."""
        rows = np.arange(self.offsets[-1]) if rows is None else np.asarray(rows, dtype=np.int64)
        parts: dict[str, list[np.ndarray]] = {c: [] for c in columns}
        order: list[np.ndarray] = []
        for sel, table in self.batches(rows, columns):
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
