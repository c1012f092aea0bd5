"""Acoustics throughput, as ratios to a SoundSpaces-style baseline measured in the same run.

Baseline: `scipy.signal.fftconvolve` of 1 s of mono audio with one binaural RIR (both ears),
which is what SoundSpaces does per observation with its precomputed RIRs.

(a) per control step with two sources, every RIR already in the cache (target <= 3x baseline);
(b) cold RIR precomputation for one source over the whole receiver grid x all yaw bins of a
    generated apartment: room responses (batch) + binauralisation (target <= 2 s per source).

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

from echo_data.acoustics.hrtf import Hrtf  # noqa: E402
from echo_data.acoustics.room import AcousticScene  # noqa: E402
from echo_data.acoustics.stream import RirCache, SourceTrack, render_track  # noqa: E402
from echo_data.recipe import load_recipe  # noqa: E402
from echo_data.scene.generate import generate_floorplan  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _best(fn, repeat: int) -> float:
    """Fastest of `repeat` timings (seconds): the least disturbed by other load on the machine."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


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

    # (b) cold precomputation per source over the grid (fresh cache each time)
    cold = []
    for s in range(len(sources)):
        cache = RirCache(scene, sources, cfg, hrtf)
        t0 = time.perf_counter()
        n_new = cache.precompute(s, pts)
        cold.append(time.perf_counter() - t0)
        n_arr = np.mean([len(r.arrivals) for r in cache._responses.values()])
    rir = cache.rir(next(iter(cache._rirs)))

    # baseline: SoundSpaces-style 1 s convolution with one binaural RIR
    x = rng.standard_normal(fs)
    base = _best(lambda: fftconvolve(x[:, None], rir, axes=0), args.repeat * 4)

    # (a) per step, two sources, warm cache: a 30 s walk through the grid points
    step = fs // recipe.robot.control_hz
    n_steps = 300
    idx = np.linspace(0, len(pts) - 1, n_steps).astype(int)
    poses = np.column_stack([pts[idx], np.linspace(0, 4 * np.pi, n_steps)])
    tracks = [SourceTrack(p, rng.standard_normal(n_steps * step + fs).astype(np.float32), None) for p in sources]
    warm = RirCache(scene, sources, cfg, hrtf)
    render_track(scene, tracks, poses, step, cfg, hrtf, cache=warm)
    n_blocks = -(-(n_steps * step + int(0.02 * fs) + warm.length - 1) // step)
    per_step = _best(lambda: render_track(scene, tracks, poses, step, cfg, hrtf, cache=warm), max(1, args.repeat // 2))
    per_step /= n_blocks

    print(f"baseline fftconvolve 1 s x RIR ({rir.shape[0]} taps, 2 ch): {base * 1e3:.3f} ms")
    print(f"(a) per step, 2 sources from cache: {per_step * 1e3:.3f} ms = {per_step / base:.2f}x baseline (target <= 3x)")
    for s, t in enumerate(cold):
        print(f"(b) cold grid precompute, source {s}: {t:.2f} s for {len(pts)} points x {cfg.yaws} yaws "
              f"= {t / base:.0f}x baseline (target <= 2 s); mean {n_arr:.0f} arrivals/response")


if __name__ == "__main__":
    main()
