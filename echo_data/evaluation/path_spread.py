"""How far the arm paths of two demonstrations of one skill lie apart (the multimodality a
behaviour-cloning learner cannot average over).

A path is the commanded arm joints (7) per control step. Paths are aligned at the untuck's first
step (`first_arm_motion`); `path_gap` compares them without regard to time shifts between phases
(a base arriving a step later), so only a detour through other joint values counts;
`joint_range_at_steps` is the plain per-step spread across many episodes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def first_arm_motion(arms: Sequence[np.ndarray]) -> int:
    """The step at which the commanded arm first leaves where it started (the untuck's start);
    the path's length when it never moves."""
    return next((k for k, q in enumerate(arms) if float(np.max(np.abs(np.asarray(q) - np.asarray(arms[0])))) > 1e-4), len(arms))


def path_gap(a: Sequence[np.ndarray], b: Sequence[np.ndarray], steps: int = 60, slack: int = 30) -> float:
    """How far two arm paths out of the tuck lie apart (rad): over `steps` steps from each one's
    first arm motion, the largest joint distance (max over joints) from a configuration of one
    path to the nearest of the other's (within `slack` more steps), both ways. Nearest points make
    it a lower bound: a 1 rad bulge of one joint shows as 0.67 rad (tests/test_path_spread.py)."""
    pa = np.asarray(a, dtype=np.float64)[first_arm_motion(a):]
    pb = np.asarray(b, dtype=np.float64)[first_arm_motion(b):]
    if len(pa) == 0 or len(pb) == 0:
        return float("inf")

    def one_way(p: np.ndarray, q: np.ndarray) -> float:
        d = np.max(np.abs(p[:steps, None, :] - q[None, : steps + slack, :]), axis=2)
        return float(np.max(np.min(d, axis=1)))

    return max(one_way(pa, pb), one_way(pb, pa))


def joint_range_at_steps(paths: Sequence[Sequence[np.ndarray]], steps: Sequence[int]) -> dict[int, float]:
    """At each phase step from the untuck's start, the largest joint range (max - min over the
    paths that are that long, max over joints), rad."""
    aligned = [np.asarray(p, dtype=np.float64)[first_arm_motion(p):] for p in paths]
    out = {}
    for k in steps:
        rows = [p[k] for p in aligned if len(p) > k]
        if rows:
            r = np.stack(rows)
            out[int(k)] = float(np.max(r.max(axis=0) - r.min(axis=0)))
    return out
