"""What echo-data wrote, and the one way `--overwrite` removes it: by file list, never rmtree.

Users keep datasets and exports next to their other work; a `--overwrite` aimed at the wrong
folder (a thesis, the parent of the dataset being exported) must delete nothing. So every folder
echo-data writes carries a marker, `.echo-data.json` (kind, format, echo-data version; an export's
marker also lists every file the export wrote; a Zarr export keeps the same record under the key
`echo-data` of its root `.zattrs`, since zarr warns about any other file it finds in a group),
and `--overwrite` first lists what it would
delete: a folder without the marker, or holding any file that is not on the list, is refused
whole (one line, nothing touched). Only then are the listed files unlinked one by one and the
folders they leave empty removed.

A training run's marker (learn/runs.py) lists its files as they are written; a preview's
(preview.py) and an export's list theirs once, before the finished folder is swapped in.

A dataset's file list is the one its manifest implies (shards, WAVs, planner media, meta/,
staged episodes, temporary siblings of any of them): it grows to millions of files, so it is
matched by pattern rather than stored. Datasets built before the marker existed are recognised
the same way: a manifest that loads as an echo-data manifest, and no file outside its list. An
export without the marker is refused (an export is minutes to redo; guessing its files is not
worth a user's folder); run and preview folders from before the marker are recognised by their
callers (`known`: a run's policy.json and the names runs always wrote; a preview's seven names).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from echo_data.dataset.storage import atomic_write_json

MARKER = ".echo-data.json"
ZATTRS = ".zattrs"  # a Zarr format 2 group's attributes: where a Zarr export's marker lives
ZATTRS_KEY = "echo-data"
DATASET = "dataset"
_TMP = re.compile(r"^\.(?P<name>.+)\.tmp-\d+$")  # storage.tmp_path's siblings


class NotWrittenByUs(ValueError):
    """A folder `--overwrite` would delete holds something echo-data did not write: one line."""


def write_marker(folder: Path, kind: str, fmt: str, files: Iterable[str] | None = None, zarr: bool = False) -> None:
    """Mark `folder` as echo-data's `kind` output in format `fmt`; `files`: every file written
    there (relative, '/'-separated), for outputs whose names no manifest implies; `zarr`: in the
    root group's attributes (module docstring)."""
    from echo_data.dataset.manifest import versions  # the installed version, as the manifest records it

    record: dict[str, Any] = {"kind": kind, "format": fmt, "version": versions()["echo-data"]}
    if files is not None:
        record["files"] = sorted(files)
    if zarr:
        attrs = json.loads((folder / ZATTRS).read_text()) if (folder / ZATTRS).is_file() else {}
        atomic_write_json(folder / ZATTRS, {**attrs, ZATTRS_KEY: record})
    else:
        atomic_write_json(folder / MARKER, record)


def read_marker(folder: Path) -> dict[str, Any] | None:
    """The marker of `folder` (None when there is none or it is not one of ours)."""
    try:
        data = json.loads((folder / MARKER).read_bytes().decode("utf-8"))
    except (OSError, ValueError):
        try:
            attrs = json.loads((folder / ZATTRS).read_bytes().decode("utf-8"))
        except (OSError, ValueError):
            return None
        data = attrs.get(ZATTRS_KEY) if isinstance(attrs, dict) else None
    return data if isinstance(data, dict) and isinstance(data.get("kind"), str) else None


def all_files(folder: Path) -> list[str]:
    """Every file and link under `folder`, relative and '/'-separated (links are not followed)."""
    out = []
    for root, dirs, files in os.walk(folder):
        rel = Path(root).relative_to(folder)
        out += [(rel / f).as_posix() for f in files]
        out += [(rel / d).as_posix() for d in dirs if (Path(root) / d).is_symlink()]  # never descend into a link
    return sorted(out)


def apart_problem(src: Path, out: Path, what: str, option: str = "--out") -> str | None:
    """Why `out` may not be written (it is, lies in or holds the dataset `src` the command
    reads: an `--overwrite` of a parent folder would delete the dataset and its neighbours),
    or None."""
    s, o = src.resolve(), out.resolve()
    if o == s or s in o.parents:
        return f"{option} {out} lies inside the {what} {src}"
    if o in s.parents:
        return f"{option} {out} contains the {what} {src}"
    return None


def _refuse(folder: Path, why: str) -> NotWrittenByUs:
    return NotWrittenByUs(f"{folder}: {why}; echo-data replaces only what it wrote (nothing was touched)")


def written_files(folder: Path, kind: str, known: Callable[[str], bool] | None = None) -> list[str]:
    """The files `--overwrite` may delete from `folder` (an echo-data output of `kind`): all of
    them, or `NotWrittenByUs` naming the first that echo-data did not write. `known(rel)` says
    whether a dataset's manifest implies a file; other outputs' markers list their files, and
    `known` then recognises only an output written before the marker existed (no marker)."""
    if not folder.is_dir() or folder.is_symlink():
        raise _refuse(folder, "is not a folder")
    files = all_files(folder)
    if not files:
        return []
    marker = read_marker(folder)
    if marker is not None and marker.get("kind") != kind:
        raise _refuse(folder, f"holds an echo-data {marker.get('kind')}, not a {kind}")
    if kind == DATASET:
        if known is None:
            raise _refuse(folder, "holds no readable echo-data manifest")
        listed: Callable[[str], bool] = known
    elif marker is None:
        if known is None:
            raise _refuse(folder, f"has no {MARKER} marker (not an echo-data {kind})")
        listed = known  # an output from before the marker, recognised by its caller
    else:
        names = marker.get("files")
        wrote = {n for n in names if isinstance(n, str)} if isinstance(names, list) else set()
        listed = wrote.__contains__
    for rel in files:
        if rel == MARKER or listed(rel) or _is_tmp_of(rel, listed):
            continue
        raise _refuse(folder, f"holds {rel}, which echo-data did not write")
    return files


