"""Streaming renderer: equals offline convolution for a still head, superposes exactly, stops to
exact silence, is deterministic, crossfades without jumps, caches on grid x yaw bins; and runs
on a generated apartment with the room model."""

from __future__ import annotations

import hashlib
import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import fftconvolve

from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.stream import FADE_S, RirCache, SourceTrack, dry_signal, render_track
from echo_data.acoustics.types import SPEED_OF_SOUND, AcousticResponse, Arrival
from echo_data.recipe import AcousticsConfig

FS = 16000
STEP = 1600
CFG = AcousticsConfig(rir_seconds=0.25, grid=0.5, yaws=8)
FADE = int(round(FADE_S * FS))


class FreeFieldScene:
    """Direct sound plus a deterministic decaying noise tail (stand-in for the room model)."""

    def __init__(self, length: int = int(0.25 * FS)) -> None:
        self.length = length
        self.calls = 0

    def response(self, src, rcv) -> AcousticResponse:
        self.calls += 1
        v = np.asarray(src, float) - np.asarray(rcv, float)
        d = float(np.linalg.norm(v))
        seed = int(abs(hash(tuple(np.round(np.concatenate([src, rcv]), 3)))) % 2**32)
        t0 = int(d / SPEED_OF_SOUND * FS) + 30
        tail = np.zeros(self.length, np.float32)
        n = np.arange(self.length - t0)
        tail[t0:] = np.random.default_rng(seed).standard_normal(len(n)) * np.exp(-n / 600.0) * 0.05 / d
        arr = Arrival(d / SPEED_OF_SOUND, tuple(v / d), 1.0 / d, (1.0,) * 7, 0)
        return AcousticResponse(FS, [arr], tail, self.length)


def walk(n: int, x0=0.0, x1=2.0, yaw0=0.0, yaw1=0.0) -> np.ndarray:
    return np.column_stack([np.linspace(x0, x1, n), np.zeros(n), np.full(n, CFG.ear_height), np.linspace(yaw0, yaw1, n)])


