"""Which weights a measurement was made with, and whether they are still the shipped ones.

Every `echo-data evaluate --json` document carries `weights`: per skill the SHA-256 of the
weights file its learner acted with (None: a scripted or built-in policy, which has none), and
the planner's. A table row records the block of the evaluation it read; `row_state` compares it
with the reference set shipped now (echo_data.learn.reference), so a table marks a row whose
learners are no longer the shipped ones as stale by itself, not by prose.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from echo_data.learn.reference import ReferenceSet
from echo_data.skills import EXPERTS

State = Literal["current", "stale", "unrecorded"]
PLANNER = "planner"  # the planner's key beside the skills' in a row's verdict


def weights(policy: Mapping[str, Any], planner: Mapping[str, Any]) -> dict[str, Any]:
    """The `weights` block from the results' `policy` and `planner` identities
    (`agents.loading.identity`): {"skills": {skill: sha256 | None}, "planner": sha256 | None}; an
    evaluation over several training seeds (`evaluation.seeds`, identity `members`) gives a skill
    whose members differ the list of their hashes, member by member."""
    if "members" in policy:
        each = [weights(m, planner)["skills"] for m in policy["members"]]
        return {"skills": {s: each[0][s] if len({m[s] for m in each}) == 1 else [m[s] for m in each] for s in EXPERTS},
                "planner": planner.get("weights_sha256")}
    per = policy.get("skills")
    if per is None:  # one policy drives every skill
        skills = {s: policy.get("weights_sha256") for s in EXPERTS}
    else:
        skills = {s: per.get(s, per.get("*", {})).get("weights_sha256") for s in EXPERTS}
    return {"skills": skills, "planner": planner.get("weights_sha256")}


@dataclass(frozen=True)
class Verdict:
    """A measurement's weights against the shipped set: `state`, and why when not current."""

    state: State
    why: str = ""


def verdict(recorded: Mapping[str, Any] | None, shipped: ReferenceSet) -> Verdict:
    """`current` when every learned skill (and a learned planner) was measured with weights the
    reference set ships for it now (serving or a variant); `stale` naming the first that was not; `unrecorded` for
    a measurement from before results named their weights. Scripted skills (no hash) always match."""
    if not recorded:
        return Verdict("unrecorded", "measured before results named their weights")
    used = {**dict(recorded.get("skills") or {}), PLANNER: recorded.get("planner")}
    for who, hashes in used.items():
        ships = shipped.shipped(None if who == PLANNER else who)
        for sha in hashes if isinstance(hashes, list) else [hashes]:  # a list: one per training seed
            if sha is not None and sha not in ships:
                now = f"ships {', '.join(sorted(h[:12] for h in ships))}" if ships else "ships none"
                return Verdict("stale", f"{who}: measured with weights {sha[:12]}, the reference set {now}")
    return Verdict("current")


def row_state(entries: Mapping[str, Mapping[str, Any]], shipped: ReferenceSet) -> Verdict:
    """A table row's verdict over its entries (one per setting, each with the `weights` it was
    measured with): stale if any entry is, unrecorded if any is and none is stale."""
    found = [verdict(e.get("weights"), shipped) for e in entries.values()]
    return next((v for v in found if v.state == "stale"), next((v for v in found if v.state == "unrecorded"), Verdict("current")))


def stale_rows(rows: Mapping[str, Mapping[str, Mapping[str, Any]]], shipped: ReferenceSet | None = None) -> set[str]:
    """The names of the rows ({name: {setting: entry}}) measured with weights the reference set
    (default: the one in use, `learn.reference.reference_dir`) no longer ships: what a table marks."""
    shipped = ReferenceSet.load() if shipped is None else shipped
    return {name for name, per in rows.items() if row_state(per, shipped).state == "stale"}


def composed_weights(plans: Mapping[str, Any], outcomes: Mapping[str, Any]) -> dict[str, Any] | None:
    """The weights of a row composed from two evaluations: the skills' of `outcomes`, the planner's
    of `plans` (None when either did not record them)."""
    if not (plans.get("weights") and outcomes.get("weights")):
        return None
    return {**outcomes["weights"], "planner": plans["weights"]["planner"]}
