"""`echo-data view`: one stored episode as an MP4 to watch and listen to.

Each video frame is one control step: head RGB, head depth, wrist depth, a top-down map (walls,
furniture, the sound sources, drawn silenced once their event is resolved and at the robot while
it carries them, the robot's path so far and its heading), the binaural spectrogram
scrolling past a cursor at the step, and the active skill as a caption. The sound track is the
episode's binaural WAV from the first step on, so picture and sound stay in step (frame t is at
t / fps seconds, the sample at `audio_offset` of step t), raised by the playback gain of
`echo_data.viz.listening` that the frame states (the WAV itself stays calibrated). The frames are `echo_data.viz.frames`'
(shared with `evaluate --video`); encoding is `echo_data.media.write_mp4`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from echo_data.camera import DEPTH_UNIT_M
from echo_data.dataset.encode import decode_png
from echo_data.dataset.reader import EpisodeError, episode_audio, episode_rows, read_manifest
from echo_data.dataset.schema import IMAGE_COLUMNS, STATE
from echo_data.records import STATE_NAMES
from echo_data.viz.frames import PANEL, EpisodeFrames
from echo_data.viz.listening import listening
from echo_data.viz.topdown import TopDownMap, episode_plan

HAND_AHEAD_M = 0.35  # a carried object is drawn this far ahead of the base centre (the gripper is in front)


# Bad input for `view` (no such episode, no images): exit 2, nothing written. The reader's own.
ViewError = EpisodeError


def render_episode_video(root: str | Path, index: int, out: str | Path, split: str = "train") -> dict[str, Any]:
    """Write the MP4 of episode `index` of `split`; return its summary (frames, seconds, path)."""
    from echo_data.media import write_mp4

    root, out = Path(root), Path(out)
    manifest = read_manifest(root)
    ep, rows = episode_rows(root, split, index)
    rgb_col, depth_col, wrist_col = IMAGE_COLUMNS["head_rgb"], IMAGE_COLUMNS["head_depth"], IMAGE_COLUMNS["wrist_depth"]
    if not rows or rgb_col not in rows[0]:
        raise ViewError(f"{root}: {split} episode {index} has no {rgb_col} column to show")
    fps = int(manifest["layout"]["fps"])
    audio, sr = episode_audio(root, ep)
    first = int(rows[0]["audio_offset"])
    hop = sr // fps
    track = audio[first : first + len(rows) * hop]
    track = np.pad(track, ((0, len(rows) * hop - len(track)), (0, 0)))
    state = np.array([r[STATE] for r in rows], dtype=np.float64)
    chain = ep["chain"]
    flags = np.array([r["skill_success"] for r in rows], dtype=bool)
    sounding, carried = source_states(chain, len(ep["events"]), flags, state[:, STATE_NAMES.index("holding")] > 0.5)
    topdown = TopDownMap(episode_plan(manifest, ep["scene_seed"]), ep["events"], size=PANEL, extent=[tuple(p) for p in state[:, :2]])
    level = listening(track, float(manifest["audio"]["full_scale_db_spl"]))
    video = EpisodeFrames(topdown, audio, sr, sound_note=level.note())

    hand = HAND_AHEAD_M * np.c_[np.cos(state[:, 2]), np.sin(state[:, 2])] + state[:, :2]  # where a carried object is drawn

    def frames() -> Any:
        moved: dict[int, tuple[float, float]] = {}  # an object stays where the hand left it
        for t, row in enumerate(rows):
            rgb = decode_png(row[rgb_col], rgb=True)
            depth, wrist = (_depth_m(row, col) for col in (depth_col, wrist_col))
            k = int(row["skill_index"])
            target = chain[k]["target_kind"] if k < len(chain) else ""
            caption = f"{ep['episode_id']}  t={row['timestamp']:.1f}s  skill {k + 1}/{len(chain)}: {row['skill']} {target}"
            moved.update({e: (float(hand[t, 0]), float(hand[t, 1])) for e in carried[t]})
            yield video.frame(rgb, depth, [tuple(p) for p in state[: t + 1, :2]], state[t, 2], int(row["audio_offset"]), caption,
                              sounding=sounding[t], wrist_depth_m=wrist, moved=dict(moved))

    write_mp4(out, frames(), fps, audio=level.apply(track), sample_rate=sr)
    return {
        "path": str(out),
        "frames": len(rows),
        "seconds": len(rows) / fps,
        "episode_id": ep["episode_id"],
        "events": [e["category"] for e in ep["events"]],
        "gain_db": level.gain_db,
        "listening": f"played {level.gain_db:+.0f} dB; stored peak {level.peak_dbfs:.1f} dBFS, RMS {level.rms_dbfs:.1f} dBFS",
    }


def source_states(
    chain: list[dict[str, Any]], n_events: int, flags: np.ndarray, holding: np.ndarray
) -> tuple[list[list[bool]], list[list[int]]]:
    """Per step: which events still sound, and which events' objects the robot carries.

    An event falls silent once the success test of the chain slot that resolves it holds (the
    environment's rule, `EchoDataEnv._update_events`): from the step after the row whose
    `skill_success` flag of that slot is set, as the env silences it after that step's action.
    An event's object is in the hand from the step after its Pick slot succeeded while the state's
    `holding` is set (a Place ends it)."""
    from echo_data.skill_table import SKILLS

    resolver = {int(c["event"]): k for k, c in enumerate(chain) if c["skill"] in SKILLS and SKILLS[c["skill"]].resolves_event}
    picks = {int(c["event"]): k for k, c in enumerate(chain) if c["skill"] in SKILLS and SKILLS[c["skill"]].lifts}
    before = np.vstack([np.zeros((1, flags.shape[1]), bool), flags[:-1]]) if len(flags) else flags  # flags as they stood when step t was observed
    sounding = [[not (e in resolver and bool(before[t, resolver[e]])) for e in range(n_events)] for t in range(len(flags))]
    carried = [[e for e, k in picks.items() if bool(before[t, k]) and bool(holding[t])] for t in range(len(flags))]
    return sounding, carried


def _depth_m(row: dict[str, Any], col: str) -> np.ndarray | None:
    """A stored depth image (16-bit PNG of millimetres) in metres, None where not stored."""
    if col not in row:
        return None
    return decode_png(row[col]).astype(np.float64) * DEPTH_UNIT_M
