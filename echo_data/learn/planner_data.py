"""What the planner reads of a dataset: each episode's record (its events, chain and sounds,
through `dataset/reader`), the first frames' inputs of a split, the skill templates learned from
the training chains, and which train episodes a run reads and validates on. Split from
`learn.planner` (the model, its training and decoding) by job.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from echo_data import seeds
from echo_data.dataset.reader import StepReader, episode_records
from echo_data.learn.data import prepare_rows
from echo_data.learn.features import FeatureSpec

if TYPE_CHECKING:
    from echo_data.learn.planner import PlannerConfig


def split_by_sounds(rows: list[dict[str, Any]], fraction: float, seed: int) -> tuple[set[int], set[int], list[str]]:
    """(train episodes, validation episodes, held-out instances): per category a seeded
    `fraction` of its train instances (at least one, never all) is held out; an episode
    validates when every sound it plays is held out, trains when none is."""
    by_cat: dict[str, set[str]] = {}
    for r in rows:
        for e in r["events"]:
            by_cat.setdefault(e["category"], set()).add(e["sound_id"])
    held: set[str] = set()
    rng = seeds.derived_rng(seeds.HELD_OUT_SOUNDS, seed)
    for cat in sorted(by_cat):
        ids = sorted(by_cat[cat])
        if len(ids) >= 2:
            n = min(len(ids) - 1, max(1, int(round(fraction * len(ids)))))
            held |= set(rng.permutation(ids)[:n].tolist())
    train = {r["episode_index"] for r in rows if not any(e["sound_id"] in held for e in r["events"])}
    val = {r["episode_index"] for r in rows if all(e["sound_id"] in held for e in r["events"])}
    return train, val, sorted(held)


@dataclass
class Episodes:
    """Inputs of the first frames of every episode in a split, and each row's labels."""

    inputs: dict[str, Any]
    index: np.ndarray  # episode_index
    frame: np.ndarray  # frame_index
    events: list[list[str]]  # categories in resolution order (priority 0 first)
    chains: list[list[dict[str, str]]]  # the export's answer: [{"skill", "target"}, ...]
    sounds: list[list[str]]  # sound instance ids


def episode_rows(dataset: Path, split: str) -> list[dict[str, Any]]:
    """The episode records of `split`, by index."""
    rows = episode_records(dataset)
    return sorted((r for r in rows if r["split"] == split), key=lambda r: r["episode_index"])


def _ordered_events(row: dict[str, Any]) -> list[dict[str, Any]]:
    return sorted(row["events"], key=lambda e: e["priority"])


def export_chain(row: dict[str, Any]) -> list[dict[str, str]]:
    """The planner export's answer for an episode row (echo_data.dataset.planner.answer)."""
    from echo_data.dataset.planner import answer

    return json.loads(answer(row["chain"]))


def learn_templates(rows: list[dict[str, Any]]) -> dict[str, list[list[str]]]:
    """Per category, the most frequent (skill, target kind) sequence of its chain entries."""
    seen: dict[str, Counter] = {}
    for r in rows:
        for k, ev in enumerate(r["events"]):
            seq = tuple((c["skill"], c["target_kind"]) for c in r["chain"] if c["event"] == k)
            seen.setdefault(ev["category"], Counter())[seq] += 1
    return {cat: [list(p) for p in c.most_common(1)[0][0]] for cat, c in sorted(seen.items())}


def chain_of(categories: list[str], templates: dict[str, list[list[str]]]) -> list[dict[str, str]]:
    return [{"skill": s, "target": t} for cat in categories for s, t in templates.get(cat, [])]


def chosen_episodes(cfg: PlannerConfig, meta: list[dict[str, Any]]) -> tuple[set[int], set[int] | None, list[str]]:
    """(the train episodes the run reads, its validation episodes when drawn by sounds (None:
    drawn from those read, by `split_episodes`), the held-out sound instances) of the train
    split's rows `meta`: one place, so that scoring the test split later knows what was heard."""
    chosen = subset([r["episode_index"] for r in meta], cfg.train_episodes, cfg.seed)
    if cfg.val_by != "sounds":
        return chosen, None, []
    fit_eps, val_set, held = split_by_sounds([r for r in meta if r["episode_index"] in chosen], cfg.val_fraction, cfg.seed)
    return fit_eps | val_set, val_set, held


def subset(indices: list[int], n: int | None, seed: int) -> set[int]:
    """The first `n` episodes of a permutation drawn from `seed` (all when `n` is None): a size
    that mixes the settings (episode indices run setting by setting), nested across sizes so a
    learning curve adds episodes to the same set."""
    order = seeds.derived_rng(seeds.SUBSET, seed).permutation(sorted(indices))
    return {int(i) for i in order[: len(order) if n is None else n]}


def load_episodes(dataset: Path, split: str, spec: FeatureSpec, frames: int = 1, episodes: set[int] | None = None) -> Episodes:
    """Frames 0..frames-1 of every episode of `split` (or of `episodes`) while its first skill runs
    (no event is resolved before the first skill, a Navigate, ends), prepared with `features.prepare`."""

    meta = {r["episode_index"]: r for r in episode_rows(dataset, split) if episodes is None or r["episode_index"] in episodes}
    reader = StepReader(dataset, split)
    t = pa.concat_tables(reader.index_tables(["episode_index", "frame_index", "skill_index"]))
    ep, fr = t.column("episode_index").to_numpy(), t.column("frame_index").to_numpy()
    keep = np.flatnonzero((fr < frames) & (t.column("skill_index").to_numpy() == 0) & np.isin(ep, list(meta)))
    index, frame = ep[keep].tolist(), fr[keep].tolist()
    inputs = prepare_rows(reader, keep, spec)
    rows = [meta[i] for i in index]
    return Episodes(
        inputs=inputs,
        index=np.asarray(index),
        frame=np.asarray(frame),
        events=[[e["category"] for e in _ordered_events(r)] for r in rows],
        chains=[export_chain(r) for r in rows],
        sounds=[[e["sound_id"] for e in r["events"]] for r in rows],
    )
