"""`echo-data validate`: check a dataset on disk against its manifest, byte by byte.

Reads every shard in full and every WAV; returns human-readable problems (empty = sound).
Everything derived is rebuilt and compared with what is on disk: the manifest's totals from
its shard entries, meta/stats.json and meta/info.json from the shards, the planner JSON from
the episode records, each planner WAV from its episode WAV, and each step's spectrogram and
log-mel from the WAV samples (they must describe exactly the audio in the file). Files that
no record names (a stray shard or WAV) are reported, as are clipped samples. The schema comes
from the recipe in the manifest, so columns added to the layout need no change here.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset import learner_stops
from echo_data.dataset import stats as stats_mod
from echo_data.dataset.encode import planner_binaural_wav_bytes, planner_wav_bytes
from echo_data.dataset.manifest import ManifestError, load_manifest, new_manifest, plan_shards, totals
from echo_data.dataset.planner import MEDIA, media_path
from echo_data.dataset.reader import episodes_table
from echo_data.dataset.schema import (
    ACTION_EE,
    ACTION_EE_EXECUTED,
    EPISODE_FIELDS,
    MEL,
    SHARD_META_KEY,
    SKILL_STOP,
    SPECTROGRAM,
    StepLayout,
    column_to_numpy,
)
from echo_data.dataset.shards import read_shard_meta
from echo_data.dataset.storage import canonical_json, sha256_file
from echo_data.pcm import clipped_samples, dequantise
from echo_data.recipe import Recipe
from echo_data.records import EE_ACTION_DIM


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
        if (g.metadata or {}).get(b"privileged") != (w.metadata or {}).get(b"privileged"):
            out.append(f"{name}: column {g.name} is not flagged privileged as the layout says")
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


# Recomputed features may differ from stored ones by float rounding on another CPU or library
# build; a spectrogram of different audio (e.g. before clipping) differs by far more.
FEATURE_ATOL = 1e-3


def _feature_problems(eid: str, audio: np.ndarray, offsets: np.ndarray, stored: dict[str, np.ndarray], sample_rate: int) -> list[str]:
    """Stored per-step spectrogram / log-mel against those of the WAV's own samples."""
    from echo_data.acoustics.features import step_features

    if not stored or not len(offsets):
        return []
    mel_bands = stored[MEL].shape[1] if MEL in stored else 64
    spec, mel = step_features(dequantise(audio), offsets, sample_rate, mel_bands)
    problems: list[str] = []
    for col, want in ((SPECTROGRAM, spec), (MEL, mel)):
        got = stored.get(col)
        if got is None:
            continue
        if got.shape != want.shape:
            problems.append(f"{eid}: {col} has shape {got.shape[1:]}, the WAV gives {want.shape[1:]}")
            continue
        diff = np.abs(got.astype(np.float64) - want)
        if not np.all(diff <= FEATURE_ATOL):
            step = int(np.unravel_index(np.argmax(diff), diff.shape)[0])
            problems.append(f"{eid}: {col} does not match the WAV's samples (max difference {diff.max():.3g} at step {step})")
    return problems


_WAV_MISSING = "{episode_id}: missing {audio_path}"
_WAV_CHANGED = "{episode_id}: {audio_path} does not match its sha256 (truncated or modified)"


def shard_damage(out: Path, file: str, entry: dict[str, Any] | None) -> str | None:
    """A shard missing or changed since the manifest recorded it (None when whole)."""
    path = out / file
    if not path.is_file():
        return f"{file}: missing"
    if entry is not None and sha256_file(path) != entry["sha256"]:
        return f"{file}: sha256 differs from the manifest"
    return None


def first_damage(out: Path, split: str | None = None, episode: int | None = None) -> str | None:
    """The first shard or WAV that a reader of the dataset would trip on (missing, truncated,
    modified: validate's own file checks), limited to one split or one episode of it; None when
    they are whole. `export`, `view` and `train` call it before reading, so damage is one line
    naming the file instead of a traceback from Arrow or libsndfile. Raises `ManifestError`
    for a folder that is no dataset."""
    manifest = load_manifest(out)
    try:
        records = episodes_table(out).to_pylist()
    except Exception as e:
        return f"meta/episodes.parquet: unreadable ({type(e).__name__})"
    chosen = [r for r in records if (split is None or r["split"] == split) and (episode is None or r["episode_index"] == episode)]
    listed = {Path(e["file"]).name: e for e in manifest.get("shards", [])}
    for name in sorted({r["shard"] for r in chosen}):
        entry = listed.get(name)
        damage = shard_damage(out, entry["file"] if entry else f"data/{name}", entry)
        if damage:
            return damage
    for r in chosen:
        path = out / r["audio_path"]
        if not path.is_file():
            return _WAV_MISSING.format(**r)
        if sha256_file(path) != r["audio_sha256"]:
            return _WAV_CHANGED.format(**r)
    return None


