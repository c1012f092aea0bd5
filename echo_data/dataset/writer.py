"""The output folder of one build: staged episodes, shards in order, the manifest, meta files.

Only the build's own process writes (`echo_data.app.build` orchestrates; workers only
encode). Each finished episode is staged under `.work/` (its rows as Arrow IPC, then a JSON
commit marker) and its WAV under audio/; once every episode of a shard is staged and the
shards before it in its split are written, the shard is written and the manifest rewritten.
`finalize` writes meta/ (episodes, stats, info), the planner export and the dataset card.
"""

from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path
from typing import Any

import pyarrow as pa

from echo_data.dataset import learner_stops
from echo_data.dataset import stats as stats_mod
from echo_data.dataset.encode import EncodedEpisode
from echo_data.dataset.manifest import ShardPlan, ShardPlans, write_manifest
from echo_data.dataset.schema import ACTION_EE, ACTION_EE_EXECUTED, ACTION_EXECUTED, EPISODE_FIELDS, FORMAT_VERSION, STATE, StepLayout
from echo_data.dataset.shards import read_shard_meta, write_shard
from echo_data.dataset.storage import atomic_write_bytes, atomic_write_json, atomic_write_parquet, sha256_file
from echo_data.recipe import Recipe
from echo_data.records import ACTION_NAMES, EE_ACTION_NAMES, STATE_NAMES

WORK = ".work"  # staged episodes of an unfinished build


