"""manifest.json: what a dataset is, how it was made, and which shards are complete.

The manifest is the build's commit log. It is written once before any work (so a resume can
check the recipe hash and --limit), then rewritten atomically after each complete shard; the
totals are always recomputed from the per-shard entries, so they never drift. Timestamps live
only under "build" and never in data files.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any, overload

from echo_data.acoustics.levels import calibration_record
from echo_data.dataset.schema import FORMAT_VERSION, StepLayout, shard_name
from echo_data.dataset.storage import atomic_write_json
from echo_data.episode import SPLIT_KEYS
from echo_data.recipe import Recipe

MANIFEST = "manifest.json"


class ManifestError(ValueError):
    """The manifest is missing, unreadable or does not match what was asked."""


def versions() -> dict[str, str | None]:
    """Installed versions that decide the bytes (read from package metadata: imports nothing)."""
    out: dict[str, str | None] = {}
    for dist in ("echo-data", "sapien", "pyroomacoustics", "numpy", "pyarrow", "librosa", "soundfile", "pillow"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


@dataclass(frozen=True)
class ShardPlan:
    """One shard as planned up front: which episodes of which split it holds."""

    split: str
    shard: int
    of: int
    first: int  # first episode index (inclusive)
    last: int  # last episode index (exclusive)

    @property
    def file(self) -> str:
        return f"data/{shard_name(self.split, self.shard, self.of)}"

    @property
    def indices(self) -> range:
        return range(self.first, self.last)


def split_sizes(recipe: Recipe, limit: int | None, only: Sequence[str] | None = None) -> dict[str, int]:
    """Episodes per split after --limit, in the canonical order train, val, test (never the
    order of keys in a file: the manifest stores the recipe with sorted keys). `only` (build
    --split) keeps the named splits: a training build need not pay for the test split, which
    `echo-data evaluate` samples from the recipe itself."""
    names = sorted((s for s in recipe.splits if only is None or s in only), key=lambda s: SPLIT_KEYS[s])
    return {s: (recipe.splits[s] if limit is None else min(recipe.splits[s], limit)) for s in names}


class ShardPlans(Sequence[ShardPlan]):
    """The shards of one split, computed on demand: memory does not grow with the episode count."""

    def __init__(self, split: str, episodes: int, per_shard: int) -> None:
        self.split, self.episodes, self.per_shard = split, episodes, per_shard
        self.n_shards = math.ceil(episodes / per_shard)

    def __len__(self) -> int:
        return self.n_shards

    @overload
    def __getitem__(self, i: int) -> ShardPlan: ...
    @overload
    def __getitem__(self, i: slice) -> list[ShardPlan]: ...
    def __getitem__(self, i: int | slice) -> ShardPlan | list[ShardPlan]:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self.n_shards))]
        if i < 0:
            i += self.n_shards
        if not 0 <= i < self.n_shards:
            raise IndexError(i)
        return ShardPlan(self.split, i, self.n_shards, i * self.per_shard, min((i + 1) * self.per_shard, self.episodes))

    def of_file(self, file: str) -> ShardPlan | None:
        """The planned shard stored as `file`, or None when `file` is not one of this split's."""
        for i in (int(part) for part in file.rsplit("-", 3)[1:2] if part.isdigit()):
            if i < self.n_shards and self[i].file == file:
                return self[i]
        return None


def plan_shards(recipe: Recipe, limit: int | None, only: Sequence[str] | None = None) -> dict[str, ShardPlans]:
    """Episodes -> shards by (split, index): `episodes_per_shard` consecutive episodes each."""
    eps = recipe.outputs.episodes_per_shard
    return {split: ShardPlans(split, n, eps) for split, n in split_sizes(recipe, limit, only).items()}


