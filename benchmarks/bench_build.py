"""Build throughput: a slice of STMM-1.9K with 1 and with 2 workers, its serial parts, and validate.

Builds the first `--limit` episodes of each split (train, test) of `recipes/stmm_1_9k.yaml` (the
three settings of the paper's table interleaved by index, so any prefix keeps their proportions) once per worker count,
into a fresh folder each time, and prints per run: episodes/s, steps/s, bytes per step, the
projected hours for the whole recipe at that rate, and the time this process spent writing
(`DatasetWriter` store / flush / finalize: the serial, parent-side part). Then the speed-up of
2 workers over 1 (acceptance: >= 1.8x), `echo-data validate` of the last dataset and its ratio
to that dataset's build time (acceptance: <= 1/3). Last, the floor: bare SAPIEN physics + render
(`timing.bare_step_render`) on the slice's first episodes, and the hours the whole recipe
would take with each worker count if a step cost only that floor and the workers scaled
perfectly: no build on this machine can be faster, so it says what a target in hours means here.
Each run also prints the peak resident memory of its worker processes (`PeakMemory`: resident
set sampled every 0.2 s, the largest and the mean over the workers) and of this process (with
one worker the build runs in this process: then its high-water mark is the worker's).

  python benchmarks/bench_build.py [--limit 20] [--workers 1 2] [--recipe recipes/stmm_1_9k.yaml]

Timings on a machine shared with other work move with its load; the ratios are measured in
the same run, back to back.
"""

from __future__ import annotations

import argparse
import functools
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("LP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]


def _timed(cls: Any, names: tuple[str, ...], spent: dict[str, float]) -> None:
    """Wrap methods of `cls` to add their wall time to `spent` (this process only)."""
    for name in names:
        fn: Callable[..., Any] = getattr(cls, name)

        @functools.wraps(fn)
        def wrapper(*a: Any, _fn: Callable[..., Any] = fn, _name: str = name, **k: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return _fn(*a, **k)
            finally:
                spent[_name] = spent.get(_name, 0.0) + time.perf_counter() - t0

        setattr(cls, name, wrapper)


class PeakMemory:
    """Peak resident memory of this process's child processes (the build's workers), sampled on a
    thread while a build runs. Sampled, not the kernel's high-water mark, because the pool's workers
    are gone (and their /proc entries with them) by the time `build` returns; a 0.2 s period misses
    only spikes shorter than that."""

    def __init__(self, period_s: float = 0.2) -> None:
        import threading

        self.period_s = period_s
        self.peaks: dict[int, int] = {}  # pid -> largest resident set seen (bytes)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        import psutil

        me = psutil.Process()
        while not self._stop.is_set():
            for child in me.children(recursive=True):
                try:
                    if "resource_tracker" in " ".join(child.cmdline()):  # multiprocessing's helper, not a worker
                        continue
                    rss = child.memory_info().rss
                except psutil.Error:  # gone between listing and reading
                    continue
                self.peaks[child.pid] = max(self.peaks.get(child.pid, 0), rss)
            self._stop.wait(self.period_s)

    def __enter__(self) -> PeakMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def line(self) -> str:
        import resource

        parent = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
        if not self.peaks:  # one worker runs the episodes in this process
            return f"peak memory per worker: {parent:.0f} MiB (the one worker is this process: its high-water mark so far)"
        mib = [v / 2**20 for v in self.peaks.values()]
        return (f"peak memory per worker: {max(mib):.0f} MiB largest, {sum(mib) / len(mib):.0f} MiB mean over "
                f"{len(mib)} worker process(es) (resident set, sampled every {self.period_s:g} s); this process {parent:.0f} MiB")


def _floor_ms(recipe: Any, recipe_dir: Path, episodes: int = 3, steps: int = 50) -> float:
    """Mean bare step + render cost (ms per control step) on the recipe's first train episodes."""
    from timing import bare_step_render

    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    library = SoundLibrary.from_recipe(recipe, recipe_dir)
    costs = []
    for i in range(episodes):
        spec, _ = sample_episode(recipe, "train", i, library)
        world = World(spec, recipe, render=True)
        world.observe()  # the first render's set-up is not part of the floor (as in bench_pipeline)
        try:
            costs.append(bare_step_render(world, steps))
        finally:
            world.close()
    return 1e3 * sum(costs) / len(costs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recipe", default=str(ROOT / "recipes" / "stmm_1_9k.yaml"))
    ap.add_argument("--limit", type=int, default=20, help="episodes per split (2 splits: 20 -> 40 episodes)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--keep", type=Path, default=None, help="keep the datasets under this folder")
    args = ap.parse_args()

    from echo_data.app.build import build
    from echo_data.dataset.manifest import split_sizes
    from echo_data.dataset.validate import validate
    from echo_data.dataset.writer import DatasetWriter
    from echo_data.recipe import load_recipe

    recipe = load_recipe(args.recipe)
    whole = sum(split_sizes(recipe, None).values())
    spent: dict[str, float] = {}
    _timed(DatasetWriter, ("store", "flush", "finalize"), spent)
    base = Path(tempfile.mkdtemp(prefix="bench_build_")) if args.keep is None else args.keep
    rates: dict[int, float] = {}
    last: tuple[Path, float] | None = None
    try:
        for w in args.workers:
            out = base / f"w{w}"
            if out.exists():
                shutil.rmtree(out)
            spent.clear()
            t0 = time.perf_counter()
            with PeakMemory() as memory:
                s = build(recipe, Path(args.recipe), out, workers=w, limit=args.limit, progress=False)
            dt = time.perf_counter() - t0
            n, steps = sum(s.episodes.values()), sum(s.steps.values())
            rates[w] = n / dt
            serial = sum(spent.values())
            parts = ", ".join(f"{k} {v:.1f} s" for k, v in spent.items())
            print(
                f"workers {w}: {n} episodes, {steps} steps in {dt:.1f} s: {n / dt:.3f} episodes/s, {steps / dt:.1f} steps/s, "
                f"{s.bytes / steps / 1e3:.1f} KB/step; whole {recipe.name} ({whole} episodes) at this rate: {whole / rates[w] / 3600:.2f} h; "
                f"parent-side writing {serial:.1f} s ({serial / dt:.0%} of the build: {parts})"
            )
            print(f"  {memory.line()}")
            last = (out, dt)
        if 1 in rates:
            for w, r in rates.items():
                if w != 1:
                    print(f"speed-up {w} workers / 1: {r / rates[1]:.2f}x (acceptance for 2: >= 1.8x)")
        if last is not None:
            t0 = time.perf_counter()
            problems = validate(last[0])
            v = time.perf_counter() - t0
            print(f"validate {last[0].name}: {v:.1f} s = {v / last[1]:.2f} of its build time (acceptance <= 0.33); {len(problems)} problem(s)")
            for p in problems[:5]:
                print("  ", p)
        floor = _floor_ms(recipe, Path(args.recipe).resolve().parent)
        per_episode = steps / n
        for w in args.workers:
            print(f"floor: {floor:.2f} ms per step (bare SAPIEN step + render, same run); whole {recipe.name} at the floor with "
                  f"{w} worker(s): {whole * per_episode * floor / 1e3 / w / 3600:.2f} h ({per_episode:.0f} steps per episode)")
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
