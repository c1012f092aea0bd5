"""The record of an evaluation in progress: one JSON line per finished episode, next to `--json`.

Why: an evaluation of a few dozen episodes takes tens of minutes; a crash, a kill or Ctrl-C
must not lose the episodes already run. Each finished episode's record is appended as one
line with a single `write` and fsynced, so the file always holds whole records (a line torn
by a kill mid-write is dropped when the file is read back). The first line names the
evaluation (recipe hash, split, agents and their checkpoints); `--resume` continues only the
same evaluation, and because each episode is a pure function of (recipe, split, index,
agents) the finished JSON is the one an uninterrupted run writes (timings aside). The file is
removed once the results JSON is written.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

SUFFIX = ".episodes.jsonl"


class JournalError(ValueError):
    """The record file cannot be used (another evaluation's, unreadable, not writable): one line."""


def journal_path(json_out: Path) -> Path:
    """Where the records of `--json OUT` go: `OUT` with `.episodes.jsonl` for its suffix."""
    return json_out.with_name(json_out.stem + SUFFIX)


# What every journal line after the header holds: a scored episode (evaluation.run.episode_record)
# or a skipped one.
EPISODE_KEYS = ("index", "episode_id", "setting", "true_chain", "planned_chain", "plan_correct", "skills", "skills_completed",
                "success", "steps", "navigate")


def is_episode_record(rec: Any) -> bool:
    """Whether `rec` is a record `evaluate` wrote: an episode's outcome or its skip."""
    if not isinstance(rec, dict) or not isinstance(rec.get("index"), int) or isinstance(rec["index"], bool) or rec["index"] < 0:
        return False
    return "skipped" in rec or all(k in rec for k in EPISODE_KEYS)


def parse(data: bytes) -> tuple[Any, list[tuple[bytes, Any]]]:
    """(the header line's JSON or None, each following whole line with its JSON) of a record
    file's bytes: the last piece has no newline (empty, or a line torn by a kill) and is dropped,
    and the lines stop at the first that is no JSON (torn inside: what precedes is kept)."""
    whole = data.split(b"\n")[:-1]
    try:
        head = json.loads(whole[0]) if whole else None
    except ValueError:
        head = None
    lines: list[tuple[bytes, Any]] = []
    for line in whole[1:]:
        try:
            lines.append((line, json.loads(line)))
        except ValueError:
            break
    return head, lines


def _read(path: Path, key: dict[str, Any]) -> tuple[dict[int, dict[str, Any]], int]:
    """(records by index, bytes of whole lines) of an existing record file of evaluation `key`."""
    data = path.read_bytes()
    head, lines = parse(data)
    if not isinstance(head, dict) or "evaluation" not in head:
        raise JournalError(f"{path}: not an evaluation record file (first line is not its header)")
    if not isinstance(head["evaluation"], dict):
        raise JournalError(f"{path}: not an evaluation record file (its header names no evaluation)")
    if head["evaluation"] != key:
        diff = sorted(k for k in set(key) | set(head["evaluation"]) if key.get(k) != head["evaluation"].get(k))
        raise JournalError(f"{path}: records of a different evaluation ({', '.join(diff)} differ); delete it to start over")
    records: dict[int, dict[str, Any]] = {}
    size = data.index(b"\n") + 1
    for number, (line, rec) in enumerate(lines, start=2):  # torn inside (a kill between write and fsync on another filesystem): parse keeps what precedes
        if not is_episode_record(rec):
            raise JournalError(f"{path}: line {number} is not an episode record (no integer 'index' and outcome); delete the file to start over")
        records[int(rec["index"])] = rec
        size += len(line) + 1
    return records, size


class Journal:
    """Append-only per-episode records of one evaluation (see the module docstring)."""

    def __init__(self, path: Path, key: dict[str, Any], resume: bool) -> None:
        self.path = path
        self.records: dict[int, dict[str, Any]] = {}
        try:
            if path.exists() and not resume:
                raise JournalError(f"{path}: records of an unfinished evaluation; --resume continues it, or delete the file to start over")
            if path.exists():
                self.records, size = _read(path, key)
                os.truncate(path, size)  # drop a torn last line so the next record starts a line
            else:
                from echo_data.dataset.storage import atomic_write_bytes

                atomic_write_bytes(path, (json.dumps({"evaluation": key}, sort_keys=True) + "\n").encode())
            self._fd = os.open(path, os.O_WRONLY | os.O_APPEND)
        except OSError as e:
            raise JournalError(f"{path}: cannot write the evaluation's records ({e.strerror or e})") from None

    def append(self, rec: dict[str, Any]) -> None:
        """Add one finished episode's record (one write, fsynced)."""
        os.write(self._fd, (json.dumps(rec, sort_keys=True) + "\n").encode())
        os.fsync(self._fd)
        self.records[int(rec["index"])] = rec

    def close(self, finished: bool) -> None:
        """Stop appending; `finished`: the results JSON holds everything, remove the file."""
        os.close(self._fd)
        if finished:
            self.path.unlink(missing_ok=True)
