"""The dataset card: README.md in every dataset folder, for people and for the Hugging Face Hub.

The YAML front matter is what the Hub reads (configs with split file patterns, task categories,
licence, size category, per-split example counts); the body says what the data is, how it was
made and how to load it. Everything is derived from manifest.json, meta/info.json and
meta/episodes.parquet, so `build` writes it and `info` rewrites it without a recipe.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from echo_data.dataset import learner_stops
from echo_data.dataset.reader import episodes_table, read_manifest
from echo_data.dataset.schema import (
    ACTION_EE,
    ACTION_EE_EXECUTED,
    ACTION_EXECUTED,
    IMAGE_COLUMNS,
    MEL,
    SKILL_STOP,
    SPECTROGRAM,
    STATE,
    StepLayout,
)
from echo_data.dataset.storage import atomic_write_bytes
from echo_data.episode import SPLIT_KEYS
from echo_data.records import PRIVILEGED_NOTES

CARD = "README.md"
# The licence of the generated data (the project's own; built-in sounds are synthesised by
# echo_data.sounds.synth, user sound folders keep their own terms: see the card's Sounds).
LICENSE = "mit"
_SIZE_BOUNDS = [(1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"), (1_000_000, "100K<n<1M"), (10_000_000, "1M<n<10M")]

# What each step column holds (units), for the features table.
COLUMN_NOTES = {
    "episode_index": "episode number within its split: it restarts at 0 in every split, so key episodes by (split, episode_index) or episode_id",
    "frame_index": "step number within the episode",
    "index": "row number within the split (restarts at 0 in every split)",
    "timestamp": "seconds since the episode's first step (frame_index / fps)",
    "task_index": "setting id (0 object_relocation, 1 state_transition, 2 multi_event)",
    "setting": "object_relocation, state_transition or multi_event",
    "skill": "the active skill (Navigate, Pick, Place, OpenDoor, CloseSink)",
    "skill_index": "position of the active skill in the episode's chain",
    "action": "base vx, vy (m/s, robot frame), wz (rad/s), torso (m), 7 arm joint targets (rad), gripper opening (m); the controller's own command at the step (the label to clone)",
    ACTION_EXECUTED: "the action the robot executed: `action` plus the recipe's perturbation (experts.perturbation in ee space, experts.action_noise in joint space; equal to `action` without one); replay these in the env's joint mode",
    ACTION_EE: "the same command in end-effector form: base vx, vy, wz, torso as in `action`; the tool-centre-point change this step in the base frame's axes (dx, dy, dz m; drx, dry, drz rotation vector rad); gripper_close (1 close, 0 open). Exact where the expert commands in this form (its joint form is derived); the forward-kinematics twin of a joint-born command otherwise (docs/action_spaces.md)",
    ACTION_EE_EXECUTED: "`action.ee` as executed (plus the perturbation); replay these in the env's ee mode (`action_mode='ee_delta'`)",
    STATE: "base x, y, yaw (world), torso, 7 arm joints, gripper, their velocities, holding (0/1)",
    IMAGE_COLUMNS["head_rgb"]: "head camera colour, PNG",
    IMAGE_COLUMNS["head_depth"]: "head camera depth along the optical axis, 16-bit PNG, millimetres (0 = nothing hit)",
    IMAGE_COLUMNS["wrist_depth"]: "wrist camera depth, 16-bit PNG, millimetres",
    SPECTROGRAM: "SoundSpaces-style log1p magnitude STFT of the last 1 s, per ear (0 = left)",
    MEL: "log-mel spectrogram of the last 1 s, per ear",
    "camera_pose.head": "head camera-to-world 4x4 (row-major, OpenCV axes: x right, y down, z forward)",
    "camera_pose.wrist": "wrist camera-to-world 4x4 (row-major, OpenCV axes)",
    "audio_path": "the episode's binaural WAV, relative to the dataset folder",
    "audio_sample_rate": "sample rate of that WAV (Hz)",
    "audio_offset": "sample of the WAV at which this step's observation was taken",
    "done": "last step of the episode",
    SKILL_STOP: "1 on the last row of each skill segment: the expert ended the skill after this row's action (a learned skill's stop label); 0 elsewhere and on the last row of an episode cut by outputs.max_frames",
    **{col: f"PRIVILEGED (simulator only; no learner's default input): {note}" for col, note in PRIVILEGED_NOTES.items()},
    "skill_success": "per chain slot (5): the environment's success test of that skill after this step's action, latched in chain order (the env's info['skills'][k]['done']); a row of skill k whose flag k was already true is the expert finishing k (letting go, backing off, tucking) before the next skill (unused slots False)",
}


def size_category(n: int) -> str:
    """Hugging Face's size category for n examples."""
    return next((name for bound, name in _SIZE_BOUNDS if n < bound), "10M<n<100M")


