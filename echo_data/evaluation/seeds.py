"""Several trainings of one learner in one evaluation: the episodes shared out over the seeds.

A single training is not a figure: two trainings of one command can differ by half the test
episodes. So a row is measured over several training seeds without costing more episodes: a
`--policy` target may list one run per seed joined by `+` (`Pick=runs/pick-s0+runs/pick-s1+runs/pick-s2`),
and member j of the evaluation is the j-th run of every skill that lists several (skills that list
one run, and the fallback, are the same in every member). Episode i is acted by member i mod k,
so N episodes cost N, each seed gets about N / k of them, and the results give the pooled figure
with its Wilson interval (the N episodes as one sample of "a training of this command") and each
seed's own figure beside it (`per_seed`, and its range).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from echo_data.evaluation.metrics import proportion

MEMBER_SEPARATOR = "+"


class SeedSpecError(ValueError):
    """A `--policy` list whose per-seed runs do not line up (one line)."""


def shipped_seeds(policy: str | Sequence[str]) -> str | Sequence[str]:
    """`policy` with each skill that the shipped reference set serves by several training seeds
    and that `policy` gives to `reference` (by name, or as the fallback) written as their list
    (`SKILL=reference:A+reference:B+...`): `--policy reference` is then measured over the seeds
    the set ships, like any `+` list. Unchanged when no target is `reference`."""
    from echo_data.agents.compose import PolicySpecError, is_composite, parse_specs
    from echo_data.learn.reference import NAME, ReferenceError, ReferenceSet

    specs = [policy] if isinstance(policy, str) else list(policy)
    if NAME not in (s.rpartition("=")[2].strip() for s in specs):
        return policy
    try:
        by_skill, fallback = parse_specs(specs) if is_composite(policy) or specs == [NAME] else ({}, specs[0])
        refs = ReferenceSet.load()
    except (PolicySpecError, ReferenceError) as e:
        raise SeedSpecError(str(e)) from None
    from echo_data.skills import EXPERTS

    asked = {s: t for s, t in by_skill.items() if t == NAME} | ({s: NAME for s in EXPERTS if s not in by_skill} if fallback == NAME else {})
    several = {s: refs.served(s) for s in asked if len(refs.served(s)) > 1}
    if not several:
        return policy
    out = [s for s in specs if s.partition("=")[0].strip() not in several]
    out += [f"{s}={MEMBER_SEPARATOR.join(f'{NAME}:{n}' for n in names)}" for s, names in several.items()]
    return out


def split_members(policy: str | Sequence[str]) -> list[str | tuple[str, ...]]:
    """The policy argument of each member (one per training seed); one member when no target
    lists several runs. Every target that lists several must list the same number. A skill the
    reference set serves by several seeds counts as such a list (`shipped_seeds`)."""
    policy = shipped_seeds(policy)
    specs = [policy] if isinstance(policy, str) else list(policy)
    counts = {}
    for s in specs:
        _, eq, target = s.rpartition("=")
        parts = (target if eq else s).split(MEMBER_SEPARATOR)
        if len(parts) > 1:
            if any(not p.strip() for p in parts):
                raise SeedSpecError(f"--policy {s!r}: an empty run between {MEMBER_SEPARATOR!r}")
            counts[s] = len(parts)
    if not counts:
        return [policy if isinstance(policy, str) else tuple(policy)]
    k = set(counts.values())
    if len(k) != 1:
        raise SeedSpecError("--policy: " + ", ".join(f"{s!r} lists {c} runs" for s, c in counts.items()) + "; every per-seed list needs the same count")
    n = k.pop()
    members: list[str | tuple[str, ...]] = []
    for j in range(n):
        one = []
        for s in specs:
            if s not in counts:
                one.append(s)
                continue
            skill, eq, target = s.rpartition("=")
            run = (target if eq else s).split(MEMBER_SEPARATOR)[j].strip()
            one.append(f"{skill}={run}" if eq else run)
        members.append(one[0] if isinstance(policy, str) else tuple(one))
    return members


def member_of(index: int, members: int) -> int:
    """Which member acts episode `index`: the episodes are dealt out in turn."""
    return index % members


def per_seed(episodes: list[dict[str, Any]], members: int) -> dict[str, Any]:
    """Skill completion per member (each a proportion with its Wilson interval) and their range,
    beside the pooled figure over all of them."""
    scored = [e for e in episodes if "skipped" not in e]
    each = [proportion(sum(bool(e["success"]) for e in scored if e["member"] == j), sum(e["member"] == j for e in scored)) for j in range(members)]
    values = [m["value"] for m in each if m["value"] is not None]
    return {
        "members": members,
        "pooled": proportion(sum(bool(e["success"]) for e in scored), len(scored)),
        "per_seed": each,
        "range": [min(values), max(values)] if values else None,
    }
