"""Normalisation statistics (LeRobot-like meta/stats.json), computed in mergeable pieces.

Each worker summarises its own episode (count, mean, M2, min, max and a 101-point quantile
sketch per channel); shards merge their episodes' summaries and keep them in their Parquet
metadata; the build merges the shards' summaries into meta/stats.json. Means and stds are exact
(Chan's parallel update); quantiles are approximate (merged sketches of per-episode quantiles).
Everything is merged in a fixed order, so the result is byte-identical whatever the worker count.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from echo_data.dataset.schema import ACTION_EXECUTED, STATE

SKETCH_POINTS = 101  # quantiles at 0, 0.01, ..., 1 per channel
IMAGE_STRIDE = 4
REPORTED_QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
_MAX_SKETCH_VALUES = 100_000  # per channel; larger inputs are strided deterministically


def summarize(values: np.ndarray, frames: int) -> dict[str, Any]:
    """Summary of `values` shaped (n_values, channels); `frames` is the number of steps it covers."""
    x = np.asarray(values)
    if x.ndim != 2 or x.shape[0] == 0:
        raise ValueError(f"summarize expects a non-empty (n, channels) array, got shape {x.shape}")
    n = x.shape[0]
    # One transposed copy, then every reduction runs along contiguous memory: reducing over the
    # rows of an (n, C) array walks it C values at a time and cost more than rendering the episode.
    xt = np.ascontiguousarray(x.T)  # (C, n)
    mean = xt.sum(axis=1, dtype=np.float64) / n
    m2 = np.zeros_like(mean)
    for start in range(0, n, 1 << 18):  # bounded float64 temporaries
        d = xt[:, start : start + (1 << 18)].astype(np.float64) - mean[:, None]
        m2 += np.einsum("ij,ij->i", d, d)
    stride = max(1, n // _MAX_SKETCH_VALUES)
    ordered = np.sort(x[::stride], axis=0).astype(np.float64)
    pos = np.linspace(0.0, len(ordered) - 1, SKETCH_POINTS)
    lo = np.floor(pos).astype(int)
    hi = np.minimum(lo + 1, len(ordered) - 1)
    frac = (pos - lo)[:, None]
    sketch = ordered[lo] * (1 - frac) + ordered[hi] * frac  # (101, C), linear interpolation
    return {
        "frames": int(frames),
        "n": int(n),
        "mean": mean.tolist(),
        "m2": m2.tolist(),
        "min": xt.min(axis=1).astype(np.float64).tolist(),
        "max": xt.max(axis=1).astype(np.float64).tolist(),
        "sketch": sketch.T.tolist(),  # (C, 101)
    }


def merge(parts: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """Merge summaries of one feature, in the given order."""
    parts = list(parts)
    if not parts:
        raise ValueError("nothing to merge")
    n = 0
    mean = np.zeros(len(parts[0]["mean"]))
    m2 = np.zeros_like(mean)
    for p in parts:
        nb, mb, m2b = p["n"], np.asarray(p["mean"]), np.asarray(p["m2"])
        tot = n + nb
        delta = mb - mean
        mean = mean + delta * (nb / tot)
        m2 = m2 + m2b + delta**2 * (n * nb / tot)
        n = tot
    # Quantile sketch: each part's points stand for n/101 values each; re-read the mixture.
    probs = np.linspace(0.0, 1.0, SKETCH_POINTS)
    channels = len(parts[0]["mean"])
    sketch = []
    for c in range(channels):
        pts = np.concatenate([np.asarray(p["sketch"][c]) for p in parts])
        w = np.concatenate([np.full(SKETCH_POINTS, p["n"] / SKETCH_POINTS) for p in parts])
        order = np.argsort(pts, kind="stable")
        cum = np.cumsum(w[order])
        cum /= cum[-1]
        idx = np.searchsorted(cum, probs * (1 - 1e-12), side="left").clip(0, len(pts) - 1)
        q = pts[order][idx]
        q[0], q[-1] = pts.min(), pts.max()
        sketch.append(q.tolist())
    return {
        "frames": int(sum(p["frames"] for p in parts)),
        "n": int(n),
        "mean": mean.tolist(),
        "m2": m2.tolist(),
        "min": np.min([p["min"] for p in parts], axis=0).tolist(),
        "max": np.max([p["max"] for p in parts], axis=0).tolist(),
        "sketch": sketch,
    }


def merge_features(parts: Iterable[dict[str, dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    """Merge {feature: summary} dicts feature by feature (features missing in a part are skipped)."""
    parts = list(parts)
    names: list[str] = []
    for p in parts:
        names += [k for k in p if k not in names]
    return {k: merge([p[k] for p in parts if k in p]) for k in names}


def finalize(summary: dict[str, Any]) -> dict[str, list[float]]:
    """A merged summary -> the published min/max/mean/std/count/q01..q99 record."""
    n = summary["n"]
    std = np.sqrt(np.maximum(np.asarray(summary["m2"]) / max(n, 1), 0.0))
    sketch = np.asarray(summary["sketch"])  # (C, 101)
    out: dict[str, list[float]] = {
        "min": list(summary["min"]),
        "max": list(summary["max"]),
        "mean": list(summary["mean"]),
        "std": std.tolist(),
        "count": [summary["frames"]],
    }
    for name, q in REPORTED_QUANTILES.items():
        out[name] = sketch[:, int(round(q * (SKETCH_POINTS - 1)))].tolist()
    return out


def dataset_stats(shard_metas: list[dict[str, Any]]) -> dict[str, dict[str, list[float]]]:
    """meta/stats.json from the shards' metadata: the train split's shards (all when there is
    no train split), merged and finalised. Validate recomputes it the same way."""
    train = [m["stats"] for m in shard_metas if m["split"] == "train"] or [m["stats"] for m in shard_metas]
    merged = merge_features(train)
    return {k: finalize(v) for k, v in merged.items()}


def episode_feature_values(
    action: np.ndarray,
    state: np.ndarray,
    images: dict[str, tuple[str, np.ndarray]],
    arrays: dict[str, np.ndarray],
    executed: np.ndarray | None = None,
    vectors: dict[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """The (n_values, channels) matrices summarised per feature, in the units loaders return:
    action/state per dimension; RGB per channel in [0, 1]; depth in metres; spectrograms per ear.
    Images are summarised from every IMAGE_STRIDE-th pixel in each direction (normalisation
    statistics do not need every pixel, and full frames would cost more than rendering them)."""
    out = {"action": action.reshape(len(action), -1), STATE: state.reshape(len(state), -1)}
    if executed is not None:
        out[ACTION_EXECUTED] = executed.reshape(len(executed), -1)
    for col, values in (vectors or {}).items():  # the ee action forms and the privileged columns
        out.setdefault(col, values.reshape(len(values), -1))
    for col, (kind, stack) in images.items():
        sub = stack[:, ::IMAGE_STRIDE, ::IMAGE_STRIDE]
        if kind == "rgb":
            out[col] = sub.reshape(-1, 3).astype(np.float32) / 255.0
        else:
            out[col] = sub.reshape(-1, 1).astype(np.float32) / 1000.0
    for col, stack in arrays.items():
        out[col] = stack.reshape(-1, stack.shape[-1])
    return out
