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

Next to these plain numbers (never instead of them), what a listener in a reverberant room can
use (`binaural_cues.py`): ILD/ITD selected by interaural coherence (Faller & Merimaa 2004) and
weighted by onsets (precedence effect), over the step's 100 ms and over the second up to its
end, their parameters chosen on the train split's line-of-sight steps and scored on test steps;
a mirror-symmetric left/right classifier on explicit per-band ILD features of the stored
log-mel, its features and C chosen on a validation part of the train split (test is never
used for a choice); every line-of-sight figure split at the critical distance of the source's
room, and what a diffuse-field model predicts for the plain ILD. The table is printed and
written as JSON (`--out`, default studies/spatial_cues/results/spatial_cues.json).

Usage:  python studies/spatial_cues/bench_spatial_cues.py [--recipe recipes/stmm_1_9k.yaml] [--train 20] [--test 10] [--out FILE]
"""

from __future__ import annotations

import argparse
import heapq
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.signal import butter, sosfiltfilt  # noqa: E402
from scipy.stats import norm  # noqa: E402

from echo_data.acoustics.features import step_features  # noqa: E402
from echo_data.acoustics.hrtf import Hrtf  # noqa: E402
from echo_data.acoustics.levels import to_full_scale  # noqa: E402
from echo_data.acoustics.noise import NoiseFloor  # noqa: E402
from echo_data.acoustics.room import AcousticScene  # noqa: E402
from echo_data.acoustics.stream import SourceTrack, render_track  # noqa: E402
from echo_data.acoustics.types import BAND_CENTERS  # noqa: E402
from echo_data.app.pipeline import PRE_ROLL_SECONDS, event_waveform, render_episode_audio, simulate, step_samples  # noqa: E402
from echo_data.recipe import load_recipe  # noqa: E402
from echo_data.records import EpisodeResult  # noqa: E402
from echo_data.scene.sampling import sample_episode  # noqa: E402
from echo_data.sounds.library import SoundLibrary  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import binaural_cues as bc  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TONAL = ("phone", "alarm", "doorbell", "furby")
MIN_OFF, MAX_OFF = math.radians(20.0), math.radians(160.0)
# Tiled estimators (binaural_cues): 20 ERB-spaced gammatone bands; the candidate parameters,
# one of each chosen on the train split's line-of-sight steps (never on test).
BC_CENTRES = bc.erb_space(300.0, 7000.0, 20)
COH_C0 = (0.9, 0.95, 0.98, 0.99)  # Faller & Merimaa show selections with c0 of 0.95-0.99
ONSET_RISE_DB = (1.0, 3.0, 6.0)
ILD_BANDS = ((500.0, 8000.0), (1500.0, 8000.0))  # all bands / where the head shadow is large
ITD_BANDS = ((300.0, 1500.0), (300.0, 8000.0))  # fine-structure bands / plus envelope ITD


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


def critical_distance(scene: AcousticScene, point) -> float:
    """Critical distance (m) of the room holding `point`, 500 Hz-1 kHz: where the direct energy
    1/r^2 equals the steady diffuse energy 16 pi (1 - alpha) / A of an omnidirectional source
    (Kuttruff, Room Acoustics, 5th ed., eq. 5.42 with Eyring's A; ~ 0.057 sqrt(V / T60))."""
    ac = scene.acoustics
    a = scene.room_of(tuple(float(v) for v in point))
    mid = [k for k, f in enumerate(BAND_CENTERS) if 500.0 <= f <= 1000.0]
    r2 = ac.eq_area[a, mid] / (16.0 * math.pi * (1.0 - ac.mean_alpha[a, mid]))
    return float(np.sqrt(r2.mean()))


def episode_rows(spec, result, audio: np.ndarray, fs: int, hop: int, scene: AcousticScene | None = None) -> list[dict]:
    """Per qualifying Navigate step: cues, truth, where the source is, and the tiled cues of
    `binaural_cues` for every parameter choice (the 100 ms of the step and the second up to its end)."""
    rows = []
    steps, offsets = result.steps, result.audio_offsets
    cands = [(i, s) for i, s in enumerate(steps) if s.skill == "Navigate" and sum(s.sounding) == 1]
    if not cands:
        return rows
    t = bc.tiles(audio, fs, BC_CENTRES)
    flen = int(bc.FRAME_S * fs)
    for i, s in cands:
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
        end = offsets[i] + hop
        tiled = {}
        for win, lo in (("100ms", offsets[i]), ("1s", end - fs)):
            sel = (t.starts >= lo) & (t.starts + flen <= end)
            tiled[win] = tile_estimates(bc.Tiles(t.centres, t.ild_db[:, sel], t.itd_s[:, sel], t.ic[:, sel], t.energy[:, sel], t.starts[sel]))
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
                rc=critical_distance(scene, ev.source) if scene is not None else float("nan"),
                tiled=tiled,
            )
        )
    return rows