def _shape(feature: dict[str, Any]) -> str:
    t = feature.get("_type")
    if t == "Value":
        return f"{feature['dtype']}"
    if t == "List":
        return f"{feature['feature']['dtype']}[{feature.get('length', '?')}]"
    if t == "Array3D":
        return f"{feature['dtype']}{tuple(feature['shape'])}"
    return t or "?"


def card_text(out: Path) -> str:
    """The card of the complete dataset at `out` (front matter + Markdown body). Long because it is
    one document's template, read top to bottom like the card it writes."""
    m = read_manifest(out)
    info = json.loads((out / "meta" / "info.json").read_text())
    episodes = episodes_table(out, ["split", "events"]).to_pylist()
    counts = m["counts"]
    splits = sorted(info["splits"], key=SPLIT_KEYS.__getitem__)
    features = StepLayout.from_dict(m["layout"]).hf_features()  # in column order
    steps = {s: counts["steps"].get(s, 0) for s in splits}
    eps = {s: counts["episodes"].get(s, 0) for s in splits}
    recipe = m["recipe"]
    # Hugging Face warns that `dataset_info.splits` is malformed without num_bytes: the split's
    # Parquet bytes (its shards' sizes in the manifest), the size `load_dataset` downloads.
    split_bytes = {s: sum(int(e["bytes"]) for e in m["shards"] if e["split"] == s) for s in splits}
    front = {
        "license": LICENSE,
        "task_categories": ["robotics"],
        "annotations_creators": ["machine-generated"],
        "tags": ["echo-data", "mobile-manipulation", "binaural-audio", "sound-triggered", "simulation", "sapien"],
        "size_categories": [size_category(sum(steps.values()))],
        "pretty_name": f"echo-data {m['name']}",
        "configs": [{"config_name": "default", "data_files": [{"split": s, "path": f"data/{s}-*.parquet"} for s in splits], "default": True}]
        + audio_config(out, splits),
        "dataset_info": {
            "splits": [{"name": s, "num_bytes": split_bytes[s], "num_examples": steps[s]} for s in splits],
            "download_size": sum(split_bytes.values()),
            "dataset_size": sum(split_bytes.values()),
        },
    }
    sounds: dict[str, set[str]] = {}
    categories: dict[str, int] = {}
    for row in episodes:
        for e in row["events"]:
            sounds.setdefault(row["split"], set()).add(e["sound_id"])
            categories[e["category"]] = categories.get(e["category"], 0) + 1
    rate = counts["episode_success_rate"]
    path = f"out/{m['name']}"
    lines = [
        "---",
        yaml.safe_dump(front, sort_keys=False).rstrip(),
        "---",
        "",
        f"# echo-data {m['name']}",
        "",
        "Simulated episodes of a Fetch-like mobile manipulator in generated apartments that hears a sound "
        "event (ringing phone, alarm clock, furby, doorbell, running sink) binaurally and resolves it with "
        "scripted expert skills: physics and rendering by SAPIEN (CPU), room acoustics by image sources "
        "with occlusion and a statistical tail, HRTF rendering. One row per control step.",
        "",
        "## Counts",
        "",
        "| split | episodes | steps |",
        "| --- | --- | --- |",
        *[f"| {s} | {eps[s]} | {steps[s]} |" for s in splits],
        "",
        f"Control rate {info['fps']} Hz; audio {info['audio_sample_rate']} Hz, 2 channels (0 = left). "
        "Settings: " + "; ".join(f"{s}: " + ", ".join(f"{k} {v}" for k, v in c.items()) for s, c in counts["settings"].items()) + ".",
        "",
        *_calibration_lines(m.get("audio", {})),
        "## Features",
        "",
        "| column | type | meaning |",
        "| --- | --- | --- |",
        *[f"| `{c}` | {_shape(f)} | {COLUMN_NOTES.get(c, '')} |" for c, f in features.items()],
        "",
        "## Cameras",
        "",
        "| camera | width x height | K (fx, fy, cx, cy) | depth unit | pose column |",
        "| --- | --- | --- | --- | --- |",
        *[
            f"| {cam} | {c['width']} x {c['height']} | {c['K'][0][0]:.3f}, {c['K'][1][1]:.3f}, {c['K'][0][2]:g}, {c['K'][1][2]:g} "
            f"| {c['depth_unit_m']} m | `{c['pose_column']}` |"
            for cam, c in info.get("cameras", {}).items()
        ],
        "",
        "Pixel (u, v) has its centre at (u + 0.5, v + 0.5); `echo_data.camera.depth_to_world(depth, K, pose)` "
        "lifts a depth image into world points.",
        "",
        "## Sounds",
        "",
        ("Built-in sounds, synthesised by `echo_data.sounds.synth` (no recordings). " if recipe["sounds"]["builtin"] else "")
        + ("User folders: " + ", ".join(f"{k}: {v}" for k, v in recipe["sounds"]["folders"].items()) + " (their own licences apply). " if recipe["sounds"]["folders"] else "")
        + "Instances heard: " + ", ".join(f"{s} {len(v)}" for s, v in sorted(sounds.items()))
        + "; test instances are never heard in train. Events: " + ", ".join(f"{k} {v}" for k, v in sorted(categories.items())) + ".",
        "",
        "## How it was made",
        "",
        f"`echo-data build` from recipe `{m['name']}` (content hash `{m['recipe_hash']}`, seed {m['seed']}"
        + (f", --limit {m['limit']}" if m["limit"] is not None else "")
        + f"); format {m['format']}. Seeds: {m['seed_rule']}. Versions: "
        + ", ".join(f"{k} {v}" for k, v in m["versions"].items() if v)
        + ". The resolved recipe is in manifest.json.",
        "",
        "## Success rates",
        "",
        f"Episode success {rate:.1%} of attempts ({counts['episode_attempts']} attempts; failed attempts are retried "
        "with the next seed and not stored)." if rate is not None else "No attempts yet.",
        "",
        *[f"- {k}: {v['successes']}/{v['attempts']}" for k, v in m["skills"].items()],
        "",
        *_truncation_lines(recipe, counts),
        *learner_stops.card_lines(m),
        *USES,
        "## Known limits",
        "",
        "- Simulation: CPU rendering at low resolution, primitive furniture and objects, scripted experts (no human demonstrations).",
        "- Acoustics: no diffraction beyond doorway frames, doors leak sound with a fixed loss, a statistical late tail.",
        "- Stored episodes are the successful (or, with `outputs.max_frames`, cleanly cut) attempts only; failures are listed in manifest.json.",
        "",
        "## Loading",
        "",
        f"With the dataset where `echo-data build` puts it by default, `{path}` (the card never depends",
        "on where a copy was written, so copies stay byte-identical):",
        "",
        "```python",
        "import datasets",
        f'ds = datasets.load_dataset("{path}", split="train")',
        "from echo_data.dataset.torch import StepDataset",
        f'steps = StepDataset("{path}", split="train")',
        "```",
        "",
        *(
            [f"The binaural sound of every episode: `datasets.load_dataset(\"{path}\", \"audio\", split=\"train\")` "
             "(the `audio` config: episode_id, episode_index and the episode WAV as an `Audio` feature, which the Hub's viewer plays).", ""]
            if audio_config(out, splits) else []
        ),
        f"LeRobot (v3.0, for LeRobot's stock policies): `echo-data export {path} --format lerobot --out {path}-lerobot`, then "
        f'`LeRobotDataset("echo-data/{m["name"]}", root="{path}-lerobot")` in the environment `bash scripts/setup_lerobot.sh` '
        "makes (`.venv-lerobot/`). "
        f"robomimic / Diffusion Policy: `--format robomimic` (one HDF5, actions in [-1, 1]) or `--format zarr --split train` (one replay buffer per split). "
        f"LLaMA-Factory: `dataset_dir={path}/planner` (sharegpt with `<audio><image>`).",
        "",
        *links_and_citation(m["name"]),
    ]
    return "\n".join(lines)


