"""Where the written stage's time goes: per-step wall and CPU of the pipeline's parts, one warm process.

Wraps the functions named below with timers, warms the process (HRTF table, first render,
mplib import), then generates and encodes the given train episodes of a recipe as the build
does, and prints each part's milliseconds per control step (parts nest: `EchoDataEnv.step`
holds the camera read-out, the audio, the features and `World.step`). Run it for two code
versions one after the other (or alternately, several times) to compare them on a shared machine.

  python benchmarks/bench_parts.py [RECIPE] [--episodes 2] [--first 1]
"""

from __future__ import annotations

import argparse
import functools
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("LP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]


def _wrap(owner: Any, name: str, label: str, spent: dict[str, float], calls: dict[str, int]) -> None:
    fn: Callable[..., Any] = getattr(owner, name)

    @functools.wraps(fn)
    def timed(*a: Any, **k: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            spent[label] = spent.get(label, 0.0) + time.perf_counter() - t0
            calls[label] = calls.get(label, 0) + 1

    setattr(owner, name, timed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "multi_event.yaml"))
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--first", type=int, default=1, help="first train index")
    args = ap.parse_args()

    import mplib  # noqa: F401  (imported once per process by the experts)
    import sapien

    from echo_data.acoustics import features, noise, stream
    from echo_data.acoustics.hrtf import Hrtf
    from echo_data.app.pipeline import generate_episode
    from echo_data.dataset import encode
    from echo_data.dataset.schema import StepLayout
    from echo_data.envs.env import EchoDataEnv
    from echo_data.recipe import load_recipe
    from echo_data.robot.robot import Robot
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    spent: dict[str, float] = {}
    calls: dict[str, int] = {}
    for cls, name in [
        (EchoDataEnv, "step"), (EchoDataEnv, "reset"), (EchoDataEnv, "_evaluate"), (Robot, "observe"), (Robot, "state"),
        (World, "step"), (sapien.Scene, "step"), (stream.StreamRenderer, "step"), (stream.RirCache, "rir"),
        (stream.RirCache, "response"), (features.FeatureStream, "features"), (noise.NoiseFloor, "render"),
    ]:
        _wrap(cls, name, f"{cls.__name__}.{name}", spent, calls)
    for name in ("encode_episode", "encode_png"):
        _wrap(encode, name, name, spent, calls)

    recipe = load_recipe(args.recipe)
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    layout = StepLayout.from_recipe(recipe)
    Hrtf.load(recipe.acoustics.hrtf, recipe.acoustics.sample_rate)
    spec, _ = sample_episode(recipe, "train", args.first, library)
    with World(spec, recipe) as w:
        w.observe()  # the renderer's first picture
    spent.clear()
    calls.clear()
    steps, wall, cpu = 0, time.perf_counter(), time.process_time()
    for i in range(args.first, args.first + args.episodes):
        res = generate_episode(recipe, "train", i, library)
        encode.encode_episode(res, layout)
        steps += len(res.steps)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(f"{steps} steps: {1e3 * wall / steps:.2f} ms/step wall, {1e3 * cpu / steps:.2f} ms/step process CPU")
    for k, v in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"  {k:30s} {1e3 * v / steps:7.3f} ms/step wall  {calls[k] / steps:6.2f} calls/step")


if __name__ == "__main__":
    main()
