"""Step rows of one skill, decoded once and prepared for training, and the episode-level split.

Rows are decoded to the arrays the world gives a policy (PNG -> uint8 RGB / uint16 millimetre
depth) and passed through `features.canonical` and `features.prepare`, exactly what a policy
does when it acts, then kept in memory: decoding PNGs every epoch would cost more than training
these small networks on two cores.
The active skill of a row is its `skill` column; a skill's segment is a run of rows with the
same (episode_index, skill_index) (a chain may Navigate twice). The target kind a segment serves
(phone, door, table, ...) is its chain entry's `target_kind` in meta/episodes.parquet.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import StepReader, episodes_table
from echo_data.dataset.schema import ACTION, IMAGE_COLUMNS, SKILL_STOP, STATE
from echo_data.learn.carry import select_rows
from echo_data.learn.features import FeatureError, FeatureSpec, canonical, kind_index, prepare

ROWS_PER_DECODE = 256  # rows decoded at once: memory stays bounded by this many frames


@dataclass
class SkillRows:
    """Everything training needs for the rows of one skill in one split."""

    inputs: dict[str, Any]  # prepared tensors, leading dimension = rows
    actions: np.ndarray  # (n, chunk, A) raw actions t..t+chunk-1 within the segment (A: the cloned column's size)
    action_pad: np.ndarray  # (n, chunk) True where the chunk ran past the segment's end
    goals: np.ndarray  # (n, 3) the segment's final base pose (x, y, yaw): where the expert went
    episodes: np.ndarray  # (n,) episode_index
    segments: np.ndarray  # (n,) segment id, contiguous rows, unique over the split (-1: appended rows)
    states: np.ndarray | None = None  # (n, STATE_DIM) the raw state each row's action was taken in (None: appended rows)

    def __len__(self) -> int:
        return len(self.episodes)


def loader_form(column: str, stored: np.ndarray) -> np.ndarray:
    """Stored pixels of many rows -> the loaders' form row by row (`features.canonical`)."""
    if column not in IMAGE_COLUMNS.values():
        return stored.astype(np.float32)
    return np.stack([canonical(column, x) for x in stored]) if len(stored) else stored.astype(np.float32)


def skills_in(dataset: Path, split: str) -> list[str]:
    """Skill names present in a split's step rows."""
    names: set[str] = set()
    for t in StepReader(dataset, split).index_tables(["skill"]):
        names.update(t.column("skill").unique().to_pylist())
    return sorted(names)


def chain_kinds(dataset: Path, split: str) -> dict[tuple[int, int], str]:
    """(episode_index, skill_index) -> the target kind of that chain entry, for one split."""
    table = episodes_table(dataset, ["episode_index", "split", "chain"])
    out: dict[tuple[int, int], str] = {}
    for ep, sp, chain in zip(*(table.column(c).to_pylist() for c in ("episode_index", "split", "chain")), strict=True):
        if sp == split:
            out.update({(int(ep), k): str(c["target_kind"]) for k, c in enumerate(chain)})
    return out


def skill_kinds(dataset: Path, split: str, skill: str) -> tuple[str, ...]:
    """The target kinds `skill` serves in a split (sorted): the "kind" input's vocabulary."""
    table = episodes_table(dataset, ["split", "chain"])
    return tuple(sorted({str(c["target_kind"]) for sp, chain in zip(*(table.column(c).to_pylist() for c in ("split", "chain")), strict=True)
                         if sp == split for c in chain if c["skill"] == skill}))


