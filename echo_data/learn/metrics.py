"""Success rates with their uncertainty."""

from __future__ import annotations

import math


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k/n (95 % for the default z).

    Unlike the normal approximation it stays inside [0, 1] and is usable for the small n and
    rates near 0 or 1 of closed-loop and planner evaluations (Wilson 1927; Brown, Cai and
    DasGupta 2001 recommend it for n < 40)."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def rate(k: int, n: int) -> dict[str, float | int | list[float] | None]:
    """{"n", "correct", "accuracy", "ci95"} for reports."""
    lo, hi = wilson(k, n)
    return {"n": n, "correct": k, "accuracy": (k / n) if n else None, "ci95": [round(lo, 4), round(hi, 4)]}
