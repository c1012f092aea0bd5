"""Spatial-cue benchmark: do the rendered ears say where the sound is?

Episodes are produced by the build's own per-episode steps (`sample_episode`, the scripted
experts, `render_episode_audio`, `step_features`) from a shipped recipe, for `--train` and
`--test` episode indices. Over Navigate steps with one sounding source 20°–160° off the nose:
(a) agreement of the sign of the ILD (500 Hz–8 kHz energy, the step's 100 ms of audio) and of
    the ITD (GCC-PHAT, ±1 ms) with the source's side, per sound category, split line of sight /
    behind a wall; behind a wall also against the side of the doorway the sound comes through
    (first doorway of the shortest doorway route from the robot's room to the source);
(b) level change (500 Hz–8 kHz, both ears) from the first to the last second of each Navigate;
(c) a left/right logistic-regression classifier trained on train-split step spectrograms
    (the stored SoundSpaces-style features; input: left minus right) and scored on test steps;
(d) the same numbers for a free-field render of the same episodes (direct sound only, same
    levels and noise floor): the physical ceiling of what a head can hear.

Usage:  python benchmarks/bench_spatial_cues.py [--recipe recipes/stmm_1_9k.yaml] [--train 16] [--test 8]
"""

from __future__ import annotations

import argparse
import heapq
import math
import os
import time
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.signal import butter, sosfiltfilt  # noqa: E402

from echo_data.acoustics.features import step_features  # noqa: E402
from echo_data.acoustics.hrtf import Hrtf  # noqa: E402
from echo_data.acoustics.levels import to_full_scale  # noqa: E402
from echo_data.acoustics.noise import NoiseFloor  # noqa: E402
from echo_data.acoustics.room import AcousticScene  # noqa: E402
from echo_data.acoustics.stream import SourceTrack, render_track  # noqa: E402
from echo_data.pipeline import PRE_ROLL_SECONDS, event_waveform, render_episode_audio, simulate, step_samples  # noqa: E402
from echo_data.recipe import load_recipe  # noqa: E402
from echo_data.records import EpisodeResult  # noqa: E402
from echo_data.scene.sampling import sample_episode  # noqa: E402
from echo_data.sounds.library import SoundLibrary  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TONAL = ("phone", "alarm", "doorbell", "furby")
MIN_OFF, MAX_OFF = math.radians(20.0), math.radians(160.0)


class FreeField:
    """A scene whose every response is the direct sound only (no walls, no room)."""

    def __init__(self, scene: AcousticScene) -> None:
        self._scene = scene
        self.plan = scene.plan

    def response(self, source, receiver):
        return self._scene.free_field(source, receiver)


def free_field_audio(spec, rollout, recipe, library) -> np.ndarray:
    """The episode track as `render_episode_audio` makes it, with a free-field scene."""
    cfg = recipe.acoustics
    fs, hop = cfg.sample_rate, step_samples(recipe)
    pre = int(round(PRE_ROLL_SECONDS * recipe.robot.control_hz))
    poses = np.array([[*s.ear_position, s.ear_yaw] for s in rollout.steps])
    poses = np.concatenate([np.repeat(poses[:1], pre, axis=0), poses])
    seconds = len(poses) * hop / fs + cfg.rir_seconds
    sources = []
    for e, ev in enumerate(spec.events):
        wave = event_waveform(spec, e, library, fs, seconds)
        stop = rollout.resolved_frame[e]
        sources.append(SourceTrack(tuple(ev.source), wave, None if stop is None else (stop + pre) * hop))
    hrtf = Hrtf.load(cfg.hrtf, fs)
    track = render_track(FreeField(AcousticScene(spec.plan, cfg)), sources, poses, hop, cfg, hrtf=hrtf).astype(np.float64)
    track += NoiseFloor(fs, cfg.noise_floor_dba, spec.plan.seed, hrtf).render(0, len(track))
    return to_full_scale(track, cfg.full_scale_db_spl)


def _band(x: np.ndarray, fs: int) -> np.ndarray:
    return sosfiltfilt(butter(4, [500.0, 0.45 * fs], btype="band", fs=fs, output="sos"), x, axis=0)


def ild_db(w: np.ndarray, fs: int) -> float:
    b = _band(w.astype(np.float64), fs)
    return float(10 * np.log10((b[:, 0] ** 2).sum() / max((b[:, 1] ** 2).sum(), 1e-30)))


def itd_s(w: np.ndarray, fs: int) -> float:
    """GCC-PHAT lag (s) within ±1 ms; > 0: the left ear leads."""
    n = 2 * len(w)
    L, R = np.fft.rfft(w[:, 0], n), np.fft.rfft(w[:, 1], n)
    cross = L * np.conj(R)
    cc = np.fft.irfft(cross / np.maximum(np.abs(cross), 1e-20), n)
    m = int(1e-3 * fs)
    cc = np.concatenate([cc[-m:], cc[: m + 1]])
    return float(-(int(np.argmax(cc)) - m) / fs)