def load_skill_rows(
    dataset: Path, split: str, skill: str, spec: FeatureSpec, chunk: int = 1, tick: Callable[[int], object] | None = None, action_column: str = ACTION,
    stop: bool = False, from_stance: bool = False, with_carries: bool = False,
) -> SkillRows:
    """Decode and prepare every row of `skill` in `split` (in shard order), with its next `chunk`
    actions of `action_column` within its segment (`dataset.reader`'s windows); with `stop`, each
    action carries one more entry, the dataset's `skill_stop` (1 on a segment's last row).
    `from_stance`, `with_carries`: Place's rows from its stance on only, a drive learner's rows
    plus Place's carries, each carry its own segment ending in a STOP (`learn.carry`)."""
    import torch

    reader = StepReader(dataset, split)
    idx = reader.index
    chosen = select_rows(reader, skill, from_stance, with_carries)
    keep = chosen.rows
    if len(keep) == 0:
        raise ValueError(f"{dataset}: no {skill!r} rows in split {split!r}")
    if action_column not in reader.meta.columns:
        raise FeatureError(f"--action-column {action_column}: {dataset} stores no such column (it has {', '.join(c for c in reader.meta.columns if c.startswith(ACTION))})")
    if stop and SKILL_STOP not in reader.meta.columns:
        raise FeatureError(f"--stop: {dataset} stores no {SKILL_STOP} column (built before it was recorded)")
    windows, pad = chosen.windows(reader, {action_column: range(chunk), **({SKILL_STOP: range(chunk)} if stop else {})})
    actions = windows[action_column].astype(np.float32)
    if stop:  # the window is clamped at the segment's end: only the real last row says stop (a carry's: its last)
        says = np.maximum(windows[SKILL_STOP], chosen.carry_ends(range(chunk)))
        actions = np.concatenate([actions, (says * ~pad[SKILL_STOP]).astype(np.float32)[..., None]], axis=-1)
    states = reader.read([STATE], keep)[STATE]
    _, last = idx.bounds("segment")
    goals = reader.read([STATE], last[keep])[STATE][:, [0, 1, 2]]
    kinds_of = chain_kinds(dataset, split) if "kind" in spec.inputs else {}
    kind = np.array([kind_index(spec, kinds_of.get((int(e), int(k)))) for e, k in zip(idx.episode[keep], idx.skill_index[keep], strict=True)]) if kinds_of else None
    parts: dict[str, list[Any]] = {}
    for lo in range(0, len(keep), ROWS_PER_DECODE):
        sel = slice(lo, lo + ROWS_PER_DECODE)
        decoded = {c: loader_form(c, v) for c, v in reader.read(spec.columns, keep[sel]).items()}
        for k, v in prepare(decoded, spec, goal=torch.from_numpy(goals[sel]), kind=None if kind is None else kind[sel]).items():
            parts.setdefault(k, []).append(v)
        if tick is not None:
            tick(len(keep[sel]))
    return SkillRows(
        inputs={k: torch.cat(v) for k, v in parts.items()},
        actions=actions,
        action_pad=pad[action_column],
        goals=goals,
        episodes=idx.episode[keep],
        segments=idx.segment[keep],
        states=states,
    )


def append_rows(rows: SkillRows, inputs: dict[str, Any], actions: np.ndarray, pad: np.ndarray | None = None,
                segments: np.ndarray | None = None) -> SkillRows:
    """`rows` plus labelled rows from elsewhere (DAgger), as episode -1 so they never validate;
    `segments` (0.., contiguous) makes them segments of their own, numbered after `rows`' (else -1:
    rows without a segment), `pad` masks window entries past their segment's end."""
    import torch

    n, chunk = len(actions), rows.actions.shape[1]
    if chunk != actions.shape[1]:
        raise ValueError(f"appended rows carry {actions.shape[1]} actions per row, training {chunk}")
    seg = np.full(n, -1, dtype=rows.segments.dtype) if segments is None else segments.astype(rows.segments.dtype) + int(rows.segments.max()) + 1
    return SkillRows(
        inputs={k: torch.cat([v, inputs[k]]) for k, v in rows.inputs.items()},
        actions=np.concatenate([rows.actions, actions.astype(np.float32)]),
        action_pad=np.concatenate([rows.action_pad, np.zeros((n, chunk), dtype=bool) if pad is None else pad]),
        goals=np.concatenate([rows.goals, np.full((n, 3), np.nan, dtype=np.float32)]),
        episodes=np.concatenate([rows.episodes, np.full(n, -1, dtype=rows.episodes.dtype)]),
        segments=np.concatenate([rows.segments, seg]),
    )


def prepare_rows(
    reader: StepReader,
    rows: np.ndarray,
    spec: FeatureSpec,
    goals: np.ndarray | None = None,
    tick: Callable[[int], object] | None = None,
    kinds: np.ndarray | None = None,
) -> dict[str, Any]:
    """Decode and prepare split rows `rows` (sorted, global), one row group (64 rows) at a time
    (`reader.batches`: each row group read once) so memory stays bounded; `goals` ((len(rows), 3))
    feed "target", `kinds` (per row: indices into `spec.kinds`) feed "kind"."""
    import torch

    parts: dict[str, list[Any]] = {}
    for sel, table in reader.batches(rows, spec.columns):
        goal = None if goals is None else torch.from_numpy(goals[sel])
        kind = None if kinds is None else kinds[sel]
        decoded = {c: loader_form(c, v) for c, v in reader.decode(table, spec.columns).items()}
        for k, v in prepare(decoded, spec, goal=goal, kind=kind).items():
            parts.setdefault(k, []).append(v)
        if tick is not None:
            tick(len(sel))
    return {k: torch.cat(v) for k, v in parts.items()}


def count_rows(dataset: Path, split: str, skill: str) -> int:
    """Rows of `skill` in `split` (cheap: reads one string column)."""
    return sum(int((np.asarray(t.column("skill").to_pylist()) == skill).sum()) for t in StepReader(dataset, split).index_tables(["skill"]))


def split_episodes(episodes: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    """Episode ids held out for validation: a seeded `fraction` of them (at least one when
    there are two or more), so no validation frame comes from an episode seen in training."""
    ids = np.unique(episodes)
    if len(ids) < 2 or fraction <= 0:
        return np.zeros(0, dtype=ids.dtype)
    n = min(len(ids) - 1, max(1, int(round(fraction * len(ids)))))
    return np.sort(np.random.default_rng(seed).permutation(ids)[:n])
