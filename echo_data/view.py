"""`echo-data view`: one stored episode as an MP4 to watch and listen to.

Each video frame is one control step: head RGB, head depth, a top-down map (walls, furniture,
the sound sources, the robot's path so far and its heading), the binaural spectrogram scrolling
past a cursor at the step, and the active skill as a caption. The sound track is the episode's
binaural WAV from the first step on, so picture and sound stay in step (frame t is at
t / fps seconds, the sample at `audio_offset` of step t). Encoding is `echo_data.media.write_mp4`.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.compute as pc
import pyarrow.parquet as pq
from PIL import Image, ImageDraw

from echo_data.dataset.manifest import load_manifest
from echo_data.dataset.schema import IMAGE_COLUMNS, STATE
from echo_data.media import colour_lut, fit_nearest

PANEL = 256  # side of the image and map panels (pixels)
SPEC_H = 128  # spectrogram strip height
CAPTION_H = 28
SPEC_SECONDS = 4.0  # spectrogram history shown left of the cursor
SPEC_AHEAD = 1.0  # and ahead of it
DEPTH_RANGE_M = 6.0  # depth colour scale: 0 m .. this
_SOURCE_COLOURS = {"phone": (220, 40, 40), "alarm": (230, 140, 0), "furby": (170, 60, 200), "doorbell": (30, 110, 220), "sink": (0, 160, 160)}


class ViewError(ValueError):
    """Bad input for `view` (no such episode, no images): exit 2, nothing written."""


def _panel(img: np.ndarray) -> np.ndarray:
    """A camera image scaled into a PANEL x PANEL square without distortion."""
    h, w = img.shape[:2]
    s = PANEL / max(h, w)
    fitted = fit_nearest(img, max(1, round(w * s)), max(1, round(h * s)))
    out = np.zeros((PANEL, PANEL, 3), dtype=np.uint8)
    y, x = (PANEL - fitted.shape[0]) // 2, (PANEL - fitted.shape[1]) // 2
    out[y : y + fitted.shape[0], x : x + fitted.shape[1]] = fitted
    return out


def episode_rows(root: Path, split: str, index: int) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The episode record and its step rows (in order)."""
    m = load_manifest(root)
    episodes = pq.read_table(root / "meta" / "episodes.parquet")
    mask = pc.and_(pc.equal(episodes["split"], split), pc.equal(episodes["episode_index"], index))
    found = episodes.filter(mask).to_pylist()
    if not found:
        n = m["counts"]["episodes"].get(split, 0)
        raise ViewError(f"{root}: no {split} episode {index} (the {split} split has {n} episodes: 0..{n - 1})")
    ep = found[0]
    table = pq.read_table(root / "data" / ep["shard"], filters=[("episode_index", "=", index)])
    return ep, table.to_pylist()


def _spectrogram_image(audio: np.ndarray, sr: int) -> tuple[np.ndarray, float]:
    """Log-magnitude STFT of both ears (left above right) as uint8 rows x columns, and columns per second."""
    from scipy.signal import stft

    hop = sr // 100
    rows = []
    for ch in range(2):
        _, _, z = stft(audio[:, ch], fs=sr, nperseg=4 * hop, noverlap=3 * hop, boundary=None, padded=False)
        db = 20 * np.log10(np.abs(z[1:]) + 1e-6)
        rows.append(db[::-1])
    spec = np.concatenate([rows[0], np.full((2, rows[0].shape[1]), np.nan), rows[1]])
    top = np.nanmax(spec) if np.isfinite(spec).any() else 0.0
    img = np.clip((spec - (top - 80.0)) / 80.0, 0, 1)
    img = np.nan_to_num(img, nan=1.0)
    return (img * 255).astype(np.uint8), sr / hop


class _Map:
    """The top-down map: static floor plan drawn once, path and robot per frame."""

    def __init__(self, plan: Any, events: list[dict[str, Any]], xy: np.ndarray) -> None:
        pts = [xy]
        pts += [np.array([e["source"][:2] for e in events])] if events else []
        if plan is not None:
            b = plan.bounds
            pts.append(np.array([[b.xmin, b.ymin], [b.xmax, b.ymax]]))
        allp = np.concatenate(pts)
        lo, hi = allp.min(axis=0) - 0.5, allp.max(axis=0) + 0.5
        self.scale = (PANEL - 8) / max(hi - lo)
        self.lo, self.hi = lo, hi
        img = Image.new("RGB", (PANEL, PANEL), (250, 250, 250))
        d = ImageDraw.Draw(img)
        if plan is not None:
            for r in plan.rooms:
                d.rectangle(self._box(r.rect.xmin, r.rect.ymin, r.rect.xmax, r.rect.ymax), fill=(236, 232, 222))
            for f in plan.furniture:
                fp = f.footprint
                d.rectangle(self._box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), fill=(190, 170, 140))
            for w in plan.walls:
                fp = w.footprint
                d.rectangle(self._box(fp.xmin, fp.ymin, fp.xmax, fp.ymax), fill=(40, 40, 40))
        for e in events:
            x, y = self._px(e["source"][:2])
            d.ellipse([x - 6, y - 6, x + 6, y + 6], fill=_SOURCE_COLOURS.get(e["category"], (0, 0, 0)), outline=(0, 0, 0))
        self.base = np.asarray(img)

    def _px(self, p: Any) -> tuple[float, float]:
        return 4 + (p[0] - self.lo[0]) * self.scale, PANEL - 4 - (p[1] - self.lo[1]) * self.scale

    def _box(self, x0: float, y0: float, x1: float, y1: float) -> list[float]:
        (a, b), (c, e) = self._px((x0, y1)), self._px((x1, y0))
        return [a, b, c, e]

    def frame(self, xy: np.ndarray, yaw: float) -> np.ndarray:
        img = Image.fromarray(self.base.copy())
        d = ImageDraw.Draw(img)
        path = [self._px(p) for p in xy]
        if len(path) > 1:
            d.line(path, fill=(20, 90, 200), width=2)
        x, y = path[-1]
        d.ellipse([x - 5, y - 5, x + 5, y + 5], fill=(20, 90, 200))
        d.line([x, y, x + 12 * np.cos(yaw), y - 12 * np.sin(yaw)], fill=(0, 0, 0), width=2)
        return np.asarray(img)