class DamagedDataset(ValueError):
    """A dataset whose shards or WAVs are not what its manifest recorded: one line naming the file."""


class UnfinishedBuild(DamagedDataset):
    """A dataset whose build stopped before it finished (its manifest says `complete: false`)."""


def check_whole(out: Path, split: str | None = None, episode: int | None = None) -> None:
    """Raise `UnfinishedBuild` for a build that has not finished (its files are not all there yet:
    that is no damage), `DamagedDataset` naming the first damaged file (`first_damage`), or
    `ManifestError`."""
    if not load_manifest(out).get("complete"):
        raise UnfinishedBuild(f"{out}: an unfinished build (manifest.json: complete is false): finish it with "
                              f"`echo-data build RECIPE --out {out} --resume`")
    damage = first_damage(out, split, episode)
    if damage:
        raise DamagedDataset(f"{out}: damaged: {damage} (`echo-data validate {out}` lists every problem)")


def _audio_problems(out: Path, row: dict[str, Any], offsets: np.ndarray, sample_rate: int, stored: dict[str, np.ndarray] | None = None) -> list[str]:
    import soundfile as sf

    path = out / row["audio_path"]
    eid = row["episode_id"]
    if not path.is_file():
        return [_WAV_MISSING.format(**row)]
    data = path.read_bytes()
    problems = []
    if hashlib.sha256(data).hexdigest() != row["audio_sha256"]:
        problems.append(_WAV_CHANGED.format(**row))
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
    clipped = clipped_samples(audio)
    if clipped:
        problems.append(f"{eid}: {row['audio_path']} has {clipped} clipped samples (at 16-bit full scale)")
    if audio.shape[1] == 2:
        problems += _feature_problems(eid, audio, offsets, stored or {}, sample_rate)
    return problems


def _label_columns(table: pa.Table) -> dict[str, np.ndarray]:
    """The columns `_label_problems` checks, as arrays (empty where the shard lacks them: its schema problem is reported)."""
    out: dict[str, np.ndarray] = {}
    names = set(table.column_names)
    if {SKILL_STOP, "skill_index"} <= names:
        out[SKILL_STOP] = table.column(SKILL_STOP).to_numpy()
        out["skill_index"] = table.column("skill_index").to_numpy()
    for col in (ACTION_EE, ACTION_EE_EXECUTED):
        if col in names:
            out[col] = column_to_numpy(table.column(col), (EE_ACTION_DIM,))[:, EE_ACTION_DIM - 1]
    return out


def _label_problems(file: str, record: dict[str, Any], cols: dict[str, np.ndarray]) -> list[str]:
    """One episode's labels: `skill_stop` 1 exactly on each skill segment's last row (not on the
    last row of a cut episode), `gripper_close` of both ee forms binary."""
    out = []
    eid = record["episode_id"]
    if SKILL_STOP in cols and len(cols[SKILL_STOP]):
        seg = cols["skill_index"]
        want = np.append(seg[1:] != seg[:-1], record.get("truncated_at") is None)
        if not np.array_equal(cols[SKILL_STOP].astype(bool), want):
            out.append(f"{file}: episode {eid} skill_stop is not 1 exactly on each skill segment's last row")
    for col in (ACTION_EE, ACTION_EE_EXECUTED):
        if col in cols and not np.all((cols[col] == 0.0) | (cols[col] == 1.0)):
            out.append(f"{file}: episode {eid} {col} gripper_close is not 0 or 1")
    return out


