"""The LeRobot export's audio feature for stock policies: the stored spectrogram (or log-mel)
pooled into blocks to at most ENV_STATE_MAX values a step and standardised per value with the
train split's statistics, as `observation.environment_state` (LeRobot's ACT and Diffusion read
that key and their default configs do not normalise it; the reasons and sizes are in
`echo_data.dataset.lerobot`'s module docstring)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.episode_arrays import column_values
from echo_data.dataset.reader import split_tables
from echo_data.dataset.schema import MEL, SPECTROGRAM, StepLayout

ENV_STATE = "observation.environment_state"  # LeRobot's environment-state key (ACT, Diffusion read it)
AUDIO_FOR_POLICY = (SPECTROGRAM, MEL)  # the first present is pooled into ENV_STATE
ENV_STATE_MAX = 512  # values a step in ENV_STATE (module docstring)
ENV_STATE_MIN_STD = 0.1  # a value's std is floored at this fraction of the mean std over values


def policy_audio(layout: StepLayout) -> str | None:
    """The audio column pooled into `observation.environment_state` (None: no audio stored)."""
    return next((c for c in AUDIO_FOR_POLICY if c in layout.arrays), None)


def audio_pool(shape: tuple[int, ...], limit: int = ENV_STATE_MAX) -> tuple[int, int]:
    """(frequency, time) block sizes that bring an (F, time, ear) array to at most `limit` values:
    the longer pooled side grows first, so neither axis is averaged away."""
    f, t, ears = shape
    pf = pt = 1
    while -(-f // pf) * -(-t // pt) * ears > limit:
        if -(-f // pf) >= -(-t // pt):
            pf += 1
        else:
            pt += 1
    return pf, pt


def pooled_audio(x: np.ndarray, pool: tuple[int, int]) -> np.ndarray:
    """(T, F, time, ear) -> (T, ceil(F/pf) * ceil(time/pt) * ear) float32: block means (a block
    at an edge averages the values it has), flattened row-major."""
    pf, pt = pool
    y = np.add.reduceat(np.add.reduceat(x.astype(np.float64), np.arange(0, x.shape[1], pf), axis=1), np.arange(0, x.shape[2], pt), axis=2)
    nf = np.diff(np.append(np.arange(0, x.shape[1], pf), x.shape[1]))
    nt = np.diff(np.append(np.arange(0, x.shape[2], pt), x.shape[2]))
    y /= (nf[:, None] * nt[None, :])[None, :, :, None]
    return y.reshape(len(x), -1).astype(np.float32)


def audio_standardisation(src: Path, manifest: dict[str, Any], col: str, shape: tuple[int, ...]) -> dict[str, Any]:
    """ENV_STATE's recipe: the pooling of `col` and the per-value mean and (floored) std of the
    pooled values over the train split's frames (every frame when there is no train split)."""
    pool = audio_pool(shape)
    splits = ["train"] if "train" in manifest["splits"] else list(manifest["splits"])
    parts = []
    for table in (t for sp in splits for t in split_tables(src, manifest, sp, [col])):
        column = table.column(col)
        parts.append(pooled_audio(column_values(column, len(column)).reshape(len(column), *shape), pool).astype(np.float64))
    values = np.concatenate(parts)
    mean, std = values.mean(axis=0), values.std(axis=0)
    std = np.maximum(std, ENV_STATE_MIN_STD * float(std.mean()) or 1.0)
    return {
        "from": col, "shape": list(shape), "pool": list(pool), "split": splits[0] if len(splits) == 1 else "all",
        "mean": mean.astype(np.float32).tolist(), "std": std.astype(np.float32).tolist(),
        "decode": "pooled = value * std + mean; pooled.reshape(ceil(F / pool[0]), ceil(time / pool[1]), ear) are block means of `from`",
    }


def environment_state(x: np.ndarray, recipe: dict[str, Any]) -> np.ndarray:
    """(T, F, time, ear) audio -> (T, n) ENV_STATE values, as `recipe` (audio_standardisation) says."""
    pool = (int(recipe["pool"][0]), int(recipe["pool"][1]))
    mean, std = np.asarray(recipe["mean"], np.float32), np.asarray(recipe["std"], np.float32)
    return ((pooled_audio(x, pool) - mean) / std).astype(np.float32)
