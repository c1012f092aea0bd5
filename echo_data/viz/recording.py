"""`echo-data view --rerun`: one stored episode as a Rerun recording (.rrd) to scrub through.

What the MP4 shows as a fixed layout, the recording offers per entity on the timelines `step`
(control step) and `time` (the step's timestamp): head RGB and head / wrist depth on their
pinhole cameras at the stored camera poses (`world/head`, `world/wrist`), the world point cloud
each depth image lifts to (`echo_data.camera.depth_to_world`: the same lift a user of the
dataset does, so a wrong pose shows as a smeared room), the robot's path and the sources in
the world and on the top-down plan (`plan/*`, over the one map of `echo_data.viz.topdown`),
the stored spectrogram observation, every state and action dimension as a time series and
the active skill as a text log. Rerun has no audio type: the sound stays in the MP4.
The file is written under a temporary name and renamed, so a failed run leaves no .rrd.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.viz import palette

MAX_POINTS = 1024  # per camera and step in the world point cloud (depth subsampled on a grid)
PLAN_PX_PER_M = 60.0


class RecordingTargetError(ValueError):
    """A --rerun target that cannot be written (wrong suffix, a folder, nowhere writable): exit 2."""


def check_rerun_target(target: Path) -> None:
    """Refuse a target that is not a writable `.rrd` file path, before anything is read (the
    folder and writability checks are `targets.check_file`'s, raising its `TargetError`)."""
    from echo_data.targets import check_file

    if target.suffix != ".rrd":
        raise RecordingTargetError(f"--rerun {target}: must end in .rrd (the file `rerun` opens)")
    check_file(target, "--rerun")


def _grid_step(h: int, w: int) -> int:
    return max(1, math.ceil(math.sqrt(h * w / MAX_POINTS)))


def write_recording(root: Path, index: int, target: Path, split: str = "train") -> dict[str, Any]:
    """Write episode `index` of `split` to `target` (.rrd); return its entities and step range."""

    import rerun as rr

    from echo_data.camera import depth_to_world
    from echo_data.dataset.encode import decode_png
    from echo_data.dataset.reader import EpisodeError, episode_rows, read_manifest
    from echo_data.dataset.schema import ACTION, CAMERA_POSES, IMAGE_COLUMNS, SPECTROGRAM, STATE
    from echo_data.records import ACTION_NAMES, STATE_NAMES
    from echo_data.viz.topdown import TopDownMap, episode_plan

    root, target = Path(root), Path(target)
    check_rerun_target(target)
    manifest = read_manifest(root)
    ep, rows = episode_rows(root, split, index)
    if not rows:
        raise EpisodeError(f"{root}: {split} episode {index} has no steps")
    cameras = _info_cameras(root)
    steps = np.arange(len(rows))
    seconds = np.array([r["timestamp"] for r in rows], dtype=np.float64)
    state = np.array([r[STATE] for r in rows], dtype=np.float64)
    action = np.array([r[ACTION] for r in rows], dtype=np.float64)

    rec = rr.RecordingStream("echo-data", recording_id=ep["episode_id"])
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    target.parent.mkdir(parents=True, exist_ok=True)
    # Not rec.save(path): Rerun's file sink logs a failed write (a full disk) and carries on, so
    # a truncated .rrd would be reported as written. The recording is encoded in memory (one
    # episode: tens of MB) and written here, where a failed write raises OSError (one line, exit
    # 2, no file left). Read once: each read of a binary stream starts a new stream header, and
    # Rerun's loader reads only the first of several concatenated streams (measured, rerun 0.23).
    sink = tmp.open("wb")
    try:
        stream = rr.binary_stream(recording=rec)
        rr.send_blueprint(_blueprint(cameras), make_active=False, make_default=True, recording=rec)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log("episode", rr.TextDocument(_describe(ep)), static=True)
        index_cols = [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("time", duration=seconds)]
        for group, names, values in (("state", STATE_NAMES, state), ("action", ACTION_NAMES, action)):
            for j, name in enumerate(names):
                rec.send_columns(f"{group}/{name}", indexes=index_cols, columns=rr.Scalars.columns(scalars=values[:, j]))
        _log_sources(rec, ep)
        topdown = TopDownMap(episode_plan(manifest, ep["scene_seed"]), ep["events"], px_per_m=PLAN_PX_PER_M, labels=True, extent=[tuple(p) for p in state[:, :2]])
        rec.log("plan/map", rr.Image(np.asarray(topdown.draw())), static=True)
        for cam, info in cameras.items():
            rec.log(f"world/{cam}", rr.Pinhole(image_from_camera=np.asarray(info["K"]), resolution=[info["width"], info["height"]], camera_xyz=rr.ViewCoordinates.RDF), static=True)
        chain = ep["chain"]
        last_skill = -1
        for t, row in enumerate(rows):
            rec.set_time("step", sequence=t)
            rec.set_time("time", duration=float(seconds[t]))
            k = int(row["skill_index"])
            if k != last_skill:
                target_kind = chain[k]["target_kind"] if k < len(chain) else ""
                rec.log("skill", rr.TextLog(f"skill {k + 1}/{len(chain)}: {row['skill']} {target_kind}", level=rr.TextLogLevel.INFO))
                last_skill = k
            path_px = [topdown.px(x, y) for x, y in state[: t + 1, :2]]
            rec.log("plan/path", rr.LineStrips2D([path_px], colors=[palette.ROBOT]))
            x, y, yaw = state[t, :3]
            rec.log("plan/robot", rr.Points2D([path_px[-1]], colors=[palette.ROBOT], radii=4.0), rr.Arrows2D(origins=[path_px[-1]], vectors=[(30 * math.cos(yaw), -30 * math.sin(yaw))], colors=[(0, 0, 0)]))
            rec.log("world/path", rr.LineStrips3D([np.c_[state[: t + 1, :2], np.zeros(t + 1)]], colors=[palette.ROBOT]))
            if SPECTROGRAM in row:
                rec.log("audio/spectrogram", rr.Tensor(np.asarray(row[SPECTROGRAM], dtype=np.float32), dim_names=["frequency", "frame", "ear"]))
            rgb = None
            for cam, info in cameras.items():
                pose = np.asarray(row[CAMERA_POSES[cam]], dtype=np.float64).reshape(4, 4)
                rec.log(f"world/{cam}", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
                rgb_col = IMAGE_COLUMNS.get(f"{cam}_rgb")
                if rgb_col in row:
                    rec.log(f"world/{cam}/rgb", rr.EncodedImage(contents=row[rgb_col]["bytes"], media_type="image/png"))
                    rgb = decode_png(row[rgb_col], rgb=True) if cam == "head" else None
                depth_col = IMAGE_COLUMNS.get(f"{cam}_depth")
                if depth_col not in row:
                    continue
                depth = decode_png(row[depth_col])
                rec.log(f"world/{cam}/depth", rr.DepthImage(depth, meter=1.0 / float(info["depth_unit_m"]), colormap="turbo"))
                g = _grid_step(*depth.shape)
                pts = depth_to_world(depth, np.asarray(info["K"]), pose, float(info["depth_unit_m"]))[::g, ::g]
                ok = np.isfinite(pts[..., 0])
                colours = rgb[::g, ::g][ok] if cam == "head" and rgb is not None and rgb.shape[:2] == depth.shape else None
                rec.log(f"world/points/{cam}", rr.Points3D(pts[ok], colors=colours, radii=0.01))
        rec.flush(blocking=True)
        sink.write(stream.read() or b"")
        rec.disconnect()
        sink.close()
        os.replace(tmp, target)
    finally:
        sink.close()
        if tmp.exists():
            tmp.unlink()
    return {"path": str(target), "steps": len(rows), "episode_id": ep["episode_id"], "cameras": sorted(cameras)}


def _info_cameras(root: Path) -> dict[str, Any]:
    """The cameras' intrinsics, depth unit and pose column from meta/info.json."""
    import json

    return dict(json.loads((root / "meta" / "info.json").read_text()).get("cameras", {}))


def _log_sources(rec: Any, ep: dict[str, Any]) -> None:
    """The episode's sound sources in the world (static), labelled by category."""
    import rerun as rr

    from echo_data.viz.topdown import event_fields

    found = [(c, s) for c, s in (event_fields(e) for e in ep["events"]) if s is not None]
    if found:
        rec.log("world/sources", rr.Points3D([s for _, s in found], colors=[palette.source(c) for c, _ in found], labels=[c for c, _ in found], radii=0.08), static=True)


def _describe(ep: dict[str, Any]) -> str:
    chain = " -> ".join(f"{c['skill']} {c.get('target_kind', '')}".strip() for c in ep["chain"])
    sources = ", ".join(e["category"] for e in ep["events"])
    return f"# {ep['episode_id']}\n\nsplit {ep['split']}, {ep['n_steps']} steps; sources: {sources}\n\nskills: {chain}"


def _blueprint(cameras: dict[str, Any]) -> Any:
    """The opening layout: 3-D world, camera images, plan, spectrogram, time series, skill log."""
    import rerun.blueprint as rrb

    images = [rrb.Spatial2DView(origin=f"world/{cam}", name=f"{cam} camera") for cam in cameras]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(rrb.Spatial3DView(origin="world", name="world (point clouds from depth + camera poses)"), rrb.Horizontal(*images, rrb.Spatial2DView(origin="plan", name="top-down plan"))),
            rrb.Vertical(
                rrb.TensorView(origin="audio/spectrogram", name="spectrogram (stored observation)"),
                rrb.TimeSeriesView(origin="state", name="state"),
                rrb.TimeSeriesView(origin="action", name="action"),
                rrb.Horizontal(rrb.TextLogView(origin="skill", name="active skill"), rrb.TextDocumentView(origin="episode", name="episode")),
            ),
        ),
        collapse_panels=True,
    )