def new_manifest(
    recipe: Recipe, limit: int | None, layout: StepLayout, workers: int, executor: str, only: Sequence[str] | None = None
) -> dict[str, Any]:
    plans = plan_shards(recipe, limit, only)
    now = _now()
    return {
        "format": FORMAT_VERSION,
        "name": recipe.name,
        "recipe_hash": recipe.content_hash(),
        "recipe": recipe.model_dump(mode="json"),
        "limit": limit,
        **({"only_splits": sorted(only, key=lambda s: SPLIT_KEYS[s])} if only is not None else {}),
        "seed": recipe.seed,
        "seed_rule": (
            "build attempt a of an episode lets the sampler try draws a*max_attempts_per_episode .. "
            "(a+1)*max_attempts_per_episode-1; draw k is seeded numpy.random.SeedSequence([recipe.seed, split_key, index, k]) "
            "(echo_data.episode.attempt_draws); each attempt record names its draw and seed once a spec was sampled"
        ),
        "split_keys": {k: v for k, v in SPLIT_KEYS.items() if k in recipe.splits},
        "versions": versions(),
        "layout": layout.to_dict(),
        "audio": {
            "sample_rate": layout.sample_rate,
            "channels": 2,
            "subtype": "PCM_16",
            "channel_0": "left",
            **calibration_record(recipe.acoustics.full_scale_db_spl, recipe.acoustics.noise_floor_dba),
        },
        "splits": {
            s: {
                "requested": recipe.splits[s],
                "episodes": sum(len(p.indices) for p in ps),
                "shards": len(ps),
                "episodes_per_shard": recipe.outputs.episodes_per_shard,
            }
            for s, ps in plans.items()
        },
        "shards": [],
        "complete": False,
        "build": {"started_at": now, "updated_at": now, "workers": workers, "executor": executor},
        **totals([]),
    }


def totals(shards: list[dict[str, Any]]) -> dict[str, Any]:
    """Aggregate the per-shard entries (in manifest order) into dataset totals."""
    episodes: dict[str, int] = {}
    steps: dict[str, int] = {}
    settings: dict[str, dict[str, int]] = {}
    skills: dict[str, dict[str, int]] = {}
    rejected: dict[str, int] = {}
    failed: list[dict[str, Any]] = []
    truncated: dict[str, int] | None = None  # only in manifests whose shard entries count cut episodes
    for sh in shards:
        sp = sh["split"]
        episodes[sp] = episodes.get(sp, 0) + sh["episodes"][1] - sh["episodes"][0]
        steps[sp] = steps.get(sp, 0) + sh["rows"]
        for k, v in sh["settings"].items():
            settings.setdefault(sp, {})[k] = settings.get(sp, {}).get(k, 0) + v
        for k, (a, s) in sh["skills"].items():
            d = skills.setdefault(k, {"attempts": 0, "successes": 0})
            d["attempts"] += a
            d["successes"] += s
        for k, v in sh["rejected"].items():
            rejected[k] = rejected.get(k, 0) + v
        failed += sh["failures"]
        if "truncated" in sh:
            truncated = truncated or {}
            truncated[sp] = truncated.get(sp, 0) + sh["truncated"]
    attempts = sum(episodes.values()) + len(failed)
    counts: dict[str, Any] = {
        "episodes": episodes,
        "steps": steps,
        "settings": settings,
        "episode_attempts": attempts,
        # stored episodes (whole, or cut by outputs.max_frames) per attempt
        "episode_success_rate": (sum(episodes.values()) / attempts) if attempts else None,
    }
    if truncated is not None:
        counts["truncated_episodes"] = truncated  # per split: episodes cut by outputs.max_frames
    return {
        "counts": counts,
        "skills": {k: skills[k] for k in sorted(skills)},
        "rejected": {k: rejected[k] for k in sorted(rejected)},
        "failed_episodes": failed,
    }


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def write_manifest(out: Path, manifest: dict[str, Any]) -> None:
    """Recompute totals from the shard entries and replace manifest.json atomically."""
    manifest.update(totals(manifest["shards"]))
    manifest["build"]["updated_at"] = _now()
    atomic_write_json(out / MANIFEST, manifest)


