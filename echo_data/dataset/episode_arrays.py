"""One stored episode at a time as numpy arrays: what the array-store exports (robomimic HDF5,
Diffusion Policy Zarr) write, read once from the shards in split and episode order.

Images are decoded (RGB uint8 (T, H, W, 3), depth uint16 millimetres (T, H, W)); spectrograms
keep their (T, F, time, ear) shape; every other fixed-size column becomes (T, ...) as stored.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from echo_data.dataset.manifest import ManifestError
from echo_data.dataset.reader import DatasetMeta, StepReader, episodes_table, read_manifest
from echo_data.dataset.schema import StepLayout
from echo_data.episode import SPLIT_KEYS

STRING_COLUMNS = ("setting", "skill", "audio_path")
DEPTH_STEP_M = 0.5  # depth ranges are rounded up to this


def depth_ranges(src: Path, layout: StepLayout, stat: str = "q99") -> dict[str, float]:
    """Per depth camera, the metres an export maps to its top value (255 in LeRobot's 8-bit
    images, 1.0 in robomimic's float depth): the source's train-split `stat` of depth
    (meta/stats.json, metres; its maximum where the quantile is not stored) rounded up to
    DEPTH_STEP_M. LeRobot's 8-bit images use the 99th percentile: the maximum would spend the 256
    levels on a few far pixels (the wrist camera sees 9 m across a room now and then but mostly
    works within 3.5 m); robomimic's float32 depth uses the maximum, so no train pixel clips."""
    stats = json.loads((src / "meta" / "stats.json").read_text())
    out = {}
    for col, (kind, _, _) in layout.images.items():
        if kind == "depth":
            st = stats.get(col, {})
            top = max(st.get(stat) or st.get("max") or [0.0])
            out[col] = max(DEPTH_STEP_M, float(np.ceil(top / DEPTH_STEP_M) * DEPTH_STEP_M))
    return out


class ExportError(ValueError):
    """Bad input for an export (not a complete dataset, output exists): exit 2, nothing written."""


@dataclass
class EpisodeArrays:
    split: str
    record: dict[str, Any]  # the row of meta/episodes.parquet
    columns: dict[str, np.ndarray]  # step column -> (T, ...)
    strings: dict[str, list[str]]  # setting, skill, audio_path per step

    @property
    def length(self) -> int:
        return len(self.columns["frame_index"])


def check_source(src: Path) -> dict[str, Any]:
    """The manifest of a complete dataset, or ExportError naming what is wrong."""
    try:
        manifest = read_manifest(src)
    except ManifestError as e:
        raise ExportError(str(e)) from None
    if not manifest.get("complete"):
        raise ExportError(f"{src}: the build is not complete (finish it with `echo-data build --resume`)")
    return manifest


def _check_apart(src: Path, out: Path) -> None:
    """An export is never written into its source dataset, onto it, or around it (an
    `--overwrite` of a parent folder would delete the dataset and its neighbours)."""
    from echo_data.dataset.written import apart_problem

    why = apart_problem(src, out, "source dataset")
    if why:
        raise ExportError(why)


def check_out_file(src: Path, out: Path, overwrite: bool) -> None:
    """Refuse an output inside or around the source, an existing one without --overwrite, and
    with it any file that is not an echo-data robomimic export (checked by its HDF5 attributes)."""
    _check_apart(src, out)
    if out.exists() and not (overwrite and out.is_file()):
        raise ExportError(f"{out} already exists" + ("; use --overwrite to replace it" if out.is_file() else " and is a folder"))
    if out.exists() and not _is_our_hdf5(out):
        raise ExportError(f"{out}: not an echo-data robomimic export; --overwrite replaces only what echo-data wrote (nothing was touched)")


def _is_our_hdf5(path: Path) -> bool:
    """Whether `path` is an HDF5 file whose `data` group carries echo-data's format attribute."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return isinstance(f.get("data"), h5py.Group) and "echo_data_format" in f["data"].attrs
    except Exception:  # h5py raises OSError, KeyError, ... for files that are no HDF5
        return False


def check_out_folder(src: Path, out: Path, overwrite: bool, kind: str) -> None:
    """Refuse an output inside or around the source, a file, an existing folder without
    --overwrite, and with it a folder holding anything echo-data's `kind` export did not write."""
    from echo_data.dataset.written import NotWrittenByUs, written_files

    _check_apart(src, out)
    if out.exists() and not (overwrite and out.is_dir()):
        raise ExportError(f"{out} already exists" + ("; use --overwrite to replace it" if out.is_dir() else " and is not a folder"))
    if out.exists():
        try:
            written_files(out, kind)
        except NotWrittenByUs as e:
            raise ExportError(str(e)) from None


def decode_images(column: pa.ChunkedArray) -> np.ndarray:
    """PNG cells of an image column -> (T, H, W[, C]) pixels as stored (depth stays uint16 mm)."""
    from echo_data.dataset.encode import decode_pngs

    return decode_pngs(column.to_pylist())


def column_values(data: pa.ChunkedArray, n: int) -> np.ndarray:
    """A fixed-shape column of n rows (nested lists, fixed-size lists, Array3D) as (n, ...)."""
    arr = data.combine_chunks()
    if isinstance(arr, pa.ExtensionArray):
        arr = arr.storage
    shape: list[int] = []
    while isinstance(arr.type, (pa.ListType, pa.FixedSizeListType, pa.LargeListType)):
        arr = arr.flatten()
        shape.append(len(arr) // max(n * int(np.prod(shape or [1])), 1))
    return np.asarray(arr.to_numpy(zero_copy_only=False)).reshape(n, *shape)


def export_splits(manifest: dict[str, Any], split: str | None) -> list[str]:
    """The splits an export holds, train first: all of them, or the one `--split` names (an
    export per split keeps a consumer that draws its own validation episodes off the test ones)."""
    splits = sorted(manifest["splits"], key=SPLIT_KEYS.__getitem__)
    if split is None:
        return splits
    if split not in splits:
        raise ExportError(f"--split {split}: the dataset has no such split (it has {', '.join(splits)})")
    return [split]


def iter_episodes(src: Path, manifest: dict[str, Any], splits: list[str] | None = None) -> Iterator[EpisodeArrays]:
    """Every stored episode of `splits` (default: all), train first (then val, test), in episode
    order within a split (`reader.StepReader.episodes`: one shard in memory at a time)."""
    meta = DatasetMeta.from_manifest(src, manifest)
    records = {(r["split"], r["episode_index"]): r for r in episodes_table(src).to_pylist()}
    for split in splits if splits is not None else export_splits(manifest, None):
        for rows in StepReader(src, split, meta).episodes():
            n = rows.num_rows
            cols: dict[str, np.ndarray] = {}
            strings: dict[str, list[str]] = {}
            for name in rows.column_names:
                if name in meta.layout.images:
                    cols[name] = decode_images(rows.column(name))
                elif name in STRING_COLUMNS or pa.types.is_string(rows.schema.field(name).type):
                    strings[name] = rows.column(name).to_pylist()
                else:
                    cols[name] = column_values(rows.column(name), n)
            yield EpisodeArrays(split, records[(split, int(rows.column("episode_index")[0].as_py()))], cols, strings)
