"""What a dataset built with `--handover-from RUN` says about it: the manifest's `handover_from`
(RUN's provenance, set when the build starts, and which episodes used a learner's hand-over,
counted from the episode records when it ends), the card's paragraph, the validator's check.

The episode records own the per-entry fact (`outcomes[k].handover.learner_stop`: true where the
Navigate expert stopped at the learner's pose, false where that pose was no usable cell); the
manifest's counts are derived from them (docs/handover.md).
"""

from __future__ import annotations

from typing import Any

KEY = "handover_from"


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The episodes (ids) whose Navigate stopped at a learner's hand-over, and the entries whose
    recorded pose was no usable cell (the exact pose was kept), from the episode records."""
    used, fallbacks = [], 0
    for row in rows:
        flags = [(o.get("handover") or {}).get("learner_stop") for o in row.get("outcomes") or []]
        if any(f is True for f in flags):
            used.append(row["episode_id"])
        fallbacks += sum(f is False for f in flags)
    return {"episodes": sorted(used), "fallbacks": fallbacks}


def problems(manifest: dict[str, Any], rows: list[dict[str, Any]]) -> list[str]:
    """A complete manifest's `handover_from` counts against the episode records."""
    block = manifest.get(KEY)
    if block is None or not manifest.get("complete"):
        return []
    want = summary(rows)
    return [f"manifest.json: {KEY}.{k} differs from what meta/episodes.parquet gives" for k in want if block.get(k) != want[k]]


def card_lines(manifest: dict[str, Any]) -> list[str]:
    """The card's paragraph on a build taught from a learner's hand-overs (none without one)."""
    block = manifest.get(KEY)
    if not block:
        return []
    return [
        "## Hand-overs from a learner",
        "",
        f"Built with `--handover-from {block['file']}` (sha256 {block['sha256']}; an `echo-data evaluate` on the "
        f"{block['split']} split, {block['episodes_in_run']} episodes, of the policy manifest.json names in "
        f"`{KEY}.policy`): in {len(block.get('episodes', []))} "
        "episodes the Navigate expert stopped where that learner's drive ended, so the next skill's demonstration starts "
        f"from the learner's own hand-over; {block.get('fallbacks', 0)} recorded pose(s) were no usable cell and kept the "
        "exact pose. The other episodes are built as usual. Per entry: `outcomes[k].handover.learner_stop` in meta/episodes.parquet.",
        "",
    ]