# The paper whose task and settings echo-data reproduces (shared/seed), and the tool itself.
CITATION = """@inproceedings{ju2026instruction,
  title     = {From Instruction to Event: Sound-Triggered Mobile Manipulation},
  author    = {Ju, Hao and Huang, Shaofei and Li, Hongyu and Ding, Zihan and Liu, Si and Wang, Meng and Zheng, Zhedong},
  booktitle = {Proceedings of the 34th ACM International Conference on Multimedia (ACM MM '26)},
  year      = {2026}
}"""
# echo-data itself (the generator; its version is in manifest.json `versions`).
ECHO_DATA_BIBTEX = """@software{echo_data,
  title   = {echo-data: sound-triggered mobile manipulation data from SAPIEN with binaural acoustics},
  author  = {{echo-data contributors}},
  year    = {2026},
  version = {0.1.0},
  note    = {Python package `echo-data`; the dataset's manifest.json names the exact version}
}"""
# The HRTF the binaural audio is rendered with (assets/hrtf/README.md): its licence asks that
# the authors be cited wherever the data is used.
KEMAR_BIBTEX = """@article{gardner1995kemar,
  title   = {{HRTF} measurements of a {KEMAR}},
  author  = {Gardner, William G. and Martin, Keith D.},
  journal = {The Journal of the Acoustical Society of America},
  volume  = {97},
  number  = {6},
  pages   = {3907--3908},
  year    = {1995}
}
@techreport{gardner1994kemar,
  title       = {{HRTF} Measurements of a {KEMAR} Dummy-Head Microphone},
  author      = {Gardner, Bill and Martin, Keith},
  institution = {MIT Media Laboratory},
  type        = {Perceptual Computing Technical Report},
  number      = {280},
  year        = {1994}
}"""
# What the data is for and what it is not (the Hub card's uses / out-of-scope sections).
USES = [
    "## Uses",
    "",
    "- Training and evaluating policies that hear a sound event, find its source and act on it (imitation learning "
    "from the scripted experts' actions; the audio, camera and state columns are the observations).",
    "- Studying binaural sound localisation in simulated apartments (calibrated WAVs, source positions in meta/episodes.parquet).",
    "- Closed-loop evaluation belongs to `echo-data evaluate` in the simulator: the stored episodes are offline data.",
    "",
    "## Out of scope",
    "",
    "- Claims about real robots or real rooms without a sim-to-real study: the scenes, objects, sounds and acoustics are simulated.",
    "- Tuning on the test split: it exists to report results once (its sound instances are never heard in train).",
    "- Speech or human-voice tasks: the sounds are synthesised events (phone, alarm, furby, doorbell, sink), no speech.",
    "",
]


