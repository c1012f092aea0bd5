"""One stored episode at a time as numpy arrays: what the array-store exports (robomimic HDF5,
Diffusion Policy Zarr) write, read once from the shards in split and episode order.

Images are decoded (RGB uint8 (T, H, W, 3), depth uint16 millimetres (T, H, W)); spectrograms
keep their (T, F, time, ear) shape; every other fixed-size column becomes (T, ...) as stored.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset.manifest import ManifestError, load_manifest
from echo_data.dataset.schema import StepLayout
from echo_data.episode import SPLIT_KEYS

STRING_COLUMNS = ("setting", "skill", "audio_path")


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
        manifest = load_manifest(src)
    except ManifestError as e:
        raise ExportError(str(e)) from None
    if not manifest.get("complete"):
        raise ExportError(f"{src}: the build is not complete (finish it with `echo-data build --resume`)")
    return manifest


def check_out_file(src: Path, out: Path, overwrite: bool) -> None:
    """Refuse an existing output (unless --overwrite replaces a file) or one inside the source."""
    if out.exists() and not (overwrite and out.is_file()):
        raise ExportError(f"{out} already exists" + ("; use --overwrite to replace it" if out.is_file() else " and is a folder"))
    if src.resolve() in out.resolve().parents:
        raise ExportError(f"--out {out} lies inside the source dataset {src}")



def check_out_folder(src: Path, out: Path, overwrite: bool) -> None:
    """Refuse an existing output folder (unless --overwrite replaces it), a file, the source itself or a place inside it."""
    if out.exists() and not (overwrite and out.is_dir()):
        raise ExportError(f"{out} already exists" + ("; use --overwrite to replace it" if out.is_dir() else " and is not a folder"))
    if out.resolve() == src.resolve() or src.resolve() in out.resolve().parents:
        raise ExportError(f"--out {out} lies inside the source dataset {src}")

def decode_images(column: pa.ChunkedArray) -> np.ndarray:
    """PNG cells of an image column -> (T, H, W[, C]) pixels as stored (depth stays uint16 mm)."""
    from PIL import Image

    return np.stack([np.asarray(Image.open(io.BytesIO(p["bytes"]))) for p in column.to_pylist()])


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
    order within a split."""
    layout = StepLayout.from_dict(manifest["layout"])
    records = {(r["split"], r["episode_index"]): r for r in pq.read_table(src / "meta" / "episodes.parquet").to_pylist()}
    for split in splits if splits is not None else export_splits(manifest, None):
        for shard in (e for e in manifest["shards"] if e["split"] == split):
            table = pq.read_table(src / shard["file"])
            ep = table.column("episode_index").to_numpy()
            bounds = np.flatnonzero(np.diff(ep)) + 1
            for lo, hi in zip(np.concatenate([[0], bounds]), np.concatenate([bounds, [len(ep)]])):
                rows = table.slice(int(lo), int(hi - lo))
                n = rows.num_rows
                cols: dict[str, np.ndarray] = {}
                strings: dict[str, list[str]] = {}
                for name in rows.column_names:
                    if name in layout.images:
                        cols[name] = decode_images(rows.column(name))
                    elif name in STRING_COLUMNS or pa.types.is_string(rows.schema.field(name).type):
                        strings[name] = rows.column(name).to_pylist()
                    else:
                        cols[name] = column_values(rows.column(name), n)
                yield EpisodeArrays(split, records[(split, int(ep[lo]))], cols, strings)
