"""Acoustics throughput, as ratios to a SoundSpaces-style baseline measured in the same run.

Baseline: `scipy.signal.fftconvolve` of 1 s of mono audio with one binaural RIR (both ears),
which is what SoundSpaces does per observation with its precomputed RIRs.

(a) per control step with two sources, every RIR already in the cache (target <= 3x baseline);
(b) cold RIR precomputation for one source over the whole receiver grid x all yaw bins of a
    generated apartment: room responses (batch) + binauralisation (target <= 2 s per source);
(c) for information: per-step features (SoundSpaces spectrogram + log-mel).
Wall and process-CPU times are both printed (best of several runs): on a shared machine the
CPU figures are the ones that say what one worker costs.

Usage:  python benchmarks/bench_audio.py [--seed 0] [--recipe recipes/quickstart.yaml] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")  # a single worker's view: one core

import numpy as np  # noqa: E402
from scipy.signal import fftconvolve  # noqa: E402

from echo_data.acoustics.binaural import binaural_length  # noqa: E402
from echo_data.acoustics.features import step_features  # noqa: E402
from echo_data.acoustics.hrtf import Hrtf  # noqa: E402
from echo_data.acoustics.room import AcousticScene  # noqa: E402
from echo_data.acoustics.stream import RirCache, SourceTrack, render_track  # noqa: E402
from echo_data.recipe import load_recipe  # noqa: E402
from echo_data.scene.generate import generate_floorplan  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _best(fn, repeat: int) -> tuple[float, float]:
    """Fastest of `repeat` runs as (wall s, process CPU s): the least disturbed by other load."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    return wall, cpu


def grid_points(plan, grid: float, z: float) -> np.ndarray:
    """Receiver grid points (n, 3) inside the rooms of `plan` (0.3 m clear of the walls)."""
    pts = []
    for room in plan.rooms:
        r = room.rect
        xs = np.arange(np.ceil((r.xmin + 0.3) / grid), np.floor((r.xmax - 0.3) / grid) + 1) * grid
        ys = np.arange(np.ceil((r.ymin + 0.3) / grid), np.floor((r.ymax - 0.3) / grid) + 1) * grid
        pts += [(x, y, z) for x in xs for y in ys]
    return np.asarray(sorted(set(pts)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recipe", type=Path, default=ROOT / "recipes" / "quickstart.yaml")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    recipe = load_recipe(args.recipe)
    cfg = recipe.acoustics
    fs = cfg.sample_rate
    plan = generate_floorplan(recipe, np.random.default_rng(args.seed))
    scene = AcousticScene(plan, cfg)
    hrtf = Hrtf.load(cfg.hrtf, fs)
    rng = np.random.default_rng(1)
    pts = grid_points(plan, cfg.grid, cfg.ear_height)
    sources = [tuple(float(v) for v in pts[i]) for i in rng.choice(len(pts), 2, replace=False)]
    sources = [(x + 0.13, y - 0.07, 0.9) for x, y, _ in sources]  # off-grid, at table height
    print(f"plan seed {plan.seed}: {len(plan.rooms)} rooms, {len(pts)} grid points at {cfg.grid} m, "
          f"{cfg.yaws} yaws, RIR {cfg.rir_seconds} s at {fs} Hz, HRTF {cfg.hrtf}")

    binaural_length(scene.free_field(sources[0], pts[0]), hrtf)  # per-process HRTF kernel bank, not per source

    # (b) cold precomputation per source over the grid (fresh cache each time)
    cold, n_arr = [], []
    for s in range(len(sources)):
        cache = RirCache(scene, sources, cfg, hrtf)
        t0, c0 = time.perf_counter(), time.process_time()
        cache.precompute(s, pts)
        cold.append((time.perf_counter() - t0, time.process_time() - c0))
        n_arr.append(np.mean([len(r.arrivals) for r in cache._responses.values()]))
    rir = cache.rir(next(iter(cache._rirs)))

    # baseline: SoundSpaces-style 1 s convolution with one binaural RIR
    x = rng.standard_normal(fs)
    base = _best(lambda: fftconvolve(x[:, None], rir, axes=0), args.repeat * 4)

    # (a) per step, two sources, warm cache: a 30 s walk through the grid points, turning
    step = fs // recipe.robot.control_hz
    n_steps = 300
    idx = np.linspace(0, len(pts) - 1, n_steps).astype(int)
    poses = np.column_stack([pts[idx], np.linspace(0, 4 * np.pi, n_steps)])
    tracks = [SourceTrack(p, rng.standard_normal(n_steps * step + fs).astype(np.float32), None) for p in sources]
    warm = RirCache(scene, sources, cfg, hrtf)
    render_track(scene, tracks, poses, step, cfg, hrtf, cache=warm)
    n_blocks = -(-(n_steps * step + int(0.02 * fs) + warm.length - 1) // step)
    whole = _best(lambda: render_track(scene, tracks, poses, step, cfg, hrtf, cache=warm), max(1, args.repeat // 2))
    per_step = (whole[0] / n_blocks, whole[1] / n_blocks)
    keys = {warm.key(0, p) for p in poses}
    switches = sum(warm.key(0, a) != warm.key(0, b) for a, b in zip(poses, poses[1:]))

    track = render_track(scene, tracks, poses, step, cfg, hrtf, cache=warm)
    offsets = (np.arange(n_steps) + 1) * step
    feats = _best(lambda: step_features(track, offsets, fs, cfg.mel_bands), 2)

    print(f"baseline fftconvolve 1 s x RIR ({rir.shape[0]} taps, 2 ch): wall {base[0] * 1e3:.3f} ms, cpu {base[1] * 1e3:.3f} ms")
    print(f"(a) per step, 2 sources from cache ({len(keys)} keys, {switches} crossfades in {n_steps} steps): "
          f"wall {per_step[0] * 1e3:.3f} ms = {per_step[0] / base[0]:.2f}x, "
          f"cpu {per_step[1] * 1e3:.3f} ms = {per_step[1] / base[1]:.2f}x baseline (target <= 3x)")
    print(f"(c) features per step (spectrogram + {cfg.mel_bands}-band log-mel, both ears): "
          f"wall {feats[0] / n_steps * 1e3:.3f} ms, cpu {feats[1] / n_steps * 1e3:.3f} ms = {feats[1] / n_steps / base[1]:.2f}x baseline")
    for s, (w, c) in enumerate(cold):
        print(f"(b) cold grid precompute, source {s}: {len(pts)} points x {cfg.yaws} yaws "
              f"({n_arr[s]:.0f} arrivals/response): wall {w:.2f} s = {w / base[0]:.0f}x, "
              f"cpu {c:.2f} s = {c / base[1]:.0f}x baseline (target <= 2 s)")


if __name__ == "__main__":
    main()