def audio_config(out: Path, splits: list[str]) -> list[dict[str, Any]]:
    """The card's `audio` config (one Parquet `Audio` table per split, which the Hub's viewer
    plays), where the build wrote them (datasets built before they existed have none)."""
    from echo_data.dataset.audio import AUDIO_TABLE

    files = [{"split": s, "path": AUDIO_TABLE.format(split=s)} for s in splits]
    return [{"config_name": "audio", "data_files": files}] if all((out / f["path"]).is_file() for f in files) else []


def links_and_citation(name: str, export: bool = False) -> list[str]:
    """The card's Links (the recipe that made the data, the formats it is read in) and Citation;
    `export`: the links of an export, which is derived from a dataset rather than built."""
    source = (
        [
            f"- Source: the echo-data dataset `{name}` (its recipe, manifest.json and Parquet shards); `echo-data export` of it "
            "writes this folder again, `echo-data build` of its recipe rebuilds the source.",
            "- Other formats of the same source: Hugging Face `datasets` Parquet (the source folder), robomimic HDF5 and "
            "Diffusion Policy Zarr (`echo-data export --format robomimic|zarr`).",
        ]
        if export
        else [
            f"- Recipe: `{name}` (echo-data's own recipes are `recipes/<name>.yaml`); the resolved copy, with every default, "
            "is `recipe` in manifest.json: `echo-data build` of it rebuilds these bytes.",
            "- Formats: Hugging Face `datasets` Parquet (this folder), LeRobot v3.0, robomimic HDF5 and Diffusion Policy Zarr "
            "(`echo-data export --format lerobot|robomimic|zarr`), Rerun recordings (`echo-data view --rerun`).",
        ]
    )
    return [
        "## Links",
        "",
        *source,
        "",
        "## Citation",
        "",
        "The task, settings and skill chain follow:",
        "",
        "```bibtex",
        CITATION,
        "```",
        "",
        "The data was generated with echo-data:",
        "",
        "```bibtex",
        ECHO_DATA_BIBTEX.replace("the dataset's manifest.json", "echo_data_manifest.json") if export else ECHO_DATA_BIBTEX,
        "```",
        "",
        "The binaural audio is rendered through the MIT KEMAR head-related impulse responses (recipe `acoustics.hrtf: kemar`, "
        f"the default; {'the source dataset' if export else 'manifest.json'}'s recipe says which), whose licence asks that "
        "their authors be cited wherever the data is used:",
        "",
        "```bibtex",
        KEMAR_BIBTEX,
        "```",
        "",
    ]


