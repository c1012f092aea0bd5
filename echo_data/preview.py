"""`echo-data preview`: one episode as a person would look at and listen to it.

Writes the sampled spec (episode.json), a top-down plan with the expert's path
(topdown.png), the first head RGB frame (head_rgb.png), a contact sheet of head RGB every 2 s
of the expert run (frames.png), what the robot hears at its start
pose for the first 2 s (heard.wav), its spectrogram (spectrogram.png) and a dB map of every
event's source over the floor plan at ear height (acoustic_map.png).

The folder is written whole or not at all: into a temporary sibling, then swapped in. It
replaces an earlier preview (its marker lists its files; a preview from before the marker is
recognised by holding only preview files) and nothing else: a folder holding anything echo-data's
preview did not write is refused before the simulation, every byte kept.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from echo_data.episode import EpisodeSpec
from echo_data.protocols import SoundLibrary
from echo_data.recipe import Recipe

HEARD_SECONDS = 2.0
KIND = "preview"  # the marker's kind (dataset/written.py)
FORMAT = "echo-data-preview/1"
FILES = ("episode.json", "topdown.png", "head_rgb.png", "frames.png", "heard.wav", "spectrogram.png", "acoustic_map.png")
PREVIEW_STAGES = 5  # progress calls of write_preview: sampled, simulated, pictures, heard, acoustic map


def _save_png(path: Path, img: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(img).save(path)


CONTACT_EVERY_S = 2.0  # seconds of episode between frames of the contact sheet
CONTACT_COLUMNS = 6


def contact_sheet(frames: list[np.ndarray], times: list[float], out: Path, columns: int = CONTACT_COLUMNS) -> None:
    """Head frames side by side in rows, each captioned with its episode time (frames.png)."""
    from PIL import Image, ImageDraw

    h, w = frames[0].shape[:2]
    columns = min(columns, len(frames))
    rows = (len(frames) + columns - 1) // columns
    sheet = Image.new("RGB", (columns * w, rows * (h + 12)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for k, (img, t) in enumerate(zip(frames, times)):
        x, y = (k % columns) * w, (k // columns) * (h + 12)
        sheet.paste(Image.fromarray(img), (x, y + 12))
        draw.text((x + 2, y), f"{t:.0f} s", fill=(0, 0, 0))
    sheet.save(out)


def heard_at_start(spec: EpisodeSpec, recipe: Recipe, library: SoundLibrary) -> np.ndarray:
    """Binaural audio at the start pose for the first HEARD_SECONDS, every source sounding: the
    episode's own renderer (`OnlineTrack`: levels, noise floor, full scale, as written)."""
    from echo_data.envs.audio import OnlineTrack

    x, y, yaw = spec.start
    track = OnlineTrack(spec, recipe, library)
    pose = (x, y, recipe.acoustics.ear_height, yaw)
    n = int(round(HEARD_SECONDS * recipe.robot.control_hz))
    return np.concatenate([track.step(pose) for _ in range(n)])


def draw_acoustic_map(spec: EpisodeSpec, recipe: Recipe, out: Path, step: float = 0.25, progress: Callable[[str], None] = lambda s: None) -> None:
    """Steady sound pressure level (dB SPL, at each source's drawn level) of every event's source
    over the plan at ear height (`echo_data.viz.acoustic_map` draws it on the one top-down map).
    `progress(note)` after each grid row: the map is minutes of image-source responses."""
    from echo_data.acoustics.room import AcousticScene, omni_rir
    from echo_data.viz.acoustic_map import save_acoustic_maps

    cfg = recipe.acoustics
    scene = AcousticScene(spec.plan, cfg)
    b = spec.plan.bounds
    xs = np.arange(b.xmin + step / 2, b.xmax, step)
    ys = np.arange(b.ymin + step / 2, b.ymax, step)
    maps = []
    for e, ev in enumerate(spec.events):
        l1m = spec.source_level(e)
        level = np.full((len(ys), len(xs)), np.nan)
        for j, y in enumerate(ys):
            for i, x in enumerate(xs):
                if spec.plan.room_at(x, y) < 0:
                    continue
                h = omni_rir(scene.response(ev.source, (x, y, cfg.ear_height)))  # direct sound at 1 m = 0 dB
                level[j, i] = l1m + 10 * np.log10(np.sum(h.astype(np.float64) ** 2) + 1e-20)
            progress(f"acoustic map {e + 1}/{len(spec.events)} ({ev.category}), row {j + 1}/{len(ys)}")
        maps.append((ev.category, (float(ev.source[0]), float(ev.source[1]), float(ev.source[2])), l1m, level))
    grid = (float(xs[0] - step / 2), float(xs[-1] + step / 2), float(ys[0] - step / 2), float(ys[-1] + step / 2))
    save_acoustic_maps(spec.plan, maps, grid, cfg.noise_floor_dba, out)


