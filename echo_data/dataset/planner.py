"""Planner export for multimodal-LLM fine-tuning (LLaMA-Factory sharegpt with audio + image).

One record per episode: the user turn holds `<audio><image>` and a prompt listing the skill
library; the assistant answers with the ground-truth skill chain as JSON. The audio is the
first seconds the robot heard (16 kHz mono, as Qwen2.5-Omni expects), the image its first head
RGB frame; both were written next to the episode by the build. Media paths are relative to
planner/ itself, so LLaMA-Factory with `dataset_dir` = <root>/planner finds them with its default
`media_dir` (= dataset_dir). Alongside, `audio_binaural/<split>/<episode>.wav` holds the first
second with both ears (16 kHz, left/right), the window the learned planner decides from: the
mono clip stays what an Omni model reads, the binaural one keeps where the sound comes from.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from echo_data.dataset.storage import atomic_write_json
from echo_data.recipe import Recipe
from echo_data.skill_table import SKILLS

# planner/ media folders, one file per episode: (folder, suffix). The one place their paths are written.
MEDIA = {"audio": ("audio", "wav"), "audio_binaural": ("audio_binaural", "wav"), "image": ("images", "png")}


def media_path(kind: str, split: str, episode_id: str) -> str:
    """An episode's planner media file, relative to planner/ (as the records name it)."""
    folder, suffix = MEDIA[kind]
    return f"{folder}/{split}/{episode_id}.{suffix}"


def prompt(with_image: bool) -> str:
    """The user turn: what the model gets, the skills it may use, the answer format."""
    skills = "\n".join(f"- {s.name}(target): {s.description}" for s in SKILLS.values())
    media = "<audio><image>" if with_image else "<audio>"
    return (
        f"{media}You are a home robot. You hear the sound above"
        + (" and see the view from your head camera" if with_image else "")
        + ". Decide which sound events need handling and resolve them in order of priority, "
        "using only these skills:\n"
        f"{skills}\n"
        'Answer with the ordered skill chain as JSON: [{"skill": ..., "target": ...}, ...]; '
        "targets are object categories (phone, alarm, furby), door, sink, or a furniture kind."
    )


def answer(chain: list[dict[str, Any]]) -> str:
    """The ground-truth chain with targets named as a listener could (see encode.target_kind)."""
    return json.dumps([{"skill": c["skill"], "target": c["target_kind"]} for c in chain])


def planner_record(row: dict[str, Any], has_image: bool) -> dict[str, Any]:
    """One sharegpt record from a row of meta/episodes.parquet."""
    rec: dict[str, Any] = {
        "messages": [
            {"role": "user", "content": prompt(has_image)},
            {"role": "assistant", "content": answer(row["chain"])},
        ],
        "audios": [media_path("audio", row["split"], row["episode_id"])],
    }
    if has_image:
        rec["images"] = [media_path("image", row["split"], row["episode_id"])]
    return rec


def dataset_info(name: str, splits: list[str], has_image: bool) -> dict[str, Any]:
    """LLaMA-Factory dataset_info.json entries, one per split."""
    columns = {"messages": "messages", "audios": "audios"}
    if has_image:
        columns["images"] = "images"
    return {
        f"{name}_{split}": {
            "file_name": f"{split}.json",
            "formatting": "sharegpt",
            "columns": columns,
            "tags": {"role_tag": "role", "content_tag": "content", "user_tag": "user", "assistant_tag": "assistant"},
        }
        for split in splits
    }


def planner_files(out: Path, recipe: Recipe, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The planner export's JSON files (path under out/ -> content); an episode has an image
    record when its PNG is on disk. Validate rebuilds them to compare."""
    any_image = False
    files: dict[str, Any] = {}
    for split in recipe.splits:
        records = []
        for row in (r for r in rows if r["split"] == split):
            has_image = (out / "planner" / media_path("image", split, row["episode_id"])).is_file()
            any_image |= has_image
            records.append(planner_record(row, has_image))
        files[f"planner/{split}.json"] = records
    files["planner/dataset_info.json"] = dataset_info(recipe.name, list(recipe.splits), any_image)
    return files


def write_planner_export(out: Path, recipe: Recipe, rows: list[dict[str, Any]]) -> None:
    """planner/{split}.json and planner/dataset_info.json (atomic, deterministic)."""
    for rel, content in planner_files(out, recipe, rows).items():
        atomic_write_json(out / rel, content)