def _truncation_lines(recipe: dict[str, Any], counts: dict[str, Any]) -> list[str]:
    """What a build with `outputs.max_frames` stored: the first frames of each episode, not whole ones."""
    n = recipe.get("outputs", {}).get("max_frames")
    if n is None:
        return []
    cut = counts.get("truncated_episodes", {})
    return [
        f"Episodes end after their first {n} control steps (`outputs.max_frames`): the experts acted as in a whole "
        "episode, so these are the first frames of whole episodes; an episode is cut when its chain is unfinished "
        "at that step (`truncated_at` in meta/episodes.parquet, `success` and `skill_success` as they stood then; "
        "cut: " + ", ".join(f"{s} {v}" for s, v in cut.items()) + "). Skill counts above cover skills finished before the cut.",
        "",
    ]


def _calibration_lines(audio: dict[str, Any]) -> list[str]:
    """The WAVs' sound-pressure calibration and the sources' levels, from the manifest."""
    if "full_scale_db_spl" not in audio:
        return []
    levels = audio.get("source_levels_db_spl_at_1m", {})
    return [
        "## Audio calibration",
        "",
        f"WAV samples are sound pressure: a sample of 1.0 is {audio['full_scale_db_spl']:g} dB SPL "
        f"({audio.get('full_scale_pa', 0):g} Pa), {audio.get('subtype', 'PCM_16')}, never clipped. "
        f"Every episode carries a room-noise bed of {audio.get('noise_floor_dba', 0):g} dB(A). "
        f"Source levels ({audio.get('level_definition', '')}):",
        "",
        "| sound | dB SPL at 1 m |",
        "| --- | --- |",
        *[f"| {c} | {lo:g}–{hi:g} |" for c, (lo, hi) in sorted(levels.items())],
        "",
    ]


