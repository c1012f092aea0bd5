"""`echo-data validate`: check a dataset on disk against its manifest, byte by byte.

Reads every shard in full and every WAV; returns human-readable problems (empty = sound).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset.manifest import ManifestError, load_manifest, plan_shards
from echo_data.dataset.schema import SHARD_META_KEY, StepLayout
from echo_data.dataset.writer import sha256_file
from echo_data.recipe import Recipe

STATS_KEYS = ("min", "max", "mean", "std", "count")


def _plain(t: pa.DataType) -> pa.DataType:
    """Extension types as their storage (they read back either way, depending on imports)."""
    return t.storage_type if isinstance(t, pa.BaseExtensionType) else t


def _schema_problems(name: str, got: pa.Schema, want: pa.Schema) -> list[str]:
    out = []
    if got.names != want.names:
        return [f"{name}: columns {got.names} differ from the expected {want.names}"]
    for g, w in zip(got, want):
        if not _plain(g.type).equals(_plain(w.type)):
            out.append(f"{name}: column {g.name} has type {_plain(g.type)}, expected {_plain(w.type)}")
    md = got.metadata or {}
    hf = md.get(b"huggingface")
    if hf is None:
        out.append(f"{name}: no Hugging Face features metadata")
    else:
        try:
            feats = json.loads(hf)["info"]["features"]
        except (ValueError, KeyError, TypeError):
            feats = None
        if feats != json.loads(want.metadata[b"huggingface"])["info"]["features"]:
            out.append(f"{name}: Hugging Face features metadata differs from the recipe's layout")
    if SHARD_META_KEY.encode() not in md:
        out.append(f"{name}: no {SHARD_META_KEY!r} metadata")
    return out


def _audio_problems(out: Path, row: dict[str, Any], offsets: np.ndarray, sample_rate: int) -> list[str]:
    import soundfile as sf

    path = out / row["audio_path"]
    eid = row["episode_id"]
    if not path.is_file():
        return [f"{eid}: missing {row['audio_path']}"]
    data = path.read_bytes()
    problems = []
    if hashlib.sha256(data).hexdigest() != row["audio_sha256"]:
        problems.append(f"{eid}: {row['audio_path']} does not match its sha256 (truncated or modified)")
    try:
        import io

        audio, sr = sf.read(io.BytesIO(data), dtype="int16", always_2d=True)
    except Exception as e:  # soundfile raises several types for broken files
        return problems + [f"{eid}: {row['audio_path']} is unreadable ({type(e).__name__}: {e})"]
    if sr != sample_rate or audio.shape[1] != 2:
        problems.append(f"{eid}: {row['audio_path']} is {sr} Hz x {audio.shape[1]} ch, expected {sample_rate} Hz x 2")
    if len(audio) != row["audio_samples"]:
        problems.append(f"{eid}: {row['audio_path']} has {len(audio)} samples, expected {row['audio_samples']}")
    if len(offsets) and (offsets.min() < 0 or offsets.max() > len(audio)):
        problems.append(f"{eid}: audio_offset outside the WAV (max {offsets.max()}, WAV has {len(audio)} samples)")
    return problems


def validate(out: Path) -> list[str]:
    """Problems found in the dataset at `out` (empty list when it is sound)."""
    out = Path(out)
    try:
        manifest = load_manifest(out)
    except ManifestError as e:
        return [str(e)]
    try:
        recipe = Recipe.model_validate(manifest["recipe"])
    except Exception as e:
        return [f"manifest.json: recipe does not validate ({type(e).__name__}: {e})"]
    problems: list[str] = []
    if recipe.content_hash() != manifest.get("recipe_hash"):
        problems.append("manifest.json: recipe_hash does not match the recipe it holds")
    if not manifest.get("complete"):
        problems.append("manifest.json: the build is not complete (run build --resume)")
    layout = StepLayout.from_recipe(recipe)
    want = layout.schema()
    listed = {e["file"]: e for e in manifest.get("shards", [])}
    all_rows: list[dict[str, Any]] = []
    for split, plans in plan_shards(recipe, manifest.get("limit")).items():
        next_index = 0
        for plan in plans:
            path = out / plan.file
            entry = listed.pop(plan.file, None)
            if entry is None:
                problems.append(f"{plan.file}: not in the manifest")
            if not path.is_file():
                problems.append(f"{plan.file}: missing")
                continue
            if entry is not None and sha256_file(path) != entry["sha256"]:
                problems.append(f"{plan.file}: sha256 differs from the manifest")
            try:
                pf = pq.ParquetFile(path)
                table = pf.read()
                shard_meta = json.loads((pf.schema_arrow.metadata or {})[SHARD_META_KEY.encode()])
            except Exception as e:
                problems.append(f"{plan.file}: unreadable ({type(e).__name__}: {e})")
                continue
            problems += _schema_problems(plan.file, pf.schema_arrow, want)
            n = table.num_rows
            if entry is not None and n != entry["rows"]:
                problems.append(f"{plan.file}: {n} rows, manifest says {entry['rows']}")
            ep = table.column("episode_index").to_numpy()
            fr = table.column("frame_index").to_numpy()
            ix = table.column("index").to_numpy()
            off = table.column("audio_offset").to_numpy()
            if not np.array_equal(ix, np.arange(next_index, next_index + n)):
                problems.append(f"{plan.file}: global index is not continuous from {next_index}")
            next_index += n
            rows = shard_meta.get("episodes", [])
            if [r["episode_index"] for r in rows] != list(plan.indices):
                problems.append(f"{plan.file}: holds episodes {[r['episode_index'] for r in rows]}, expected {list(plan.indices)}")
            pos = 0
            for r in rows:
                k = r["n_steps"]
                if not (np.all(ep[pos : pos + k] == r["episode_index"]) and np.array_equal(fr[pos : pos + k], np.arange(k))):
                    problems.append(f"{plan.file}: episode {r['episode_id']} rows are not frames 0..{k - 1} in order")
                problems += _audio_problems(out, r, off[pos : pos + k], layout.sample_rate)
                pos += k
            if pos != n:
                problems.append(f"{plan.file}: episode records cover {pos} rows of {n}")
            for col, shape in layout.arrays.items():
                storage = table.column(col)
                lengths = [len(c.storage if isinstance(c.type, pa.BaseExtensionType) else c) for c in storage.chunks]
                if sum(lengths) != n:
                    problems.append(f"{plan.file}: {col} has {sum(lengths)} values for {n} rows")
            all_rows += rows
    for file in listed:
        problems.append(f"{file}: listed in the manifest but not part of the planned layout")
    problems += _meta_problems(out, recipe, all_rows)
    for path in sorted(out.rglob(".*.tmp-*")):
        problems.append(f"{path.relative_to(out)}: leftover temporary file")
    return problems


def _meta_problems(out: Path, recipe: Recipe, rows: list[dict[str, Any]]) -> list[str]:
    problems = []
    try:
        ep = pq.read_table(out / "meta" / "episodes.parquet").to_pylist()
        if ep != rows:
            problems.append("meta/episodes.parquet: differs from the episode records in the shards")
    except Exception as e:
        problems.append(f"meta/episodes.parquet: unreadable ({type(e).__name__})")
    try:
        stats = json.loads((out / "meta" / "stats.json").read_text())
        for feat in ("action", "observation.state") + tuple(StepLayout.from_recipe(recipe).arrays):
            if rows and not all(k in stats.get(feat, {}) for k in STATS_KEYS):
                problems.append(f"meta/stats.json: no {'/'.join(STATS_KEYS)} for {feat}")
    except Exception as e:
        problems.append(f"meta/stats.json: unreadable ({type(e).__name__})")
    if recipe.outputs.planner_export:
        for split in recipe.splits:
            try:
                records = json.loads((out / "planner" / f"{split}.json").read_text())
            except Exception as e:
                problems.append(f"planner/{split}.json: unreadable ({type(e).__name__})")
                continue
            if len(records) != sum(1 for r in rows if r["split"] == split):
                problems.append(f"planner/{split}.json: {len(records)} records for a split of different size")
            for rec in records:
                for media in rec.get("audios", []) + rec.get("images", []):
                    if not (out / "planner" / media).is_file():
                        problems.append(f"planner/{split}.json: missing {media}")
        if not (out / "planner" / "dataset_info.json").is_file():
            problems.append("planner/dataset_info.json: missing")
    return problems
