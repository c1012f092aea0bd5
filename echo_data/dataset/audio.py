"""The binaural sound a step row refers to, read straight from the episode WAV.

Each step row carries `audio_path` (relative to the dataset root), `audio_sample_rate` and
`audio_offset` (the sample at which the step's observation is taken), so a user can reach
the sound without knowing the layout; this reads only the samples asked for.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np


def binaural_window(root: str | Path, row: Mapping[str, Any], seconds: float = 1.0) -> np.ndarray:
    """The `seconds` of binaural audio heard up to a step: samples [offset - n, offset) of its
    episode WAV as float32 (n, 2), channel 0 = left, zeros before the recording starts (the
    same window the step's spectrogram was computed from when `seconds` is 1).

    `row` is a step row (dict from `datasets`, `StepDataset` or pyarrow) with `audio_path`,
    `audio_sample_rate` and `audio_offset`."""
    from echo_data.dataset.reader import audio_samples

    def scalar(v: Any) -> Any:
        return v.item() if hasattr(v, "item") else v

    sr = int(scalar(row["audio_sample_rate"]))
    offset = int(scalar(row["audio_offset"]))
    n = int(round(seconds * sr))
    if n <= 0:
        raise ValueError(f"seconds must be positive, got {seconds}")
    return audio_samples(root, str(scalar(row["audio_path"])), offset - n, offset, sr)


# The episode WAVs once more as a Parquet `Audio` column per split: the dataset card's `audio`
# config, so the Hub's viewer plays the binaural sound (its viewer reads a repository through one
# builder, Parquet here: a config of bare .wav files would not load beside the step shards).
AUDIO_TABLE = "meta/audio/{split}.parquet"


def write_audio_tables(out: Path, episodes: list[dict[str, Any]]) -> list[str]:
    """Write AUDIO_TABLE for each split of `episodes` (meta/episodes.parquet rows, in order):
    episode_id, episode_index and the WAV's bytes as a Hugging Face `Audio` cell; return the paths."""
    import json

    import pyarrow as pa

    from echo_data.dataset.storage import atomic_write_parquet

    features = {"episode_id": {"dtype": "string", "_type": "Value"}, "episode_index": {"dtype": "int64", "_type": "Value"}, "audio": {"_type": "Audio"}}
    audio_type = pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    written = []
    for split in dict.fromkeys(e["split"] for e in episodes):
        rows = [e for e in episodes if e["split"] == split]
        table = pa.table(
            {
                "episode_id": pa.array([e["episode_id"] for e in rows], pa.string()),
                "episode_index": pa.array([int(e["episode_index"]) for e in rows], pa.int64()),
                "audio": pa.array([{"bytes": (out / e["audio_path"]).read_bytes(), "path": f"{e['episode_id']}.wav"} for e in rows], audio_type),
            }
        ).replace_schema_metadata({"huggingface": json.dumps({"info": {"features": features}})})
        rel = AUDIO_TABLE.format(split=split)
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_parquet(out / rel, table)
        written.append(rel)
    return written