def load_manifest(out: Path) -> dict[str, Any]:
    """The manifest of the dataset at `out`, its shape checked: a damaged or hand-edited file is
    one `ManifestError` naming the file and the key, never a TypeError deep inside a reader."""
    path = out / MANIFEST
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise ManifestError(f"{out}: no {MANIFEST} (not an echo-data dataset)") from None
    except IsADirectoryError:
        raise ManifestError(f"{path}: is a folder, not a manifest (not an echo-data dataset)") from None
    except UnicodeDecodeError as e:
        raise ManifestError(f"{path}: unreadable manifest (not UTF-8 text: byte {e.start})") from None
    except (OSError, json.JSONDecodeError, RecursionError) as e:
        raise ManifestError(f"{path}: unreadable manifest ({e.__class__.__name__}: {e})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT_VERSION:
        fmt = data.get("format") if isinstance(data, dict) else None
        if isinstance(fmt, str) and fmt.startswith("echo-data/"):
            raise ManifestError(f"{path}: dataset format {fmt}; this echo-data reads {FORMAT_VERSION} (rebuild with --overwrite)")
        raise ManifestError(f"{path}: not an {FORMAT_VERSION} manifest")
    wrong = manifest_shape_problem(data)
    if wrong:
        raise ManifestError(f"{path}: {wrong}")
    return data


def _kind(v: Any) -> str:
    return "null" if v is None else "true/false" if isinstance(v, bool) else type(v).__name__


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


# What the readers (validate, info, build --resume, export, view, train, evaluate) take from a
# manifest, as (key, test, what it must be). Keys a newer writer adds are not listed: they are
# not read, so their shape cannot break a reader.
_TOP: tuple[tuple[str, Any, str], ...] = (
    ("name", lambda v: isinstance(v, str), "text"),
    ("recipe_hash", lambda v: isinstance(v, str), "text"),
    ("recipe", lambda v: isinstance(v, dict), "a mapping"),
    ("limit", lambda v: v is None or (_is_int(v) and v >= 1), "null or an integer >= 1"),
    ("seed", lambda v: _is_int(v) and v >= 0, "an integer >= 0"),
    ("layout", lambda v: isinstance(v, dict), "a mapping"),
    ("audio", lambda v: isinstance(v, dict), "a mapping"),
    ("splits", lambda v: isinstance(v, dict) and all(isinstance(x, dict) for x in v.values()), "a mapping of split -> mapping"),
    ("shards", lambda v: isinstance(v, list) and all(isinstance(x, dict) for x in v), "a list of mappings"),
    ("complete", lambda v: isinstance(v, bool), "true or false"),
    ("build", lambda v: isinstance(v, dict), "a mapping"),
    ("counts", lambda v: isinstance(v, dict), "a mapping"),
    ("skills", lambda v: isinstance(v, dict), "a mapping"),
    ("rejected", lambda v: isinstance(v, dict), "a mapping"),
    ("failed_episodes", lambda v: isinstance(v, list), "a list"),
    ("versions", lambda v: isinstance(v, dict), "a mapping"),
)
_SHARD: tuple[tuple[str, Any, str], ...] = (
    ("file", lambda v: isinstance(v, str), "text"),
    ("split", lambda v: isinstance(v, str), "text"),
    ("sha256", lambda v: isinstance(v, str), "text"),
    ("rows", lambda v: _is_int(v) and v >= 0, "an integer >= 0"),
    ("bytes", lambda v: _is_int(v) and v >= 0, "an integer >= 0"),
    ("episodes", lambda v: isinstance(v, list) and len(v) == 2 and all(_is_int(x) for x in v), "[first, last] integers"),
    ("settings", lambda v: isinstance(v, dict) and all(_is_int(x) for x in v.values()), "a mapping of integers"),
    ("skills", lambda v: isinstance(v, dict) and all(isinstance(x, list) and len(x) == 2 and all(_is_int(y) for y in x) for x in v.values()), "a mapping of [attempts, successes]"),
    ("rejected", lambda v: isinstance(v, dict) and all(_is_int(x) for x in v.values()), "a mapping of integers"),
    ("failures", lambda v: isinstance(v, list), "a list"),
)


def manifest_shape_problem(data: dict[str, Any]) -> str | None:
    """The first key of a manifest whose value has the wrong type ("key: must be ..., got ..."),
    or None when every key a reader uses has the shape the writer gives it."""
    for key, ok, what in _TOP:
        if key not in data:
            return f"{key}: missing"
        if not ok(data[key]):
            return f"{key}: must be {what}, got {_kind(data[key])} {str(data[key])[:40]!r}"
    only = data.get("only_splits")
    if only is not None and not (isinstance(only, list) and all(isinstance(s, str) and s in SPLIT_KEYS for s in only)):
        return f"only_splits: must be a list of split names, got {_kind(only)}"
    for split, entry in data["splits"].items():
        for k in ("requested", "episodes", "shards", "episodes_per_shard"):
            if k in entry and not (_is_int(entry[k]) and entry[k] >= 0):
                return f"splits.{split}.{k}: must be an integer >= 0, got {_kind(entry[k])}"
    for i, shard in enumerate(data["shards"]):
        for key, ok, what in _SHARD:
            if key in shard and not ok(shard[key]):
                return f"shards[{i}].{key}: must be {what}, got {_kind(shard[key])}"
            if key not in shard and key in ("file", "split", "sha256", "rows"):
                return f"shards[{i}].{key}: missing"
    return None