def tile_estimates(t: bc.Tiles) -> dict[tuple, float]:
    """Every candidate parameter choice's ILD and ITD estimate of one window (chosen later on train)."""
    out: dict[tuple, float] = {}
    for c0 in COH_C0:
        for band in ILD_BANDS:
            out[("coh", "ild", c0, band)] = bc.coherence_selected(t, c0, band, band)[0]
        for band in ITD_BANDS:
            out[("coh", "itd", c0, band)] = bc.coherence_selected(t, c0, band, band)[1]
    for rise in ONSET_RISE_DB:
        for band in ILD_BANDS:
            out[("onset", "ild", rise, band)] = bc.onset_weighted(t, band, band, rise)[0]
        for band in ITD_BANDS:
            out[("onset", "itd", rise, band)] = bc.onset_weighted(t, band, band, rise)[1]
    return out


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


def agreement(rows: list[dict], key, truth: str) -> tuple[float, int]:
    """Share of rows whose cue sign equals `truth` (+1 left / -1 right); `key` is a row field or
    a (window, estimator key) into the row's tiled estimates. Rows with a zero cue or no truth
    are left out."""

    def val(x: dict) -> float:
        return x[key] if isinstance(key, str) else x["tiled"][key[0]][key[1]]

    r = [x for x in rows if x[truth] is not None and val(x) != 0]
    if not r:
        return float("nan"), 0
    return float(np.mean([np.sign(val(x)) == x[truth] for x in r])), len(r)


def choose(rows: list[dict], estimator: str, cue: str, window: str) -> tuple:
    """The candidate parameters of one tiled estimator with the best line-of-sight agreement on `rows` (train)."""
    keys = [k for k in rows[0]["tiled"][window] if k[0] == estimator and k[1] == cue] if rows else []
    los = [x for x in rows if x["los"]]
    return max(keys, key=lambda k: (agreement(los, (window, k), "side")[0], -keys.index(k)))


def diffuse_model(room: list[dict], free: list[dict], far: float = 3.0, sigma: float | None = None) -> tuple[float, float, int]:
    """Agreement a diffuse-field model predicts for the plain ILD, and the spread it uses.

    Per step the direct sound's ear energies are the free-field render's (same path, same
    levels); a diffuse field adds the same expected energy to each ear, mean direct energy x
    (d / r_c)^2 (the definition of the critical distance), so the expected ILD shrinks to
    ILD_pred; the diffuse field's own ILD scatters about that with the spread sigma measured on
    the room render's steps beyond `far` x r_c (direct sound >= 9.5 dB below the diffuse field).
    Predicted agreement = mean of Phi(|ILD_pred| / sigma) with the direct sound's sign.
    Returns (predicted agreement, sigma dB, n far steps); a given `sigma` is used as is."""
    far_ild = [x["ild"] for x in room if x["dist"] > far * x["rc"]]
    if sigma is None:
        if len(far_ild) < 10:
            return float("nan"), float("nan"), len(far_ild)
        sigma = float(np.sqrt(np.mean(np.square(far_ild))))
    p = []
    for r, f in zip(room, free):
        g = 10 ** (f["ild"] / 10.0)  # direct energies L = g R; their mean is (1 + g) / 2 R
        diffuse = (1 + g) / 2 * (r["dist"] / r["rc"]) ** 2
        pred = 10 * np.log10((g + diffuse) / (1 + diffuse))
        p.append(norm.cdf(abs(pred) / sigma) if np.sign(f["ild"]) == r["side"] else norm.cdf(-abs(pred) / sigma))
    return float(np.mean(p)), sigma, len(far_ild)