def validate(out: Path, progress: Callable[[int], None] = lambda n: None) -> list[str]:
    """Problems found in the dataset at `out` (empty list when it is sound); `progress(1)` after each shard."""
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
    for plans in plan_shards(recipe, manifest.get("limit"), manifest.get("only_splits")).values():
        next_index = 0
        for plan in plans:
            progress(1)
            path = out / plan.file
            entry = listed.pop(plan.file, None)
            if entry is None:
                problems.append(f"{plan.file}: not in the manifest")
            damage = shard_damage(out, plan.file, entry)
            if damage:
                problems.append(damage)
            if not path.is_file():
                continue
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
            try:
                features = {c: column_to_numpy(table.column(c), layout.arrays[c]) for c in (SPECTROGRAM, MEL) if c in layout.arrays}
            except Exception as e:
                problems.append(f"{plan.file}: audio feature columns unreadable ({type(e).__name__}: {e})")
                features = {}
            if entry is not None:
                problems += _entry_problems(plan.file, entry, rows, path.stat().st_size, next_index - n, (plan.first, plan.last))
            labels = _label_columns(table)
            pos = 0
            for r in rows:
                k = r["n_steps"]
                problems += _label_problems(plan.file, r, {c: a[pos : pos + k] for c, a in labels.items()})
                if not (np.all(ep[pos : pos + k] == r["episode_index"]) and np.array_equal(fr[pos : pos + k], np.arange(k))):
                    problems.append(f"{plan.file}: episode {r['episode_id']} rows are not frames 0..{k - 1} in order")
                mine = {c: a[pos : pos + k] for c, a in features.items() if len(a) >= pos + k}
                problems += _audio_problems(out, r, off[pos : pos + k], layout.sample_rate, mine)
                pos += k
            if pos != n:
                problems.append(f"{plan.file}: episode records cover {pos} rows of {n}")
            for col in layout.arrays:
                storage = table.column(col)
                lengths = [len(c.storage if isinstance(c.type, pa.BaseExtensionType) else c) for c in storage.chunks]
                if sum(lengths) != n:
                    problems.append(f"{plan.file}: {col} has {sum(lengths)} values for {n} rows")
            all_rows += rows
    for file in listed:
        problems.append(f"{file}: listed in the manifest but not part of the planned layout")
    if not all_rows and not problems:
        problems.append("the dataset holds no episodes")
    problems += _manifest_problems(manifest, recipe)
    problems += _meta_problems(out, recipe, all_rows)
    problems += learner_stops.problems(manifest, all_rows)
    problems += _derived_problems(out, recipe, layout, manifest, all_rows)
    problems += _stray_problems(out, recipe, manifest, all_rows)
    problems += _audio_table_problems(out, all_rows)
    for path in sorted(out.rglob(".*.tmp-*")):
        problems.append(f"{path.relative_to(out)}: leftover temporary file")
    return problems


