"""`echo-data build RECIPE --handover-from RUN`: teach the next skill from where a learner hands over.

RUN is what `echo-data evaluate RECIPE --split train --json RUN.json` wrote (the results JSON, or
its journal `RUN.episodes.jsonl` while it runs): per episode, per chain entry the learner ran, the
hand-over record with the base pose the entry ended at (`records.HandOverRecord.end`). For every
episode RUN holds, the build's Navigate expert of each entry whose learned drive succeeded stops at
that pose instead of its own goal (`World.handover_stops`), so the demonstrations of the skill after
it start where the learner hands over (docs/handover.md). Only the spec RUN ran is changed (same
seed: a retry's fresh draw is built as usual); episodes RUN lacks are built as usual.

Bad input is one line naming the file and the key, before anything is written: another recipe's
run (its content hash), a test-split run (never train on the test split), a file that is no
evaluate output, records without end poses.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from echo_data.outputs import OutputError
from echo_data.recipe import Recipe


class HandoverRunError(OutputError):
    """RUN cannot be used (one line naming the file and the key): exit 2, nothing written."""


@dataclass(frozen=True)
class LearnerStops:
    """A learner's hand-overs in one episode: the spec it ran (its seed) and, per chain index of a
    Navigate whose learned drive succeeded, the base pose (x, y, yaw) it ended at."""

    seed: int
    stops: dict[int, tuple[float, float, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class HandoverRun:
    """RUN read and checked against the recipe: its episodes' stops and its provenance."""

    split: str
    episodes: dict[int, LearnerStops]
    provenance: dict[str, Any]  # the manifest's `handover_from`: file name, sha256, split, policy, drive_end

    def jobs(self) -> dict[tuple[str, int], LearnerStops]:
        """The stops by (split, index), as the build's workers look them up."""
        return {(self.split, i): s for i, s in self.episodes.items() if s.stops}


def _read(path: Path) -> tuple[dict[str, Any], list[Any], bytes]:
    """(what RUN says it evaluated, its episode records, its bytes): a results JSON or a journal."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise HandoverRunError(f"--handover-from {path}: cannot read ({e.strerror or e})") from None
    try:
        doc = json.loads(data)
    except ValueError:
        doc = None
    if isinstance(doc, dict) and "episodes" in doc:
        recipe: dict[str, Any] = doc["recipe"] if isinstance(doc.get("recipe"), dict) else {}
        head = {"recipe": recipe.get("content_hash"), "split": doc.get("split"), "policy": doc.get("policy"), "drive_end": doc.get("drive_end")}
        if not isinstance(doc["episodes"], list):
            raise HandoverRunError(f"--handover-from {path}: episodes: expected a list of episode records")
        return head, doc["episodes"], data
    from echo_data.evaluation.journal import parse

    first, lines = parse(data)  # a journal: whole lines only, as evaluate --resume reads it
    records = [rec for _, rec in lines]
    if not isinstance(first, dict) or not isinstance(first.get("evaluation"), dict):
        raise HandoverRunError(f"--handover-from {path}: not what `echo-data evaluate --json` writes (a results JSON with 'episodes', or its journal)")
    return first["evaluation"], records, data


def _end_pose(path: Path, where: str, skill: dict[str, Any]) -> tuple[float, float, float] | None:
    """The end pose of a learned Navigate entry's record (None: none to use), or the one-line error."""
    from echo_data.skill_table import role_of

    if role_of(str(skill.get("skill"))) != "approach" or not skill.get("success") or skill.get("handover") is None:
        return None
    end = skill["handover"].get("end") if isinstance(skill["handover"], dict) else None
    if not (isinstance(end, list) and len(end) == 3 and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in end)):
        raise HandoverRunError(f"--handover-from {path}: {where}.handover.end: expected three finite numbers (x, y, yaw), got {end!r}")
    return (float(end[0]), float(end[1]), float(end[2]))


def _episode(path: Path, n: int, rec: Any) -> tuple[int, LearnerStops] | None:
    """One episode record's index and stops (None: a skipped episode)."""
    if isinstance(rec, dict) and "skipped" in rec:
        return None
    index, seed = (rec.get("index"), rec.get("seed")) if isinstance(rec, dict) else (None, None)
    if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in (index, seed)):
        raise HandoverRunError(f"--handover-from {path}: episodes[{n}]: expected an episode record with integer 'index' and 'seed'")
    skills = rec.get("skills")
    if not isinstance(skills, list) or not all(isinstance(s, dict) for s in skills):
        raise HandoverRunError(f"--handover-from {path}: episodes[{n}].skills: expected a list of skill records")
    if any(s.get("skill") and "handover" not in s for s in skills):
        raise HandoverRunError(f"--handover-from {path}: episodes[{n}].skills: no 'handover' records (evaluated by an echo-data "
                               "that did not record end poses): run evaluate again")
    stops = {k: pose for k, s in enumerate(skills) if (pose := _end_pose(path, f"episodes[{n}].skills[{k}]", s)) is not None}
    assert isinstance(index, int) and isinstance(seed, int)
    return index, LearnerStops(seed, stops)


def load_handover_run(path: Path, recipe: Recipe) -> HandoverRun:
    """RUN read and checked against `recipe` (see the module docstring); `HandoverRunError` when unusable."""
    head, records, data = _read(path)
    if head.get("recipe") != recipe.content_hash():
        theirs = str(head.get("recipe"))[:12]
        raise HandoverRunError(f"--handover-from {path}: recipe.content_hash: {theirs} is another recipe's run (this recipe: {recipe.content_hash()[:12]})")
    split = head.get("split")
    if split == "test":
        raise HandoverRunError(f"--handover-from {path}: split: 'test': a build never trains on the test split (evaluate --split train)")
    if split not in recipe.splits:
        raise HandoverRunError(f"--handover-from {path}: split: {split!r} is none of the recipe's splits ({', '.join(recipe.splits)})")
    episodes: dict[int, LearnerStops] = {}
    for n, rec in enumerate(records):
        got = _episode(path, n, rec)
        if got is not None:
            if got[0] >= recipe.splits[split]:
                raise HandoverRunError(f"--handover-from {path}: episodes[{n}].index: {got[0]} is past the {split} split ({recipe.splits[split]} episodes)")
            episodes[got[0]] = got[1]
    provenance = {"file": path.name, "sha256": hashlib.sha256(data).hexdigest(), "split": split, "policy": head.get("policy"),
                  "drive_end": head.get("drive_end"), "episodes_in_run": len(episodes)}
    return HandoverRun(split, episodes, provenance)