MEL_ILD_CLIP_DB = 30.0
MEL_LOW_BAND = 8  # log-mel bands from here up (above ~300 Hz at 64 bands, 16 kHz)
BAND_GROUPS = 8


def _weighted_ild(ild: np.ndarray, w: np.ndarray) -> float:
    return float((ild * w).sum() / max(float(w.sum()), 1e-30))


def classifier_features(spec: np.ndarray, mel: np.ndarray, kind: str) -> np.ndarray:
    """Left/right features of one step's stored features (the second before the step), all
    odd under swapping the ears (so a mirrored step has the negated features).

    "spec": the SoundSpaces spectrogram's left minus right log1p magnitude (mean over the
    second and its last 4 frames), as before. From the log-mel's per-band ILD (dB, left minus
    right, clipped to +-30 dB), over all bands above ~300 Hz and over 8 groups of adjacent
    bands: "onset3" / "onset6": weighted by each frame's level rise above 3 / 6 dB times its
    power (the precedence effect: onsets carry the direct sound); "cues": both onset kinds
    plus the power-weighted ILD of the second and of its last 100 ms; "spec+cues": both."""
    d = np.log1p(spec[..., 0]) - np.log1p(spec[..., 1])
    old = np.concatenate([d.mean(axis=1), d[:, -4:].ravel()])
    if kind == "spec":
        return old
    ild = np.clip(mel[MEL_LOW_BAND:, :, 0] - mel[MEL_LOW_BAND:, :, 1], -MEL_ILD_CLIP_DB, MEL_ILD_CLIP_DB)  # (bands, frames)
    lev = 0.5 * (mel[MEL_LOW_BAND:, :, 0] + mel[MEL_LOW_BAND:, :, 1])
    power = 10 ** ((lev - lev.max()) / 10)
    rise = np.zeros_like(lev)
    rise[:, 1:] = np.diff(lev, axis=1)
    weights = {f"onset{t}": np.maximum(rise - t, 0.0) * power for t in (3, 6)}
    weights["energy"] = power
    last = np.zeros_like(power)
    last[:, -10:] = power[:, -10:]
    weights["last"] = last
    use = {"onset3": ("onset3",), "onset6": ("onset6",)}.get(kind, ("onset3", "onset6", "energy", "last"))
    groups = [np.arange(len(ild))] + np.array_split(np.arange(len(ild)), BAND_GROUPS)
    feats = np.array([_weighted_ild(ild[g], weights[u][g]) for u in use for g in groups])
    return np.concatenate([old, feats]) if kind == "spec+cues" else feats


CLF_KINDS = ("spec", "onset3", "onset6", "cues", "spec+cues")
CLF_C = (0.01, 0.1, 1.0)


def _fit(X: np.ndarray, y: np.ndarray, c: float, symmetric: bool):
    """Logistic regression on standardised features. `symmetric`: the left/right task is
    mirror-symmetric, so fit without intercept on the data plus its mirror (features negated,
    label flipped), scaling each feature by its RMS (an odd classifier: f(-x) = -f(x))."""
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    if not symmetric:
        return make_pipeline(StandardScaler(), LogisticRegression(C=c, max_iter=3000)).fit(X, y)
    scale = StandardScaler(with_mean=False).fit(np.concatenate([X, -X]))
    clf = LogisticRegression(C=c, max_iter=3000, fit_intercept=False)
    return make_pipeline(scale, clf.fit(scale.transform(np.concatenate([X, -X])), np.concatenate([y, -y])))