def _seg_hits_box(a, b, lo, hi) -> bool:
    """Whether the 2-D segment a→b crosses the axis-aligned box [lo, hi] (slab test)."""
    d = b - a
    t0, t1 = 0.0, 1.0
    for k in range(2):
        if abs(d[k]) < 1e-12:
            if a[k] < lo[k] or a[k] > hi[k]:
                return False
            continue
        u0, u1 = sorted(((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]))
        t0, t1 = max(t0, u0), min(t1, u1)
        if t0 > t1:
            return False
    return True


def line_of_sight(plan, a, b) -> bool:
    """No wall between the head and the source (2-D, walls as their footprints)."""
    a, b = np.asarray(a[:2], float), np.asarray(b[:2], float)
    for w in plan.walls:
        fp = w.footprint
        if _seg_hits_box(a, b, (fp.xmin, fp.ymin), (fp.xmax, fp.ymax)):
            return False
    return True


def doorway_towards(plan, ear, src) -> np.ndarray | None:
    """Centre of the first doorway on the shortest route (through doorway centres) from the
    ear's room to the source's room."""
    ra, rb = plan.room_at(*ear[:2]), plan.room_at(*src[:2])
    if ra < 0 or rb < 0 or ra == rb:
        return None
    dws = [d for d in plan.doorways if -1 not in d.rooms]
    best: list[tuple[float, int, int]] = [(float(np.hypot(d.center[0] - ear[0], d.center[1] - ear[1])), i, i) for i, d in enumerate(dws) if ra in d.rooms]
    heapq.heapify(best)
    seen: set[int] = set()
    while best:
        dist, i, first = heapq.heappop(best)
        if i in seen:
            continue
        seen.add(i)
        d = dws[i]
        if rb in d.rooms:
            return np.asarray(dws[first].center)
        for j, e in enumerate(dws):
            if j not in seen and set(e.rooms) & set(d.rooms):
                heapq.heappush(best, (dist + float(np.hypot(e.center[0] - d.center[0], e.center[1] - d.center[1])), j, first))
    return None


def side(ear, yaw, point) -> tuple[int, float]:
    """(+1 left / -1 right, angle off the nose in rad) of a point seen from a head."""
    az = math.atan2(point[1] - ear[1], point[0] - ear[0]) - yaw
    az = math.atan2(math.sin(az), math.cos(az))
    return (1 if az > 0 else -1), abs(az)


def episode_rows(spec, result, audio: np.ndarray, fs: int, hop: int) -> list[dict]:
    """Per qualifying Navigate step: cues, truth, and where the source is."""
    rows = []
    steps, offsets = result.steps, result.audio_offsets
    for i, s in enumerate(steps):
        if s.skill != "Navigate" or sum(s.sounding) != 1:
            continue
        e = int(np.flatnonzero(s.sounding)[0])
        ev = spec.events[e]
        sgn, off = side(s.ear_position, s.ear_yaw, ev.source)
        if not (MIN_OFF <= off <= MAX_OFF):
            continue
        w = audio[offsets[i] : offsets[i] + hop].astype(np.float64)
        los = line_of_sight(spec.plan, s.ear_position, ev.source)
        door = None if los else doorway_towards(spec.plan, s.ear_position, ev.source)
        door_side = None
        if door is not None:
            ds, doff = side(s.ear_position, s.ear_yaw, door)
            door_side = ds if MIN_OFF <= doff <= MAX_OFF else None
        rows.append(
            dict(
                cat=ev.category,
                los=los,
                side=sgn,
                door_side=door_side,
                ild=ild_db(w, fs),
                itd=itd_s(w, fs),
                step=i,
                dist=float(np.linalg.norm(np.asarray(ev.source) - np.asarray(s.ear_position))),
            )
        )
    return rows


def level_rises(result, audio: np.ndarray, fs: int, hop: int, control_hz: int) -> list[float]:
    """dB rise (500 Hz–8 kHz, both ears) from the first to the last second of each Navigate
    run with a sounding source."""
    out = []
    steps, offsets = result.steps, result.audio_offsets
    i = 0
    while i < len(steps):
        if steps[i].skill != "Navigate" or not any(steps[i].sounding):
            i += 1
            continue
        j = i
        while j + 1 < len(steps) and steps[j + 1].skill == "Navigate" and any(steps[j + 1].sounding):
            j += 1
        if j - i + 1 >= 2 * control_hz:
            a = _band(audio[offsets[i] : offsets[i] + control_hz * hop].astype(np.float64), fs)
            b = _band(audio[offsets[j] + hop - control_hz * hop : offsets[j] + hop].astype(np.float64), fs)
            out.append(float(10 * np.log10((b**2).mean() / max((a**2).mean(), 1e-30))))
        i = j + 1
    return out


def agreement(rows: list[dict], key: str, truth: str) -> tuple[float, int]:
    r = [x for x in rows if x[truth] is not None and x[key] != 0]
    if not r:
        return float("nan"), 0
    return float(np.mean([np.sign(x[key]) == x[truth] for x in r])), len(r)