def _plan(manifest: dict[str, Any], scene_seed: int) -> Any:
    """The episode's apartment, regenerated from the recipe and its scene seed (None if impossible)."""
    try:
        from echo_data.recipe import Recipe
        from echo_data.scene.generate import generate_floorplan_from_seed

        return generate_floorplan_from_seed(Recipe.model_validate(manifest["recipe"]), int(scene_seed))
    except Exception:  # the map is still useful without walls
        return None


def render_episode_video(root: str | Path, index: int, out: str | Path, split: str = "train") -> dict[str, Any]:
    """Write the MP4 of episode `index` of `split`; return its summary (frames, seconds, path)."""
    import soundfile as sf

    from echo_data.media import write_mp4

    root, out = Path(root), Path(out)
    manifest = load_manifest(root)
    ep, rows = episode_rows(root, split, index)
    rgb_col, depth_col = IMAGE_COLUMNS["head_rgb"], IMAGE_COLUMNS["head_depth"]
    if not rows or rgb_col not in rows[0]:
        raise ViewError(f"{root}: {split} episode {index} has no {rgb_col} column to show")
    fps = int(manifest["layout"]["fps"])
    audio, sr = sf.read(root / ep["audio_path"], dtype="float32", always_2d=True)
    first = int(rows[0]["audio_offset"])
    hop = sr // fps
    track = audio[first : first + len(rows) * hop]
    track = np.pad(track, ((0, len(rows) * hop - len(track)), (0, 0)))
    spec, cols_per_s = _spectrogram_image(audio, sr)
    spec_rgb = colour_lut("magma")[spec]
    spec_w = 3 * PANEL
    px_per_s = spec_w / (SPEC_SECONDS + SPEC_AHEAD)
    turbo = colour_lut("turbo")
    state = np.array([r[STATE] for r in rows], dtype=np.float64)
    chain = ep["chain"]
    mapper = _Map(_plan(manifest, ep["scene_seed"]), ep["events"], state[:, :2])

    def frames() -> Any:
        for t, row in enumerate(rows):
            canvas = np.zeros((PANEL + SPEC_H + CAPTION_H, spec_w, 3), dtype=np.uint8)
            rgb = np.asarray(Image.open(io.BytesIO(row[rgb_col]["bytes"])).convert("RGB"))
            canvas[:PANEL, :PANEL] = _panel(rgb)
            if depth_col in row:
                depth = np.asarray(Image.open(io.BytesIO(row[depth_col]["bytes"]))).astype(np.float64) / 1000.0
                canvas[:PANEL, PANEL : 2 * PANEL] = _panel(turbo[np.clip(depth / DEPTH_RANGE_M * 255, 0, 255).astype(np.uint8)])
            canvas[:PANEL, 2 * PANEL :] = mapper.frame(state[: t + 1, :2], state[t, 2])
            # spectrogram columns around the step's sample, cursor at SPEC_SECONDS from the left
            now = int(row["audio_offset"]) / sr
            cols = np.round((now + (np.arange(spec_w) / px_per_s - SPEC_SECONDS)) * cols_per_s).astype(int)
            ok = (cols >= 0) & (cols < spec_rgb.shape[1])
            strip = np.zeros((spec_rgb.shape[0], spec_w, 3), dtype=np.uint8)
            strip[:, ok] = spec_rgb[:, cols[ok]]
            strip = fit_nearest(strip, spec_w, SPEC_H).copy()
            cursor = int(SPEC_SECONDS * px_per_s)
            strip[:, cursor : cursor + 2] = 255
            canvas[PANEL : PANEL + SPEC_H] = strip
            cap = Image.fromarray(canvas)
            k = int(row["skill_index"])
            target = chain[k]["target_kind"] if k < len(chain) else ""
            ImageDraw.Draw(cap).text(
                (8, PANEL + SPEC_H + 8),
                f"{ep['episode_id']}  t={row['timestamp']:.1f}s  skill {k + 1}/{len(chain)}: {row['skill']} {target}   (spectrogram: left ear above right)",
                fill=(255, 255, 255),
            )
            yield np.asarray(cap)

    write_mp4(out, frames(), fps, audio=track, sample_rate=sr)
    return {"path": str(out), "frames": len(rows), "seconds": len(rows) / fps, "episode_id": ep["episode_id"], "events": [e["category"] for e in ep["events"]]}
