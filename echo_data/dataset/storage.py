"""Putting bytes on disk atomically: the one implementation every writer of the dataset uses.

Write a temporary sibling (named `.NAME.tmp-PID`, so resume and validate can spot leftovers),
fsync it, rename it over the target and fsync the folder: a reader sees the old file or the
whole new one, never a part, and a finished rename survives a power cut.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq


def fsync_dir(path: Path) -> None:
    """Make a rename in `path` durable."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def tmp_path(path: Path) -> Path:
    """Temporary sibling of `path`; the `.tmp-` marker lets resume and validate spot leftovers."""
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield the temporary sibling to write `path`'s new content to; on leaving the block the
    file is fsynced and renamed over `path`, and the folder fsynced."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = tmp_path(path)
    try:
        yield tmp
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:  # a failed write (or a target that is a folder) leaves nothing behind
        tmp.unlink(missing_ok=True)
        raise
    fsync_dir(path.parent)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Replace `path` with `data` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def canonical_json(obj: Any) -> bytes:
    """Stable JSON bytes (sorted keys) for files whose bytes must not depend on dict order."""
    return (json.dumps(obj, sort_keys=True, indent=1, ensure_ascii=False) + "\n").encode()


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_bytes(path, canonical_json(obj))


def atomic_write_parquet(path: Path, table: pa.Table) -> None:
    """A small Parquet table (zstd) replacing `path` atomically (meta/episodes.parquet)."""
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd", row_group_size=4096)


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