def noise(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(n).astype(np.float32)


def test_still_head_equals_offline_convolution():
    scene = FreeFieldScene()
    n = 12
    poses = walk(n, 0.2, 0.2)
    src = SourceTrack((2.0, 1.0, 1.0), noise(n * STEP + FS, 1), None)
    y = render_track(scene, [src], poses, STEP, CFG, Hrtf.load("kemar", FS))
    cache = RirCache(scene, [src.position], CFG, Hrtf.load("kemar", FS))
    rir = cache.rir(cache.key(0, poses[0])).astype(np.float64)
    ref = fftconvolve(dry_signal(src, n * STEP, FS)[:, None], rir, axes=0)
    assert y.shape == (n * STEP + FADE + len(rir) - 1, 2)
    np.testing.assert_allclose(y, ref[: len(y)], atol=1e-5 * np.abs(ref).max())


def test_sources_superpose_exactly():
    scene = FreeFieldScene()
    n = 30
    poses = walk(n, 0.0, 2.5, 0.0, 2.0)
    a = SourceTrack((2.0, 1.5, 1.0), noise(n * STEP, 2), 14 * STEP + 77)
    b = SourceTrack((-1.0, -2.0, 0.8), (np.sin(np.arange(n * STEP) * 0.05) * 0.5).astype(np.float32), None)
    both = render_track(scene, [a, b], poses, STEP, CFG).astype(np.float64)
    ya = render_track(scene, [a], poses, STEP, CFG).astype(np.float64)
    yb = render_track(scene, [b], poses, STEP, CFG).astype(np.float64)
    assert np.abs(ya).max() > 0.02 and np.abs(yb).max() > 0.02
    np.testing.assert_allclose(both, ya + yb, atol=1e-6 * np.abs(both).max())


def test_stopped_source_reaches_exact_zero_after_fade_plus_rir_length():
    scene = FreeFieldScene()
    n = 20
    stop = 6 * STEP + 123
    src = SourceTrack((1.5, -1.0, 1.0), noise(n * STEP, 3), stop)
    y = render_track(scene, [src], walk(n, 0.0, 1.0), STEP, CFG)
    rir_len = len(y) - n * STEP - FADE + 1
    silent_from = stop + FADE + rir_len - 1
    assert np.all(y[silent_from:] == 0.0)
    assert np.abs(y[silent_from - 400 : silent_from]).max() > 0.0  # the reverb really rings until then
    # the dry signal itself: full level before the stop, a 20 ms fade, then nothing
    x = dry_signal(src, n * STEP, FS)
    np.testing.assert_array_equal(x[:stop], src.waveform[:stop])
    assert np.all(np.abs(x[stop : stop + FADE]) <= np.abs(src.waveform[stop : stop + FADE]))
    assert np.all(x[stop + FADE :] == 0.0)


def test_reverb_decays_naturally_after_the_stop():
    """After the stop the output is the RIR's own decay, not a cut: energy falls off gradually."""
    scene = FreeFieldScene()
    n = 12
    stop = 4 * STEP
    y = render_track(scene, [SourceTrack((2.0, 0.0, 1.2), noise(n * STEP, 4), stop)], walk(n, 0.0, 0.0), STEP, CFG)
    e = [float((y[stop + FADE + k * 400 : stop + FADE + (k + 1) * 400].astype(np.float64) ** 2).sum()) for k in range(6)]
    assert all(v > 0 for v in e) and all(a > b for a, b in zip(e, e[1:]))


def test_same_inputs_give_identical_bytes():
    n = 25
    poses = walk(n, -0.3, 2.7, 0.5, -2.0)
    srcs = [SourceTrack((2.0, 1.0, 1.0), noise(n * STEP, 5), 11 * STEP), SourceTrack((0.0, 3.0, 0.5), noise(n * STEP, 6), None)]
    a = render_track(FreeFieldScene(), srcs, poses, STEP, CFG)
    b = render_track(FreeFieldScene(), srcs, poses, STEP, CFG)
    assert a.dtype == np.float32
    assert hashlib.sha256(a.tobytes()).hexdigest() == hashlib.sha256(b.tobytes()).hexdigest()


def _max_jump_at(y: np.ndarray, idx: np.ndarray) -> float:
    d = np.abs(np.diff(y.astype(np.float64), axis=0)).max(axis=1)
    return float(d[idx].max())


def test_crossfade_has_no_jumps_at_rir_switches():
    scene = FreeFieldScene()
    n = 24
    poses = walk(n, 0.0, 5.5, 0.0, 3.0)  # changes cell or yaw bin at many steps
    tone = (0.8 * np.sin(2 * np.pi * 220 * np.arange(n * STEP) / FS)).astype(np.float32)
    src = SourceTrack((1.0, 2.0, 1.2), tone, None)
    cache = RirCache(scene, [src.position], CFG, Hrtf.load("kemar", FS))
    y = render_track(scene, [src], poses, STEP, CFG, cache=cache)
    keys = [cache.key(0, p) for p in poses]
    switches = np.array([j for j in range(1, n) if keys[j] != keys[j - 1]])
    assert len(switches) >= 5
    diffs = np.abs(np.diff(y.astype(np.float64), axis=0)).max(axis=1)
    own = np.percentile(diffs[STEP : n * STEP], 99.9)  # the signal's own sample-to-sample steps
    boundary = np.concatenate([switches * STEP - 1 + k for k in range(-2, 3)])
    assert _max_jump_at(y, boundary) <= 1.2 * own
    # the same check does catch a hard switch: splice the two RIRs' outputs at one boundary
    j = int(switches[0])
    hard = y.astype(np.float64).copy()
    old = fftconvolve(tone[:, None].astype(np.float64), cache.rir(keys[j - 1]).astype(np.float64), axes=0)
    hard[: j * STEP] = old[: j * STEP]
    new = fftconvolve(tone[:, None].astype(np.float64), cache.rir(keys[j]).astype(np.float64), axes=0)
    hard[j * STEP : (j + 1) * STEP] = new[j * STEP : (j + 1) * STEP]
    assert abs(hard[j * STEP] - hard[j * STEP - 1]).max() > 2 * own


def test_cache_keys_grid_cells_and_yaw_bins():
    scene = FreeFieldScene()
    h = Hrtf.load("sphere", FS)
    cache = RirCache(scene, [(2.0, 0.0, 1.2)], CFG, h)
    z = CFG.ear_height
    bin_width = 2 * math.pi / CFG.yaws
    # within one cell and one yaw bin: one key, one response, one RIR
    k0 = cache.key(0, (0.1, -0.2, z, 0.3 * bin_width))
    assert cache.key(0, (-0.2, 0.24, z, -0.4 * bin_width)) == k0
    assert cache.key(0, (0.26, 0.0, z, 0.0)) != k0  # next cell
    assert cache.key(0, (0.0, 0.0, z, 0.6 * bin_width)) != k0  # next yaw bin
    assert cache.key(0, (0.0, 0.0, z, 2 * math.pi)) == cache.key(0, (0.0, 0.0, z, 0.0))  # yaw wraps
    pos, yaw = cache.receiver(k0)
    assert pos == pytest.approx((0.0, 0.0, z)) and yaw == 0.0
    cache.rir(k0)
    cache.rir(cache.key(0, (0.0, 0.0, z, 3 * bin_width)))  # same cell, other yaw: response reused
    assert (scene.calls, cache.rirs_computed) == (1, 2)
    # a render computes each distinct key once
    poses = walk(40, 0.0, 1.0, 0.0, 1.5)
    cache2 = RirCache(scene, [(2.0, 0.0, 1.2)], CFG, h)
    render_track(scene, [SourceTrack((2.0, 0.0, 1.2), noise(40 * STEP, 7))], poses, STEP, CFG, h, cache=cache2)
    assert cache2.rirs_computed == len({k for p in poses for k, _ in cache2.keys(0, p)})
    assert cache2.responses_computed == len({cache2.key(0, p)[:5] for p in poses})


def test_left_source_is_heard_left_in_the_track():
    scene = FreeFieldScene()
    n = 10
    src = SourceTrack((0.0, 2.0, 1.2), noise(n * STEP, 8), None)  # +y
    left = render_track(scene, [src], walk(n, 0.0, 0.0, 0.0, 0.0), STEP, CFG).astype(np.float64)
    right = render_track(scene, [src], walk(n, 0.0, 0.0, math.pi, math.pi), STEP, CFG).astype(np.float64)
    e_l, e_r = (left**2).sum(axis=0), (right**2).sum(axis=0)
    assert e_l[0] > 2 * e_l[1] and e_r[1] > 2 * e_r[0]


def test_generated_apartment_with_room_model():
    """End to end on a generated plan with the room engineer's AcousticScene."""
    from echo_data.acoustics.room import AcousticScene
    from echo_data.recipe import Recipe
    from echo_data.scene.generate import generate_floorplan

    recipe = Recipe(name="t", acoustics=CFG)
    plan = generate_floorplan(recipe, np.random.default_rng(0))
    scene = AcousticScene(plan, CFG)
    room = plan.rooms[0].rect
    cx, cy = room.center
    n = 15
    poses = np.column_stack([np.linspace(cx - 0.6, cx + 0.6, n), np.full(n, cy), np.full(n, CFG.ear_height), np.zeros(n)])
    src = SourceTrack((cx, cy + 1.0, 1.0), noise(n * STEP, 9), 8 * STEP)  # on the head's left
    a = render_track(scene, [src], poses, STEP, CFG)
    b = render_track(scene, [src], poses, STEP, CFG)
    assert np.array_equal(a, b) and np.isfinite(a).all()
    e = (a[: 8 * STEP].astype(np.float64) ** 2).sum(axis=0)
    assert e[0] > e[1] > 0
    assert np.all(a[8 * STEP + FADE + (len(a) - n * STEP - FADE) :] == 0.0)


def test_grid_points_stay_in_the_heads_room():
    """A wall on a grid line: heads on either side share (ix, iy) but never a receiver."""
    from echo_data.floorplan import Rect

    class Plan:
        rooms = (SimpleNamespace(index=0, rect=Rect(0.0, 0.0, 3.0, 3.0)), SimpleNamespace(index=1, rect=Rect(3.0, 0.0, 6.0, 3.0)))
        walls = (SimpleNamespace(thickness=0.1),)

        def room_at(self, x, y):
            return next((r.index for r in self.rooms if r.rect.contains(x, y)), -1)

    scene = FreeFieldScene()
    scene.plan = Plan()
    cache = RirCache(scene, [(1.0, 1.0, 1.0)], CFG, Hrtf.load("sphere", FS))
    z = CFG.ear_height
    west, east = cache.key(0, (2.8, 1.5, z, 0.0)), cache.key(0, (3.2, 1.5, z, 0.0))
    assert west[2:] == east[2:] and west != east
    assert cache.receiver(west)[0][0] < 3.0 - 0.05 and cache.receiver(east)[0][0] > 3.0 + 0.05
    assert cache.receiver(cache.key(0, (1.4, 1.6, z, 0.0)))[0] == pytest.approx((1.5, 1.5, z))  # inside: plain grid


def _cues(ir: np.ndarray) -> tuple[float, float]:
    """(broadband ILD in dB, ITD in µs) of a binaural IR: the energy ratio of the whole IR, and
    the lag (within ±1 ms) of the cross-correlation peak of the first 3 ms after onset,
    low-passed at 1.5 kHz (where ITD is defined unambiguously), 8x upsampled, parabolic peak."""
    from scipy.signal import butter, resample_poly, sosfiltfilt

    ild = 10 * np.log10((ir[:, 0] ** 2).sum() / (ir[:, 1] ** 2).sum())
    on = int(np.argmax(np.abs(ir).max(axis=1) > 0.1 * np.abs(ir).max()))
    seg = ir[max(on - 32, 0) : on + 48].astype(np.float64)
    seg = sosfiltfilt(butter(4, 1500.0, fs=FS, output="sos"), seg, axis=0)
    seg = resample_poly(seg, 8, 1, axis=0)
    c = np.correlate(seg[:, 0], seg[:, 1], "full")
    mid, span = len(seg) - 1, int(8 * FS * 1e-3)
    k = mid - span + int(np.argmax(c[mid - span : mid + span + 1]))
    frac = 0.5 * (c[k - 1] - c[k + 1]) / (c[k - 1] - 2 * c[k] + c[k + 1])
    lag = (k + frac - mid) / (8 * FS)  # > 0: left lags right
    return float(ild), float(-lag * 1e6)


def test_turning_in_place_in_one_degree_steps_changes_cues_smoothly():
    """A head turning in 1° steps (default 5° yaw bins, RIRs interpolated between neighbours):
    the RIR each step is rendered with changes its ILD by at most 0.6 dB and its ITD by at most
    20 µs per step (a source 1.5 m away in the horizontal plane: the physical ITD changes by
    up to ~9 µs per degree)."""
    from support.room_plans import shoebox_plan

    from echo_data.acoustics.room import AcousticScene

    cfg = AcousticsConfig(rir_seconds=0.25)
    assert 360 / cfg.yaws <= 5.0
    scene = AcousticScene(shoebox_plan(5.0, 4.0, "plasterboard", "carpet_cotton", "ceiling_plasterboard"), cfg)
    cache = RirCache(scene, [(3.5, 2.0, 1.2)], cfg, Hrtf.load("kemar", FS))
    ild, itd = [], []
    for deg in np.arange(0.0, 181.0, 1.0):
        pose = (2.0, 2.0, cfg.ear_height, np.deg2rad(deg))
        ir = sum(w * cache.rir(k).astype(np.float64) for k, w in cache.keys(0, pose))
        a, b = _cues(ir)
        ild.append(a)
        itd.append(b)
    ild, itd = np.asarray(ild), np.asarray(itd)
    assert np.abs(np.diff(ild)).max() <= 0.6, np.abs(np.diff(ild)).max()
    assert np.abs(np.diff(itd)).max() <= 20.0, np.abs(np.diff(itd)).max()
    # the cues do follow the turn: source ahead, then on the right (90°), then behind
    assert abs(ild[0]) < 1.5 and ild[90] < -2.0 and itd[90] < -400.0 and abs(itd[180]) < 50.0
    # with 45° bins and no interpolation the cues jump in one step (the measure sees it)
    coarse = RirCache(scene, [(3.5, 2.0, 1.2)], AcousticsConfig(rir_seconds=0.25, yaws=8), Hrtf.load("kemar", FS))
    jumps = np.asarray([_cues(coarse.rir(coarse.key(0, (2.0, 2.0, cfg.ear_height, np.deg2rad(d)))).astype(np.float64)) for d in np.arange(0.0, 91.0, 1.0)])
    assert np.abs(np.diff(jumps[:, 0])).max() > 1.5 and np.abs(np.diff(jumps[:, 1])).max() > 200.0