def _is_tmp_of(rel: str, listed: Callable[[str], bool]) -> bool:
    """A temporary sibling (`.NAME.tmp-PID`) of a listed file, left by a killed writer."""
    head, _, name = rel.rpartition("/")
    m = _TMP.match(name)
    return m is not None and (listed(f"{head}/{m['name']}" if head else m["name"]) or m["name"] == MARKER)


def remove_written(folder: Path, files: Iterable[str], keep: Iterable[str] = ()) -> None:
    """Unlink the listed files of `folder` (all but `keep`), then each folder that became empty,
    deepest first; `folder` itself stays. Nothing outside the list is touched."""
    spared = set(keep)
    dirs: set[Path] = set()
    for rel in files:
        if rel in spared:
            continue
        p = folder / rel
        p.unlink(missing_ok=True)
        dirs.update(d for d in p.parents if d != folder and folder in d.parents)
    for d in sorted(dirs, key=lambda d: len(d.parts), reverse=True):
        with contextlib.suppress(OSError):  # not empty: it holds a spared file
            d.rmdir()


def replace_folder(tmp: Path, out: Path, kind: str, known: Callable[[str], bool] | None = None) -> None:
    """Move the finished output `tmp` to `out`; an existing `out` is first checked again (the
    user may have put files there since the command started) and removed by its file list
    (`known`: as in `written_files`)."""
    if out.exists():
        files = written_files(out, kind, known)
        old = out.with_name(f".{out.name}.old-{os.getpid()}")
        os.replace(out, old)
        os.replace(tmp, out)
        remove_written(old, files)
        old.rmdir()
    else:
        os.replace(tmp, out)


def mark_export(tmp: Path, kind: str, fmt: str, zarr: bool = False) -> None:
    """Write the marker of an export built in `tmp`, listing every file in it (`zarr`: in its
    root `.zattrs`, which the list then names too)."""
    files = [f for f in all_files(tmp) if f != MARKER]
    write_marker(tmp, kind, fmt, sorted({*files, ZATTRS}) if zarr else files, zarr=zarr)


def dataset_file_test(manifest: dict[str, Any]) -> Callable[[str], bool]:
    """Whether a relative path is one a build of this manifest writes (see the module doc)."""
    splits = "|".join(re.escape(s) for s in manifest.get("splits", {}) if isinstance(s, str))
    eid = rf"({splits})-\d{{6}}"
    patterns = [
        r"manifest\.json", r"README\.md", r"\.build\.lock", r"meta/(episodes\.parquet|stats\.json|info\.json)",
        rf"data/({splits})-\d{{5}}-of-\d{{5}}\.parquet",
        rf"meta/audio/({splits})\.parquet",  # the card's playable audio config (dataset/audio.AUDIO_TABLE)
        rf"audio/({splits})/{eid}\.wav",
        rf"planner/(audio|audio_binaural)/({splits})/{eid}\.wav", rf"planner/images/({splits})/{eid}\.png",
        rf"planner/(({splits})\.json|dataset_info\.json)",
        rf"\.work/({splits})/\d{{6}}\.(arrow|json)",
    ]
    full = re.compile("|".join(f"(?:{p})" for p in patterns)) if splits else re.compile(r"manifest\.json|README\.md|\.build\.lock")
    return lambda rel: full.fullmatch(rel) is not None


def dataset_files(folder: Path) -> list[str]:
    """The files of the dataset folder `folder` that `build --overwrite` may delete, or
    `NotWrittenByUs` (a folder without an echo-data manifest, or holding anything else)."""
    from echo_data.dataset.manifest import MANIFEST

    if not (folder / MANIFEST).exists():
        files = all_files(folder)
        if read_marker(folder) is not None and all(f in (MARKER, ".build.lock") or _is_tmp_of(f, lambda _: False) for f in files):
            return files  # a build killed between its marker and its manifest
        raise _refuse(folder, f"is not empty and holds no {MANIFEST} (not an echo-data dataset)")
    try:  # not load_manifest: a dataset of an older format is exactly what --overwrite replaces
        manifest = json.loads((folder / MANIFEST).read_bytes().decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        raise _refuse(folder, f"its {MANIFEST} cannot be read") from None
    fmt = manifest.get("format") if isinstance(manifest, dict) else None
    if not (isinstance(fmt, str) and fmt.startswith("echo-data/") and isinstance(manifest.get("splits"), dict)):
        raise _refuse(folder, f"its {MANIFEST} is not an echo-data manifest")
    return written_files(folder, DATASET, dataset_file_test(manifest))