def write_card(out: Path) -> Path:
    """Write (or refresh) README.md of the complete dataset at `out`, atomically."""
    path = Path(out) / CARD
    atomic_write_bytes(path, card_text(Path(out)).encode())
    return path


# How the LeRobot export numbers and reshapes what the dataset's card describes per split.
EXPORT_NOTES = {
    "episode_index": "episode number within the export (it holds one split: `splits` in meta/info.json)",
    "observation.environment_state": "the spectrogram (else the log-mel) mean-pooled to at most 512 values and standardised per value with the train split's mean and std (meta/info.json `echo_data.environment_state` holds both and the pooling)",
    "index": "frame number across the whole export",
    SPECTROGRAM: "SoundSpaces-style log1p magnitude STFT of the last 1 s, flattened row-major from (frequency, time, ear)",
    MEL: "log-mel spectrogram of the last 1 s, flattened row-major from (frequency, time, ear)",
    IMAGE_COLUMNS["head_depth"]: "head camera depth, 8-bit x 3 channels (Cameras below gives metres per step)",
    IMAGE_COLUMNS["wrist_depth"]: "wrist camera depth, 8-bit x 3 channels (Cameras below gives metres per step)",
    IMAGE_COLUMNS["head_rgb"]: "head camera colour (PNG image, or with `--video rgb` AV1 video as LeRobot encodes it, a keyframe every 2 frames)",
}
# lerobot-doctor's warnings on an export, and why they are expected.
DOCTOR_NOTES = [
    "`camera_pose.*` dims 12-15 constant: the last row of a 4x4 rigid transform is always (0, 0, 0, 1).",
    "`audio_sample_rate` constant: one sample rate per dataset.",
    "`action` torso / gripper dims static or at their maximum: the experts hold the torso and keep the gripper open while driving.",
    "Spectrogram / `done` / `skill_success` outliers: sound onsets are loud against the noise floor; `done` and late chain slots are rare by design.",
    "`audio_path` not in stats.json: strings have no statistics.",
]


