"""Steps/s of N `EchoDataEnv`s in an async vector env (every observation), against one env in this process.

  1 process   `EchoDataEnv.step` here, seeded random actions: steps/s, and the distribution of a
              step's wall time (mean, p50, p90, p99)
  stragglers  a vector step waits for the slowest of its N envs: the mean of the slowest of N
              steps drawn from that distribution (bootstrap) bounds the share of linear scaling
              that N envs can reach even with free cores and no transport cost
  N async     `gymnasium.make_vec(id, num_envs=N, vectorization_mode="async")` with the spawn
              context: steps/s of all envs together, per env, and the share of N x one process
  threads     threads per worker process, by name (BLAS pools, renderer, listening thread)
  floor       the bare SAPIEN step + render + readback (`timing.floor_times`) in N processes at
              once against one: how far the machine itself scales N renderers, the bound the
              N async envs are judged against (on CPU rendering, cores are shared by everything)
`ECHO_DATA_PREFETCH=0` turns the listening thread's idle-time RIR prefetch off (to compare).

  python benchmarks/bench_vec.py [RECIPE] [--n 2] [--n 4 ...] [--steps 60] [--no-images] [--no-audio]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import time
from collections import Counter
from pathlib import Path
from typing import Any

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _make(recipe: Any, images: bool, audio: bool) -> Any:
    from echo_data.envs import EchoDataEnv

    return EchoDataEnv(recipe, split="train", images=images, audio=audio)


def _thread_names() -> dict[str, int]:
    """This process's threads by name (Linux)."""
    names: Counter[str] = Counter()
    for t in os.listdir("/proc/self/task"):
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            names[Path(f"/proc/self/task/{t}/comm").read_text().strip()] += 1
    return dict(names)


def _make_probe(recipe: Any, images: bool, audio: bool) -> Any:
    """An env whose `thread_names()` reports its worker's threads (called through `envs.call`)."""
    env = _make(recipe, images, audio)
    env.thread_names = _thread_names
    return env


def one_process(recipe: Any, steps: int, images: bool, audio: bool) -> np.ndarray:
    """Wall seconds of each `EchoDataEnv.step` in this process (resets not timed)."""
    env = _make(recipe, images, audio)
    rng = np.random.default_rng(0)
    low, high = env.action_space.low, env.action_space.high
    env.reset(options={"index": 0})
    for _ in range(3):
        env.step(rng.uniform(low, high).astype(np.float32))
    times, ep = [], 0
    while len(times) < steps:
        a = rng.uniform(low, high).astype(np.float32)
        t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step(a)
        times.append(time.perf_counter() - t0)
        if term or trunc:
            ep += 1
            env.reset(options={"index": ep})
    env.close()
    return np.array(times)


def slowest_of(times: np.ndarray, n: int, draws: int = 20000) -> float:
    """Mean of the slowest of n steps drawn from `times` (bootstrap, seeded)."""
    rng = np.random.default_rng(1)
    return float(rng.choice(times, (draws, n)).max(axis=1).mean())


def vector(recipe: Any, n: int, steps: int, images: bool, audio: bool) -> tuple[float, dict[str, int]]:
    """(steps/s of all n envs of an async vector env, the first worker's threads by name)."""
    import gymnasium as gym

    envs = gym.vector.AsyncVectorEnv([functools.partial(_make_probe, recipe, images, audio)] * n, context="spawn")
    try:
        rng = np.random.default_rng(1)
        low, high = envs.single_action_space.low, envs.single_action_space.high
        envs.reset(seed=list(range(n)))
        for _ in range(3):  # every process past its first render
            envs.step(rng.uniform(low, high, (n, len(low))).astype(np.float32))
        t0 = time.perf_counter()
        for _ in range(steps):
            envs.step(rng.uniform(low, high, (n, len(low))).astype(np.float32))
        dt = time.perf_counter() - t0
        threads = envs.call("thread_names")[0]
    finally:
        envs.close()
    return n * steps / dt, threads


def _floor_worker(recipe: Any, steps: int, start: Any, out: Any) -> None:
    """One process: an env's world at its start pose, then the bare floor timed once every
    process is ready (`start`, a barrier); puts its wall seconds per step on `out`."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from timing import floor_times

    env = _make(recipe, True, False)
    env.reset(options={"index": 0})
    floor_times(env.world, 5)  # past the first render
    start.wait()
    out.put(floor_times(env.world, steps)[0])
    env.close()


def floor_processes(recipe: Any, n: int, steps: int) -> float:
    """Steps/s of the bare floor run in n spawned processes at once (all of them together)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    start, out = ctx.Barrier(n), ctx.Queue()
    procs = [ctx.Process(target=_floor_worker, args=(recipe, steps, start, out)) for _ in range(n)]
    for p in procs:
        p.start()
    walls = [out.get() for _ in procs]
    for p in procs:
        p.join()
    return float(sum(1.0 / w for w in walls))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "multi_event.yaml"))
    ap.add_argument("--n", type=int, action="append", help="envs in the vector env (repeat; default 2)")
    ap.add_argument("--steps", type=int, default=60, help="timed vector steps (one process: 3x as many steps)")
    ap.add_argument("--no-images", action="store_true")
    ap.add_argument("--no-audio", action="store_true")
    args = ap.parse_args()
    from echo_data.envs.listener import prefetch_enabled
    from echo_data.recipe import load_recipe

    recipe = load_recipe(args.recipe)
    images, audio = not args.no_images, not args.no_audio
    print(f"cores {os.cpu_count()}; images={images} audio={audio} prefetch={prefetch_enabled()}", flush=True)
    t = one_process(recipe, 3 * args.steps, images, audio)
    one = 1 / t.mean()
    ms = t * 1e3
    print(f"1 process   {one:7.1f} steps/s; step wall mean {ms.mean():.2f} ms, p50 {np.median(ms):.2f}, p90 {np.percentile(ms, 90):.2f}, p99 {np.percentile(ms, 99):.2f}", flush=True)
    for n in args.n or [2]:
        bound = t.mean() / slowest_of(t, n)
        sn, threads = vector(recipe, n, args.steps, images, audio)
        print(f"N = {n:2d} async {sn:7.1f} steps/s in all = {sn / n:6.1f} per env = {sn / (n * one):.2f} of N x one process"
              f" (stragglers alone bound it to {bound:.2f}); worker threads {sum(threads.values())}: {threads}", flush=True)
    if images:
        f1 = floor_processes(recipe, 1, 3 * args.steps)
        for n in args.n or [2]:
            fn = floor_processes(recipe, n, 3 * args.steps)
            print(f"floor       1 process {f1:7.1f} steps/s; {n} processes {fn:7.1f} steps/s in all = {fn / (n * f1):.2f} of N x one process"
                  " (the machine's own scaling: the async envs' share above is judged against it)", flush=True)


if __name__ == "__main__":
    main()
