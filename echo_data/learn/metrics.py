"""Accuracy records for the learners' reports (the interval is the evaluation's Wilson)."""

from __future__ import annotations

from echo_data.evaluation.metrics import wilson  # one Wilson interval for the project


def rate(k: int, n: int) -> dict[str, float | int | list[float] | None]:
    """{"n", "correct", "accuracy", "ci95"} for reports."""
    lo, hi = wilson(k, n)
    return {"n": n, "correct": k, "accuracy": (k / n) if n else None, "ci95": [round(lo, 4), round(hi, 4)]}