def export_card(info: dict[str, Any], src_card: Path, folder: Path) -> str:
    """README.md of the LeRobot export in `folder`: LeRobot-style front matter (with the playable
    `audio` config), the export's own numbering, features (named as the export names them, with
    what LeRobot's policies make of each), cameras, why lerobot-doctor warns, then the source
    card's sections that hold for the export too (counts, sounds, how it was made, success, uses,
    limits), their pointers to files only the source has made to say so."""
    ed = info["echo_data"]
    front: dict[str, Any] = {
        "license": LICENSE,
        "task_categories": ["robotics"],
        "annotations_creators": ["machine-generated"],
        "tags": ["LeRobot", "echo-data", "binaural-audio"],
        "size_categories": [size_category(info["total_frames"])],
        # one split per export (echo_data.dataset.lerobot): its data files are that split's
        "configs": [{"config_name": "default", "data_files": [{"split": sp, "path": "data/*/*.parquet"} for sp in info["splits"]]}, *audio_config(folder, list(info["splits"]))],
    }
    body = src_card.read_text().split("---\n", 2)[-1] if src_card.is_file() else ""
    own = ("Features", "Loading", "Links", "Citation", "Cameras")  # written here for the export
    kept = [_source_pointers(sec) for sec in body.split("\n## ")[1:] if sec.split("\n", 1)[0] not in own]
    feats = info["features"]
    renamed = ed.get("renamed", {})
    lines = [
        f"# LeRobot {info['codebase_version']} export of echo-data {ed['source']}",
        "",
        f"{info['total_episodes']} episodes, {info['total_frames']} frames at {info['fps']} Hz, written by `echo-data export "
        "--format lerobot` from the echo-data dataset named above (Parquet shards there, LeRobot's layout here). It holds "
        f"the {' and '.join(info['splits'])} split only (`splits` {info['splits']}): `lerobot-train` and `LeRobotDataset` read every "
        "episode of a folder, so each split is exported to a folder of its own (`--split test` for the test split). "
        "`index` counts frames across the export. The episode WAVs are under audio/ "
        "(`audio_path`), and once more as a Parquet `Audio` column per split in meta/audio/ (the `audio` config: "
        "episode_id, the export's episode_index and the WAV, which the Hub's viewer plays).",
        "",
        "## Features",
        "",
        "LeRobot's policies type a feature by its name: cameras (`observation.images.*`), `observation.state`, "
        "`observation.environment_state` (here the audio spectrogram pooled to at most 512 values and standardised with "
        "the train split's per-value mean and std, `echo_data.environment_state` in meta/info.json) and `action` are what stock ACT and Diffusion use; "
        "`extra.*` features are never a policy's input or output (strip `extra.` for echo-data's column name).",
        "",
        "| feature | dtype | shape | meaning |",
        "| --- | --- | --- | --- |",
        *[f"| `{k}` | {f['dtype']} | {f['shape']} | {_export_note(k, renamed)} |" for k, f in feats.items()],
        "",
        "## Cameras",
        "",
        "| camera | width x height | K (fx, fy, cx, cy) | pose column |",
        "| --- | --- | --- | --- |",
        *[
            f"| {cam} | {c['width']} x {c['height']} | {c['K'][0][0]:.3f}, {c['K'][1][1]:.3f}, {c['K'][0][2]:g}, {c['K'][1][2]:g} | `{c['pose_column']}` |"
            for cam, c in ed.get("cameras", {}).items()
        ],
        "",
        "Depth images are 8-bit, the same value in all three channels: metres = pixel / 255 x range "
        + "; ".join(f"(`{k}`: {v['range_m']:g} m)" for k, v in ed.get("depth_images", {}).items())
        + ". The exact 16-bit millimetres are in the source dataset.",
        "",
        "## lerobot-doctor",
        "",
        "`lerobot-doctor check` reports no failure; its warnings and why they are expected:",
        "",
        *[f"- {n}" for n in DOCTOR_NOTES],
        "",
        "## Loading",
        "",
        "In LeRobot's environment (`bash scripts/setup_lerobot.sh` in the echo-data repository makes `.venv-lerobot/`):",
        "",
        "```python",
        "from ledataset.datasets.lerobot_dataset import LeRobotDataset  # or lerobot.datasets.lerobot_dataset",
        f'ds = LeRobotDataset("echo-data/{ed["source"]}", root=".")',
        "```",
        "",
        *["## " + sec.rstrip() + "\n" for sec in kept],
        *links_and_citation(ed["source"], export=True),
    ]
    # the front matter through huggingface_hub's card classes (what the Hub reads them with)
    from huggingface_hub import DatasetCard, DatasetCardData

    card = DatasetCard("---\n" + DatasetCardData(**front).to_yaml() + "\n---\n\n" + "\n".join(lines))
    return str(card.content)


def _source_pointers(section: str) -> str:
    """A source-card section with its pointers to files the export does not carry (the resolved
    recipe and failures in manifest.json, source positions in meta/episodes.parquet) made to
    name the source dataset."""
    for name in ("manifest.json", "meta/episodes.parquet"):
        section = section.replace(f"in {name}", f"in the source dataset's {name}")
    return section


def _export_note(name: str, renamed: dict[str, str]) -> str:
    """What a LeRobot export feature holds: the export's own note, else the echo-data column's."""
    col = renamed.get(name, name)
    note = EXPORT_NOTES.get(name) or EXPORT_NOTES.get(col) or COLUMN_NOTES.get(col, "")
    if name.startswith("extra."):
        return f"echo-data `{col}`, not a policy input or output: {note}"
    return note if col == name else f"echo-data `{col}`: {note}"