def classifier(train: list[dict], test: list[dict], kind: str = "spec", c: float = 0.05, symmetric: bool = False) -> float:
    """Test accuracy of a logistic regression on `kind` features fitted on `train`
    (items: features per kind "x", label "y")."""
    if not train or not test or len({t["y"] for t in train}) < 2:
        return float("nan")
    clf = _fit(np.stack([t["x"][kind] for t in train]), np.array([t["y"] for t in train]), c, symmetric)
    return float(clf.score(np.stack([t["x"][kind] for t in test]), np.array([t["y"] for t in test])))


def choose_classifier(train: list[dict], val_share: float = 0.25) -> tuple[str, float, float]:
    """(features, C, validation accuracy) of the mirror-symmetric classifier: the best choice
    on the train split's last `val_share` of episodes (held out whole, so no episode is on both
    sides), fitted on the rest."""
    eps = sorted({t["ep"] for t in train})
    cut = set(eps[int(round(len(eps) * (1 - val_share))) :])
    fit, val = [t for t in train if t["ep"] not in cut], [t for t in train if t["ep"] in cut]
    scores = {(k, c): classifier(fit, val, k, c, symmetric=True) for k in CLF_KINDS for c in CLF_C}
    (k, c), v = max(scores.items(), key=lambda kv: -1 if np.isnan(kv[1]) else kv[1])
    return k, c, v


def add_episode(data: dict, split: str, idx: int, spec, ro, room: np.ndarray, free: np.ndarray, offsets: np.ndarray, recipe) -> None:
    """Rows, level rises and classifier features of one episode's two renders into `data`."""
    fs, hop = recipe.acoustics.sample_rate, step_samples(recipe)
    scene = AcousticScene(spec.plan, recipe.acoustics)
    noise = noise_level_db(spec, recipe)
    pairs: list[list[dict]] = []
    for name, audio in (("room", room), ("free", free)):
        res = EpisodeResult(spec, ro.steps, ro.outcomes, ro.success, audio=audio, audio_offsets=offsets)
        d = data[name][split]
        r = episode_rows(spec, res, audio, fs, hop, scene)
        for x in r:
            x["ep"] = idx
        pairs.append(r)
        d["rows"] += r
        d["rises"] += level_rises(res, audio, fs, hop, recipe.robot.control_hz)
        if r:
            sp_f, mel_f = step_features(audio, offsets[[x["step"] for x in r]], fs, recipe.acoustics.mel_bands)
            d["feats"] += [dict(ep=idx, y=x["side"], los=x["los"], door=x["door_side"], x={k: classifier_features(a, b, k) for k in CLF_KINDS}) for a, b, x in zip(sp_f, mel_f, r)]
    # the same steps in both renders: the source is audible in a step's 100 ms where its direct
    # sound alone (the free-field render) stands >= AUDIBLE_DB above the noise floor
    for x, f in zip(*pairs):
        level = 10 * np.log10(max(float((_band(free[offsets[f["step"]] : offsets[f["step"]] + hop].astype(np.float64), fs) ** 2).mean()), 1e-30))
        x["audible"] = f["audible"] = level >= noise + AUDIBLE_DB


AUDIBLE_DB = 6.0


def noise_level_db(spec, recipe) -> float:
    """Band (500 Hz-8 kHz) level in dB re full scale of the episode's noise floor alone."""
    cfg = recipe.acoustics
    fs = cfg.sample_rate
    bed = NoiseFloor(fs, cfg.noise_floor_dba, spec.plan.seed, Hrtf.load(cfg.hrtf, fs)).render(0, fs)
    return float(10 * np.log10(max(float((_band(to_full_scale(bed, cfg.full_scale_db_spl), fs) ** 2).mean()), 1e-30)))


def empty_data() -> dict:
    return {nm: {sp: {"rows": [], "rises": [], "feats": []} for sp in ("train", "test")} for nm in ("room", "free")}


def render_episodes(args, recipe, library) -> tuple[dict, int]:
    """Render every episode's room and free-field audio and extract rows, level rises and
    classifier features, per render and split."""
    t0 = time.perf_counter()
    data = empty_data()
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
            add_episode(data, split, idx, spec, ro, room, free_field_audio(spec, ro, recipe, library), offsets, recipe)
            print(f"{split} {idx}: {len(ro.steps)} steps, {time.perf_counter() - t0:.0f} s", flush=True)
    return data, n_ok