class DatasetWriter:
    """Owns the output directory during a build: intermediates, shards, manifest, meta."""

    def __init__(self, out: Path, recipe: Recipe, layout: StepLayout, manifest: dict[str, Any], plans: dict[str, ShardPlans]):
        self.out, self.recipe, self.layout, self.manifest, self.plans = out, recipe, layout, manifest, plans
        self.done: dict[str, dict[str, Any]] = {}
        # per split: (next shard to write, rows written before it), so a flush costs O(1) shards
        self.cursor: dict[str, tuple[int, int]] = {s: (0, 0) for s in plans}
        self.split_order = {s: n for n, s in enumerate(plans)}

    # -- state on disk
    def work(self, split: str, index: int, ext: str) -> Path:
        return self.out / WORK / split / f"{index:06d}.{ext}"

    def stored(self, split: str, index: int) -> bool:
        return self.work(split, index, "json").is_file() and self.work(split, index, "arrow").is_file()

    def verify_shards(self) -> int:
        """Keep manifest shards whose file matches its sha256; drop the rest (they are redone)."""
        kept = []
        for entry in self.manifest["shards"]:
            path = self.out / entry["file"]
            ps = self.plans.get(entry.get("split", ""))
            if ps is not None and ps.of_file(entry["file"]) and path.is_file() and sha256_file(path) == entry["sha256"]:
                kept.append(entry)
                self.done[entry["file"]] = entry
        if len(kept) != len(self.manifest["shards"]):
            self.manifest["shards"] = kept
            self.manifest["complete"] = False
            write_manifest(self.out, self.manifest)
        return sum(e["episodes"][1] - e["episodes"][0] for e in kept)

    def remove_leftovers(self) -> None:
        """Temporary files of a killed writer are never part of the dataset."""
        for path in self.out.rglob(".*.tmp-*"):
            if path.is_file():
                path.unlink()

    # -- episodes
    def store(self, enc: EncodedEpisode) -> None:
        """Media first, rows next, the JSON commit marker last (each atomic)."""
        atomic_write_bytes(self.out / enc.episode["audio_path"], enc.wav)
        if self.recipe.outputs.planner_export:
            from echo_data.dataset.planner import media_path

            planner = self.out / "planner"
            atomic_write_bytes(planner / media_path("audio", enc.split, enc.episode_id), enc.planner_wav or b"")
            atomic_write_bytes(planner / media_path("audio_binaural", enc.split, enc.episode_id), enc.planner_binaural_wav or b"")
            if enc.planner_png is not None:
                atomic_write_bytes(planner / media_path("image", enc.split, enc.episode_id), enc.planner_png)
        atomic_write_bytes(self.work(enc.split, enc.index, "arrow"), enc.table_ipc)
        atomic_write_json(self.work(enc.split, enc.index, "json"), enc.meta())

    # -- shards
    def flush(self, split: str) -> None:
        """Write every shard of `split` that is ready, in order (a shard's global `index`
        numbering starts after the rows of the shards before it)."""
        k, offset = self.cursor[split]
        plans = self.plans[split]
        while k < len(plans):
            plan = plans[k]
            entry = self.done.get(plan.file)
            if entry is None:
                if not all(self.stored(split, i) for i in plan.indices):
                    break
                metas = [json.loads(self.work(split, i, "json").read_text()) for i in plan.indices]
                tables = [pa.ipc.open_stream(pa.memory_map(str(self.work(split, i, "arrow")))).read_all() for i in plan.indices]
                entry = self._write(plan, metas, tables, offset)
            offset += entry["rows"]
            k += 1
        self.cursor[split] = (k, offset)

    def _write(self, plan: ShardPlan, metas: list[dict[str, Any]], tables: list[pa.Table], offset: int) -> dict[str, Any]:
        episodes, failures = [], []
        rejected: Counter[str] = Counter()
        skills: dict[str, list[int]] = {}
        settings: Counter[str] = Counter()
        start = offset
        name = Path(plan.file).name
        for meta, table in zip(metas, tables):
            row = dict(meta["episode"])
            row.update({"shard": name, "dataset_from_index": start, "dataset_to_index": start + table.num_rows})
            start += table.num_rows
            episodes.append(row)
            failures += meta["failures"]
            rejected.update(meta["rejected"])
            settings[row["setting"]] += 1
            for k, (a, s) in meta["skills"].items():
                acc = skills.setdefault(k, [0, 0])
                acc[0] += a
                acc[1] += s
        shard_meta = {
            "split": plan.split,
            "shard": plan.shard,
            "of": plan.of,
            "episodes": episodes,
            "stats": stats_mod.merge_features(m["stats"] for m in metas),
        }
        written = write_shard(self.out / plan.file, self.layout, tables, offset, shard_meta)
        entry = {
            "file": plan.file,
            "split": plan.split,
            "shard": plan.shard,
            "of": plan.of,
            "episodes": [plan.first, plan.last],
            "index_from": offset,
            "rows": written.rows,
            "bytes": written.bytes,
            "sha256": written.sha256,
            "settings": dict(sorted(settings.items())),
            "truncated": sum(r.get("truncated_at") is not None for r in episodes),  # cut by outputs.max_frames
            "skills": {k: skills[k] for k in sorted(skills)},
            "rejected": dict(sorted(rejected.items())),
            "failures": failures,
        }
        self.done[plan.file] = entry
        self.manifest["shards"] = sorted(self.done.values(), key=lambda e: (self.split_order[e["split"]], e["shard"]))
        write_manifest(self.out, self.manifest)
        for i in plan.indices:  # only after the manifest names the shard
            self.work(plan.split, i, "arrow").unlink(missing_ok=True)
            self.work(plan.split, i, "json").unlink(missing_ok=True)
        return entry

    # -- the end
    def finalize(self) -> None:
        """meta/episodes.parquet, meta/stats.json, meta/info.json, planner export, manifest complete."""
        from echo_data.dataset.audio import write_audio_tables
        from echo_data.dataset.card import write_card
        from echo_data.dataset.planner import write_planner_export

        metas = [read_shard_meta(self.out / e["file"]) for e in self.manifest["shards"]]
        rows = [row for m in metas for row in m["episodes"]]
        atomic_write_parquet(self.out / "meta" / "episodes.parquet", pa.Table.from_pylist(rows, schema=EPISODE_FIELDS))
        atomic_write_json(self.out / "meta" / "stats.json", stats_mod.dataset_stats(metas))
        atomic_write_json(self.out / "meta" / "info.json", self.info_json())
        if self.recipe.outputs.planner_export:
            write_planner_export(self.out, self.recipe, rows)
        write_audio_tables(self.out, rows)
        if learner_stops.KEY in self.manifest:  # built --handover-from: which episodes used it (before the card reads it)
            self.manifest[learner_stops.KEY].update(learner_stops.summary(rows))
            write_manifest(self.out, self.manifest)
        write_card(self.out)
        self.manifest["complete"] = True
        write_manifest(self.out, self.manifest)
        shutil.rmtree(self.out / WORK, ignore_errors=True)

    def info_json(self) -> dict[str, Any]:
        """LeRobot-like meta/info.json: how to read the files without echo-data."""
        shards = self.manifest["shards"]
        splits: dict[str, Any] = {}
        for s in self.plans:
            mine = [e for e in shards if e["split"] == s]
            splits[s] = {
                "episodes": sum(e["episodes"][1] - e["episodes"][0] for e in mine),
                "frames": sum(e["rows"] for e in mine),
                "files": [e["file"] for e in mine],
            }
        return {
            "codebase_version": FORMAT_VERSION,
            "name": self.recipe.name,
            "fps": self.layout.fps,
            "audio_sample_rate": self.layout.sample_rate,
            "total_episodes": sum(v["episodes"] for v in splits.values()),
            "total_frames": sum(v["frames"] for v in splits.values()),
            "splits": splits,
            "data_path": "data/{split}-{shard:05d}-of-{num_shards:05d}.parquet",
            "audio_path": "audio/{split}/{episode_id}.wav",
            "episode_index": "per split: equals the episode's index in its split; `index` counts frames per split",
            "stats_split": "train" if "train" in self.plans else "all",
            "names": {
                "action": list(ACTION_NAMES), ACTION_EXECUTED: list(ACTION_NAMES),
                ACTION_EE: list(EE_ACTION_NAMES), ACTION_EE_EXECUTED: list(EE_ACTION_NAMES), STATE: list(STATE_NAMES),
            },
            "features": self.layout.hf_features(),
            "privileged": self.layout.privileged_columns(),
            "cameras": camera_infos(self.recipe, self.layout),
        }


def camera_infos(recipe: Recipe, layout: StepLayout) -> dict[str, Any]:
    """Intrinsics and depth units of each stored camera, and where its pose and images are."""
    from echo_data.camera import camera_info
    from echo_data.dataset.schema import CAMERA_POSES, IMAGE_COLUMNS

    cfg = {"head": recipe.robot.head_camera, "wrist": recipe.robot.wrist_camera}
    return {
        cam: {
            **camera_info(cfg[cam]),
            "pose_column": CAMERA_POSES[cam],
            "image_columns": [col for key, col in IMAGE_COLUMNS.items() if key.startswith(cam) and col in layout.images],
        }
        for cam in layout.cameras
    }
