"""The paper's metrics over per-episode outcomes, each with its 95 % interval and N.

- task planning: the planner's chain equals the true chain exactly (order included);
- task planning without the receptacle (`plan_right_without_receptacle`): the same with the
  target of every Place step blanked, the skills and their order still exact;
- skill completion: the plan right and every skill succeeded in order;
- progressive success at position p: the plan right and skills 1..p succeeded, over the
  episodes whose chain has at least p skills (Habitat-style latched stages);
- Navigate success: the Navigate skill's success test, over every Navigate skill attempted (a
  skill is attempted when the plan is right and the skills before it succeeded);
- Navigate hand-over: the share of attempted Navigate skills that ended inside the next skill's
  stance (docs/handover.md), the paper's success region being the wider one;
- Navigate SPL: S * l / max(l, p) per attempted Navigate skill (Anderson et al. 2018, "On
  Evaluation of Embodied Navigation Agents"), l = the navigation expert's planned path from where
  the skill started, p = the path the base drove.
Proportions get Wilson score intervals (Wilson 1927; they stay inside [0, 1] and behave at 0 and
N, unlike the normal approximation); SPL, a mean of values in [0, 1], a normal interval clipped
to [0, 1].
"""

from __future__ import annotations

import math
from typing import Any

from echo_data.skill_table import role_of

Z95 = 1.959963984540054  # two-sided 95 % standard normal quantile


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k/n ((0, 1) for n = 0)."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    lo = 0.0 if k == 0 else max(0.0, centre - half)  # exact ends: round-off must not exclude 0 or 1
    hi = 1.0 if k == n else min(1.0, centre + half)
    return (lo, hi)


def proportion(k: int, n: int) -> dict[str, Any]:
    lo, hi = wilson(k, n)
    return {"value": k / n if n else None, "ci95": [lo, hi], "k": k, "n": n}


def mean_interval(xs: list[float]) -> dict[str, Any]:
    n = len(xs)
    if n == 0:
        return {"value": None, "ci95": [0.0, 1.0], "n": 0}
    m = sum(xs) / n
    sd = math.sqrt(sum((x - m) ** 2 for x in xs) / (n - 1)) if n > 1 else 0.0
    half = Z95 * sd / math.sqrt(n)
    return {"value": m, "ci95": [max(0.0, m - half), min(1.0, m + half)], "n": n}


def without_receptacle(chain: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """`chain` with the target of every Place step blanked (None), every step kept."""
    return [dict(c, target=None) if role_of(c["skill"]) == "deliver" else c for c in chain]


def plan_right_without_receptacle(planned: list[dict[str, Any]] | None, true: list[dict[str, Any]]) -> bool:
    """A plan right but for where Place puts the object: the planning figure to set beside the
    paper's. The paper's chains name skills and sounding objects; ours also name Place's
    receptacle (the nearest free one), which no sound tells. Only that target is forgiven: a
    plan with a Place step too many or too few, or in another position, is wrong. The one
    definition for the planner's own scores (`learn.planner.score`) and the paper table
    (`evaluation.table`); no plan (None) is wrong."""
    return planned is not None and without_receptacle(planned) == without_receptacle(true)


def summarise(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """Metrics of a list of per-episode records (see `echo_data.evaluation.run.episode_record`)."""
    n = len(episodes)
    plan = sum(bool(e["plan_correct"]) for e in episodes)
    done = sum(bool(e["success"]) for e in episodes)
    longest = max((len(e["true_chain"]) for e in episodes), default=0)
    progressive = []
    for p in range(1, longest + 1):
        eligible = [e for e in episodes if len(e["true_chain"]) >= p]
        progressive.append({"through": p, **proportion(sum(e["skills_completed"] >= p for e in eligible), len(eligible))})
    spl = [nv["spl"] for e in episodes for nv in e["navigate"] if nv["spl"] is not None]
    nav = [bool(nv["success"]) for e in episodes for nv in e["navigate"]]
    carries = [c for e in episodes for c in e.get("carries", [])]
    return {
        "episodes": n,
        "task_planning": proportion(plan, n),
        "skill_completion": proportion(done, n),
        "progressive": progressive,
        "navigate_success": proportion(sum(nav), len(nav)),
        "navigate_handover": proportion(sum(bool(nv.get("handed_over")) for e in episodes for nv in e["navigate"]), len(nav)),
        "navigate_spl": mean_interval(spl),
        # Place's carries by the drive policy (docs/handover.md#places-carry): how many ended in Place's stance
        "carry_handover": proportion(sum(bool(c["handed_over"]) for c in carries), len(carries)),
        "mean_steps": sum(e["steps"] for e in episodes) / n if n else None,
        "seconds": sum(e.get("seconds", 0.0) for e in episodes),
    }


def by_setting(episodes: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """One metrics table per setting present, in the recipe's setting order, plus "all" when mixed."""
    from echo_data.recipe import SETTINGS

    out = {s: summarise([e for e in episodes if e["setting"] == s]) for s in SETTINGS if any(e["setting"] == s for e in episodes)}
    if len(out) > 1:
        out["all"] = summarise(episodes)
    return out