def report(data: dict, header: dict) -> dict:
    """The benchmark's table (list of rows: metric, room, free, goal) plus the chosen parameters."""
    table: list[dict] = []

    def cell(v: float, k: int) -> dict:
        return {"value": None if not k or np.isnan(v) else round(float(v), 3), "n": int(k)}

    def add(metric: str, fn, goal: str = "", split: str = "train+test") -> None:
        table.append(dict(metric=metric, split=split, room=cell(*fn("room")), free=cell(*fn("free")), goal=goal))

    def rows(nm: str, split: str = "all") -> list[dict]:
        return data[nm]["train"]["rows"] + data[nm]["test"]["rows"] if split == "all" else data[nm][split]["rows"]

    def sub(rs: list[dict], where: str) -> list[dict]:
        return {
            "los": [x for x in rs if x["los"]],
            "los_near": [x for x in rs if x["los"] and x["dist"] <= x["rc"]],
            "los_far": [x for x in rs if x["los"] and x["dist"] > x["rc"]],
            "los_1.2": [x for x in rs if x["los"] and x["dist"] <= 1.2],
            "wall": [x for x in rs if not x["los"]],
        }[where]

    # (a) plain 100 ms cues, all episodes (as before)
    for cue, key in (("ILD", "ild"), ("ITD", "itd")):
        add(f"{cue} sign = source side, line of sight", lambda nm, key=key: agreement(sub(rows(nm), "los"), key, "side"), "≥ 0.85")
        add(f"{cue} sign = source side, line of sight, within 1.2 m", lambda nm, key=key: agreement(sub(rows(nm), "los_1.2"), key, "side"))
        add(f"{cue} sign = source side, line of sight, within the critical distance", lambda nm, key=key: agreement(sub(rows(nm), "los_near"), key, "side"))
        add(f"{cue} sign = source side, line of sight, beyond the critical distance", lambda nm, key=key: agreement(sub(rows(nm), "los_far"), key, "side"))
        add(f"{cue} sign = source side, behind a wall", lambda nm, key=key: agreement(sub(rows(nm), "wall"), key, "side"))
        add(f"{cue} sign = doorway side, behind a wall", lambda nm, key=key: agreement(sub(rows(nm), "wall"), key, "door_side"), "≥ 0.75")
    for cue, key in (("ILD", "ild"), ("ITD", "itd")):
        add(f"{cue} sign = source side, line of sight, source audible in the step's 100 ms",
            lambda nm, key=key: agreement([x for x in sub(rows(nm), "los") if x["audible"]], key, "side"))
        add(f"{cue} sign = source side, line of sight, source silent in the step's 100 ms (a gap)",
            lambda nm, key=key: agreement([x for x in sub(rows(nm), "los") if not x["audible"]], key, "side"))
    for cat in sorted({x["cat"] for x in rows("room")}):
        kind = "tonal" if cat in TONAL else "broadband"
        for cue, key in (("ILD", "ild"), ("ITD", "itd")):
            add(f"{cue}, {cat} ({kind}), line of sight", lambda nm, key=key, cat=cat: agreement([x for x in sub(rows(nm), "los") if x["cat"] == cat], key, "side"))
    rises = {nm: data[nm]["train"]["rises"] + data[nm]["test"]["rises"] for nm in data}
    add("median level rise over Navigate (dB)", lambda nm: (float(np.median(rises[nm])) if rises[nm] else float("nan"), len(rises[nm])), "≥ 8")
    add("left/right classifier on test spectrograms (spectrogram L−R, C = 0.05, as before)", lambda nm: (classifier(data[nm]["train"]["feats"], data[nm]["test"]["feats"]), len(data[nm]["test"]["feats"])), "≥ 0.85", "test")

    # (b) tiled estimators: parameters chosen on train (room render), scored on test
    chosen: dict = {}
    train_rows = rows("room", "train")
    for est, label in (("coh", "coherence-selected"), ("onset", "onset-weighted")):
        for window in ("100ms", "1s"):
            for cue in ("ild", "itd"):
                k = choose(train_rows, est, cue, window) if train_rows else None
                if k is None:
                    continue
                name = f"{cue.upper()} {label}, {window}"
                chosen[name] = dict(estimator=est, cue=cue, window=window, param=k[2], bands_hz=list(k[3]),
                                    train_los_agreement=round(agreement(sub(train_rows, "los"), (window, k), "side")[0], 3))
                for where, truth, goal in (("los", "side", "≥ 0.85"), ("los_near", "side", ""), ("los_far", "side", ""), ("wall", "side", ""), ("wall", "door_side", "≥ 0.75")):
                    what = {"los": "source side, line of sight", "los_near": "source side, line of sight, within the critical distance",
                            "los_far": "source side, line of sight, beyond the critical distance", "wall": "source side, behind a wall"}[where]
                    if truth == "door_side":
                        what = "doorway side, behind a wall"
                    add(f"{name}: sign = {what}", lambda nm, where=where, truth=truth, window=window, k=k: agreement(sub(rows(nm, "test"), where), (window, k), truth), goal, "test")
    # per sound, the onset-weighted cues over the second (test)
    for cue in ("ild", "itd"):
        name = f"{cue.upper()} onset-weighted, 1s"
        if name not in chosen:
            continue
        k = ("onset", cue, chosen[name]["param"], tuple(chosen[name]["bands_hz"]))
        for cat in sorted({x["cat"] for x in rows("room", "test")}):
            kind = "tonal" if cat in TONAL else "broadband"
            add(f"{name}: {cat} ({kind}), line of sight", lambda nm, k=k, cat=cat: agreement([x for x in sub(rows(nm, "test"), "los") if x["cat"] == cat], ("1s", k), "side"), "", "test")
    # the plain cues on the same test steps, for comparison
    for cue, key in (("ILD", "ild"), ("ITD", "itd")):
        add(f"{cue} plain 100 ms: sign = source side, line of sight", lambda nm, key=key: agreement(sub(rows(nm, "test"), "los"), key, "side"), "≥ 0.85", "test")
        add(f"{cue} plain 100 ms: sign = doorway side, behind a wall", lambda nm, key=key: agreement(sub(rows(nm, "test"), "wall"), key, "door_side"), "≥ 0.75", "test")

    # (c) classifier with features and C chosen on a validation part of train
    kind, c, v = choose_classifier(data["room"]["train"]["feats"]) if data["room"]["train"]["feats"] else ("spec", 0.05, float("nan"))
    chosen["classifier"] = dict(features=kind, C=c, validation_accuracy=round(v, 3))
    for where, keep, goal in (("", lambda t: True, "≥ 0.85"), (", line of sight", lambda t: t["los"], ""), (", behind a wall", lambda t: not t["los"], "")):
        add(f"left/right classifier on test steps{where}, mirror-symmetric ({kind} features, C = {c}, chosen on train validation)",
            lambda nm, keep=keep: (classifier(data[nm]["train"]["feats"], [t for t in data[nm]["test"]["feats"] if keep(t)], kind, c, symmetric=True),
                                   sum(1 for t in data[nm]["test"]["feats"] if keep(t))), goal, "test")

    def door_items(nm: str) -> list[dict]:
        return [dict(t, y=t["door"]) for t in data[nm]["test"]["feats"] if not t["los"] and t["door"] is not None]

    add(f"left/right classifier on test steps behind a wall = doorway side, mirror-symmetric ({kind} features, C = {c})",
        lambda nm: (classifier(data[nm]["train"]["feats"], door_items(nm), kind, c, symmetric=True), len(door_items(nm))), "≥ 0.75", "test")

    # (d) distances and the diffuse-field model
    los = sub(rows("room"), "los")
    free_los = sub(rows("free"), "los")
    d = np.array([x["dist"] for x in los])
    rc = np.array([x["rc"] for x in los])
    pred_all, sigma, n_far = diffuse_model(los, free_los)
    far_idx = [i for i, x in enumerate(los) if x["dist"] > x["rc"]]
    near_idx = [i for i, x in enumerate(los) if x["dist"] <= x["rc"]]
    pred_far = diffuse_model([los[i] for i in far_idx], [free_los[i] for i in far_idx], sigma=sigma)[0] if far_idx else float("nan")
    pred_near = diffuse_model([los[i] for i in near_idx], [free_los[i] for i in near_idx], sigma=sigma)[0] if near_idx else float("nan")
    bins = []
    for lo, hi in ((0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 5.0), (5.0, np.inf)):
        idx = [i for i, x in enumerate(los) if lo < x["dist"] / x["rc"] <= hi]
        a, k = agreement([los[i] for i in idx], "ild", "side")
        pred = diffuse_model([los[i] for i in idx], [free_los[i] for i in idx], sigma=sigma)[0] if idx else float("nan")
        bins.append(dict(distance_over_rc=[lo, None if hi == np.inf else hi], n=k, plain_ild_agreement=round(a, 3), diffuse_model=round(pred, 3),
                         free_field=round(agreement([free_los[i] for i in idx], "ild", "side")[0], 3)))
    distances = dict(
        los_steps=len(los),
        share_los_steps_source_silent=round(float(np.mean([not x["audible"] for x in los])), 3) if los else None,
        median_distance_m=round(float(np.median(d)), 2) if len(d) else None,
        median_critical_distance_m=round(float(np.median(rc)), 2) if len(rc) else None,
        share_beyond_critical_distance=round(float(np.mean(d > rc)), 3) if len(d) else None,
        median_direct_to_reverberant_db=round(float(np.median(20 * np.log10(rc / d))), 1) if len(d) else None,
        diffuse_model_ild_agreement=dict(all=round(pred_all, 3), within_rc=round(pred_near, 3), beyond_rc=round(pred_far, 3),
                                         reverberant_ild_spread_db=round(sigma, 2), n_steps_beyond_3rc=n_far),
        plain_ild_by_distance=bins,
    )
    return dict(header, table=table, chosen=chosen, distances=distances)