def classifier(train: list[tuple[np.ndarray, int]], test: list[tuple[np.ndarray, int]]) -> float:
    from sklearn.linear_model import LogisticRegression

    if not train or not test or len({y for _, y in train}) < 2:
        return float("nan")
    X = np.stack([x for x, _ in train])
    mu, sd = X.mean(axis=0), X.std(axis=0) + 1e-6
    clf = LogisticRegression(C=0.05, max_iter=2000).fit((X - mu) / sd, [y for _, y in train])
    Xt = np.stack([x for x, _ in test])
    return float(clf.score((Xt - mu) / sd, [y for _, y in test]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--recipe", default=str(ROOT / "recipes" / "stmm_1_9k.yaml"))
    ap.add_argument("--train", type=int, default=16)
    ap.add_argument("--test", type=int, default=8)
    args = ap.parse_args()
    recipe = load_recipe(args.recipe)
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    fs, hop = recipe.acoustics.sample_rate, step_samples(recipe)
    t0 = time.perf_counter()
    rows = {"room": [], "free": []}
    rises = {"room": [], "free": []}
    feats = {("room", "train"): [], ("room", "test"): [], ("free", "train"): [], ("free", "test"): []}
    n_ok = 0
    for split, n in (("train", args.train), ("test", args.test)):
        for idx in range(n):
            try:
                spec, _ = sample_episode(recipe, split, idx, library)
            except Exception as exc:  # noqa: BLE001 - a benchmark skips unsampleable indices
                print(f"skip {split} {idx}: {exc}")
                continue
            ro = simulate(spec, recipe, observe=False)
            if not ro.steps:
                continue
            n_ok += 1
            room, offsets = render_episode_audio(spec, ro, recipe, library)
            free = free_field_audio(spec, ro, recipe, library)
            for name, audio in (("room", room), ("free", free)):
                res = EpisodeResult(spec, ro.steps, ro.outcomes, ro.success, audio=audio, audio_offsets=offsets)
                r = episode_rows(spec, res, audio, fs, hop)
                rows[name] += r
                rises[name] += level_rises(res, audio, fs, hop, recipe.robot.control_hz)
                if r:
                    spec_feats, _ = step_features(audio, offsets[[x["step"] for x in r]], fs, 8)
                    diff = np.log1p(spec_feats[..., 0]) - np.log1p(spec_feats[..., 1])  # (k, 65, 26)
                    feats[(name, split)] += [(np.concatenate([d.mean(axis=1), d[:, -4:].ravel()]), x["side"]) for d, x in zip(diff, r)]
            print(f"{split} {idx}: {len(ro.steps)} steps, {time.perf_counter() - t0:.0f} s", flush=True)

    print(f"\n{n_ok} episodes of {Path(args.recipe).name} ({args.train} train + {args.test} test indices)\n")
    print("| | room (ours) | free field (ceiling) | goal |")
    print("|---|---|---|---|")

    def line(label: str, fn, goal: str) -> None:
        vals = []
        for name in ("room", "free"):
            v, k = fn(name)
            vals.append("n/a" if not k else f"{v:.2f} (n={k})")
        print(f"| {label} | {vals[0]} | {vals[1]} | {goal} |")

    for cue, key in (("ILD", "ild"), ("ITD", "itd")):
        line(f"{cue} sign = source side, line of sight", lambda nm, key=key: agreement([x for x in rows[nm] if x["los"]], key, "side"), "≥ 0.85")
        line(f"{cue} sign = source side, line of sight, within 1.2 m", lambda nm, key=key: agreement([x for x in rows[nm] if x["los"] and x["dist"] <= 1.2], key, "side"), "")
        line(f"{cue} sign = source side, behind a wall", lambda nm, key=key: agreement([x for x in rows[nm] if not x["los"]], key, "side"), "")
        line(f"{cue} sign = doorway side, behind a wall", lambda nm, key=key: agreement([x for x in rows[nm] if not x["los"]], key, "door_side"), "≥ 0.75")
    for cat in sorted({x["cat"] for x in rows["room"]}):
        kind = "tonal" if cat in TONAL else "broadband"
        for cue, key in (("ILD", "ild"), ("ITD", "itd")):
            line(f"{cue}, {cat} ({kind}), line of sight", lambda nm, key=key, cat=cat: agreement([x for x in rows[nm] if x["los"] and x["cat"] == cat], key, "side"), "")
    line("median level rise over Navigate (dB)", lambda nm: (float(np.median(rises[nm])) if rises[nm] else float("nan"), len(rises[nm])), "≥ 8")
    line("left/right classifier on test spectrograms", lambda nm: (classifier(feats[(nm, "train")], feats[(nm, "test")]), len(feats[(nm, "test")])), "≥ 0.85")
    d = np.asarray([x["dist"] for x in rows["room"] if x["los"]])
    if len(d):
        print(f"\nline-of-sight steps: median distance to the source {np.median(d):.2f} m, {np.mean(d <= 1.2):.0%} within 1.2 m")
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