def _before_marker(rel: str) -> bool:
    return rel in FILES


def check_preview_out(out: Path) -> None:
    """`out` may take a preview: absent, empty or an earlier preview (else `NotWrittenByUs`)."""
    from echo_data.dataset.written import written_files

    if out.is_dir() and any(out.iterdir()):
        written_files(out, KIND, _before_marker)


def write_preview(
    recipe: Recipe, recipe_dir: Path | None, seed: int, out: Path, index: int = 0, progress: Callable[[str], None] = lambda s: None,
    note: Callable[[str], None] = lambda s: None,
) -> dict[str, object]:
    """Sample episode `index` with the recipe's seed replaced by `seed`; simulate; write the files.
    `progress(stage)` is called PREVIEW_STAGES times, as each stage ends; `note(text)` says how
    far the running stage is, any number of times (the acoustic map, per grid row)."""
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary

    recipe = recipe.model_copy(update={"seed": seed})
    library = SoundLibrary.from_recipe(recipe, recipe_dir)
    spec, rejected = sample_episode(recipe, "train", index, library)
    progress("sampled")
    from echo_data.dataset.written import mark_export, replace_folder

    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")  # this process's own
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        summary = _write_files(spec, rejected, recipe, library, tmp, progress, note)
        mark_export(tmp, KIND, FORMAT)
        replace_folder(tmp, out, KIND, _before_marker)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return summary


def _write_files(spec: EpisodeSpec, rejected: object, recipe: Recipe, library: SoundLibrary, out: Path, progress: Callable[[str], None],
                 note: Callable[[str], None]) -> dict[str, object]:
    """The preview's files in `out` (`note`: how far the acoustic map is)."""
    import soundfile as sf

    from echo_data.app.pipeline import simulate
    from echo_data.viz.spectrogram import save_spectrogram
    from echo_data.viz.topdown import draw_topdown

    (out / "episode.json").write_text(json.dumps(spec.to_dict(), indent=2))
    rollout = simulate(spec, recipe, observe=True)
    progress("simulated")
    path = [(float(s.state[0]), float(s.state[1])) for s in rollout.steps]
    draw_topdown(spec.plan, out / "topdown.png", path=path, start=spec.start, events=spec.events, chain=spec.chain)
    if rollout.steps and rollout.steps[0].head_rgb is not None:
        _save_png(out / "head_rgb.png", rollout.steps[0].head_rgb)
        every = max(1, int(round(CONTACT_EVERY_S * recipe.robot.control_hz)))
        picked = list(range(0, len(rollout.steps), every))
        contact_sheet([rgb for i in picked if (rgb := rollout.steps[i].head_rgb) is not None], [i / recipe.robot.control_hz for i in picked], out / "frames.png")
    progress("pictures")
    fs = recipe.acoustics.sample_rate
    heard = heard_at_start(spec, recipe, library)
    sf.write(out / "heard.wav", heard, fs, subtype="PCM_16")
    cats = " + ".join(ev.category for ev in spec.events)
    save_spectrogram(heard, fs, out / "spectrogram.png", f"heard at start: {cats}")
    progress("heard")
    draw_acoustic_map(spec, recipe, out / "acoustic_map.png", progress=note)
    progress("acoustic map")
    return {
        "episode_id": spec.episode_id,
        "setting": spec.setting,
        "chain": [f"{c.skill}({c.target})" for c in spec.chain],
        "success": rollout.success,
        "outcomes": [(o.skill, o.success, o.reason) for o in rollout.outcomes],
        "rejected": rejected,
        "steps": len(rollout.steps),
    }