def _episode_fields(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Records as EPISODE_FIELDS: a field added later (truncated_at) is null in the table and
    absent from older shards' records, and both read as None here."""
    return [{f: r.get(f) for f in EPISODE_FIELDS.names} for r in records]


def _meta_problems(out: Path, recipe: Recipe, rows: list[dict[str, Any]]) -> list[str]:
    problems = []
    try:
        ep = episodes_table(out).to_pylist()
        if _episode_fields(ep) != _episode_fields(rows):
            problems.append("meta/episodes.parquet: differs from the episode records in the shards")
    except Exception as e:
        problems.append(f"meta/episodes.parquet: unreadable ({type(e).__name__})")
    return problems


def _entry_problems(file: str, entry: dict[str, Any], rows: list[dict[str, Any]], size: int, index_from: int, episodes: tuple[int, int]) -> list[str]:
    """A manifest shard entry against its shard: what the file holds, not what someone typed."""
    problems = []
    if entry.get("bytes") != size:
        problems.append(f"manifest.json: {file} is {size} bytes, the manifest says {entry.get('bytes')}")
    if list(entry.get("episodes", [])) != list(episodes):
        problems.append(f"manifest.json: {file} holds episodes {list(episodes)}, the manifest says {entry.get('episodes')}")
    if entry.get("index_from") != index_from:
        problems.append(f"manifest.json: {file} starts at index {index_from}, the manifest says {entry.get('index_from')}")
    settings = dict(sorted(Counter(r["setting"] for r in rows).items()))
    if entry.get("settings") != settings:
        problems.append(f"manifest.json: {file} settings {entry.get('settings')} differ from its episodes' {settings}")
    return problems


def _manifest_problems(manifest: dict[str, Any], recipe: Recipe) -> list[str]:
    """Totals (counts, success rate, skills, rejections, failed attempts) are a function of the
    shard entries: an edited total no longer matches them. Keys the build never writes are
    named (a hand edit or another tool's: a reader would silently ignore them)."""
    known = set(new_manifest(recipe, manifest.get("limit"), StepLayout.from_recipe(recipe), 1, "local", manifest.get("only_splits"))) | set(totals([]))
    known.add(learner_stops.KEY)  # built --handover-from RUN
    problems = [f"manifest.json: unknown key {k!r}" for k in sorted(set(manifest) - known)]
    try:
        want = totals(manifest.get("shards", []))
    except Exception as e:
        return [f"manifest.json: shard entries are malformed ({type(e).__name__}: {e})"]
    for key, value in want.items():
        got = manifest.get(key)
        if key == "counts" and isinstance(got, dict):
            for sub, v in value.items():
                if got.get(sub) != v:
                    problems.append(f"manifest.json: counts.{sub} is {got.get(sub)!r}, its shard entries give {v!r}")
        elif got != value:
            problems.append(f"manifest.json: {key} differs from what its shard entries give")
    if manifest.get("seed") != recipe.seed:
        problems.append(f"manifest.json: seed {manifest.get('seed')!r} differs from the recipe's {recipe.seed}")
    return problems


def _json_file_problem(out: Path, rel: str, want: Any) -> str | None:
    path = out / rel
    if not path.is_file():
        return f"{rel}: missing"
    try:
        got = path.read_bytes()
    except OSError as e:
        return f"{rel}: unreadable ({e.strerror or e})"
    if got != canonical_json(want):
        return f"{rel}: differs from what the shards give (edited or stale)"
    return None


def _derived_problems(out: Path, recipe: Recipe, layout: StepLayout, manifest: dict[str, Any], rows: list[dict[str, Any]]) -> list[str]:
    """meta/stats.json, meta/info.json and the planner export, rebuilt and compared byte by byte."""
    from echo_data.dataset.planner import planner_files
    from echo_data.dataset.writer import DatasetWriter

    problems: list[str] = []
    metas = []
    for e in manifest.get("shards", []):
        try:
            metas.append(read_shard_meta(out / e["file"]))
        except Exception:
            return problems  # an unreadable shard is reported already; nothing to rebuild from
    expected: dict[str, Any] = {}
    try:
        expected["meta/stats.json"] = stats_mod.dataset_stats(metas)
    except Exception as e:
        problems.append(f"meta/stats.json: cannot be rebuilt from the shards ({type(e).__name__}: {e})")
    plans = plan_shards(recipe, manifest.get("limit"), manifest.get("only_splits"))
    expected["meta/info.json"] = DatasetWriter(out, recipe, layout, manifest, plans).info_json()
    if recipe.outputs.planner_export:
        expected.update(planner_files(out, recipe, rows))
    for rel, want in expected.items():
        p = _json_file_problem(out, rel, want)
        if p:
            problems.append(p)
    if recipe.outputs.planner_export:
        problems += _planner_media_problems(out, layout, rows)
    return problems


def _planner_media_problems(out: Path, layout: StepLayout, rows: list[dict[str, Any]]) -> list[str]:
    """Each planner WAV (mono and binaural) must be the clip its episode WAV gives (catches truncation and edits)."""
    import soundfile as sf

    problems = []
    for r in rows:
        rels = {kind: "planner/" + media_path(kind, r["split"], r["episode_id"]) for kind in ("audio", "audio_binaural")}
        for rel in rels.values():
            if not (out / rel).is_file():
                problems.append(f"{rel}: missing")
        try:
            audio, _ = sf.read(str(out / r["audio_path"]), dtype="int16", always_2d=True)
            track = dequantise(audio)
            want = {"audio": planner_wav_bytes(track, layout.sample_rate), "audio_binaural": planner_binaural_wav_bytes(track, layout.sample_rate)}
        except Exception:
            continue  # the episode WAV's own problem is reported already
        for kind, rel in rels.items():
            if (out / rel).is_file() and (out / rel).read_bytes() != want[kind]:
                problems.append(f"{rel}: differs from the clip of {r['audio_path']} (truncated or modified)")
    return problems


def _audio_table_problems(out: Path, rows: list[dict[str, Any]]) -> list[str]:
    """The card's audio tables (`audio.AUDIO_TABLE`, where present) hold exactly the episode WAVs."""
    from echo_data.dataset.audio import AUDIO_TABLE

    problems = []
    for split in dict.fromkeys(r["split"] for r in rows):
        rel = AUDIO_TABLE.format(split=split)
        if not (out / rel).is_file():
            continue
        try:
            got = pq.read_table(out / rel).to_pylist()
        except Exception as e:
            problems.append(f"{rel}: unreadable ({type(e).__name__}: {e})")
            continue
        mine = [r for r in rows if r["split"] == split]
        if [g["episode_id"] for g in got] != [r["episode_id"] for r in mine]:
            problems.append(f"{rel}: episodes differ from meta/episodes.parquet")
            continue
        for g, r in zip(got, mine):
            wav = out / r["audio_path"]
            if wav.is_file() and g["audio"]["bytes"] != wav.read_bytes():
                problems.append(f"{rel}: {r['episode_id']} differs from {r['audio_path']}")
    return problems


def _stray_problems(out: Path, recipe: Recipe, manifest: dict[str, Any], rows: list[dict[str, Any]]) -> list[str]:
    """Media and shard files that no record names: a reader globbing the folders would use them."""
    expected = {e["file"] for e in manifest.get("shards", [])}
    expected |= {r["audio_path"] for r in rows}
    if recipe.outputs.planner_export:
        expected |= {"planner/" + media_path(kind, r["split"], r["episode_id"]) for kind in MEDIA for r in rows}
    problems = []
    for folder in ("data", "audio", *(f"planner/{f}" for f, _ in MEDIA.values())):
        for path in sorted((out / folder).rglob("*")) if (out / folder).is_dir() else []:
            rel = path.relative_to(out).as_posix()
            if path.is_file() and rel not in expected and not path.name.startswith("."):
                problems.append(f"{rel}: stray file (no record names it)")
    return problems