def json_safe(x):
    """NaN (no steps of a kind) as null: JSON has no NaN."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    return x


def print_table(out: dict) -> None:
    print("| | split | room (ours) | free field (ceiling) | goal |")
    print("|---|---|---|---|---|")
    for r in out["table"]:
        cells = ["n/a" if c["value"] is None else f"{c['value']:.2f} (n={c['n']})" for c in (r["room"], r["free"])]
        print(f"| {r['metric']} | {r['split']} | {cells[0]} | {cells[1]} | {r['goal']} |")
    print("\nchosen on train:", json.dumps(out["chosen"], ensure_ascii=False))
    print("distances:", json.dumps(out["distances"], ensure_ascii=False))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--recipe", default=str(ROOT / "recipes" / "stmm_1_9k.yaml"))
    ap.add_argument("--train", type=int, default=20)
    ap.add_argument("--test", type=int, default=10)
    ap.add_argument("--out", default=str(Path(__file__).with_name("results") / "spatial_cues.json"))
    args = ap.parse_args()
    recipe = load_recipe(args.recipe)
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    t0 = time.perf_counter()
    data, n_ok = render_episodes(args, recipe, library)
    header = dict(
        command=f"python studies/spatial_cues/bench_spatial_cues.py --recipe {Path(args.recipe).name} --train {args.train} --test {args.test}",
        recipe=Path(args.recipe).name, train_indices=args.train, test_indices=args.test, episodes=n_ok,
    )
    out = json_safe(report(data, header))
    out["seconds"] = round(time.perf_counter() - t0)
    print(f"\n{n_ok} episodes of {Path(args.recipe).name} ({args.train} train + {args.test} test indices)\n")
    print_table(out)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1, ensure_ascii=False, allow_nan=False) + "\n")
    print(f"wrote {args.out}; {out['seconds']} s")


if __name__ == "__main__":
    main()
