"""Environment steps per second with every observation (cameras and audio), in 1 and 2 processes.

  floor    bare SAPIEN physics sub-steps + render + picture readback of the robot's cameras
           (`bench_pipeline.bare_step_render`), in this process, on the first episode's world
  1 proc   `EchoDataEnv.step` in this process: physics, cameras, the control period heard
           online (`OnlineTrack`), its spectrogram and log-mel, the skills' success tests
  2 procs  `gymnasium.vector.AsyncVectorEnv` of two environments, each in its own process
           (what `gymnasium.make_vec(..., vectorization_mode="async")` builds): steps of both / s
Actions are seeded uniform draws from the action space; resets are not timed (an episode that
ends is reset and the clock paused). Acceptance: >= 100 steps/s in one process; no environment
step can be faster than the floor, so the floor's own steps/s is printed beside the target (on a
2-core machine rendering on the CPU it is below 100). Wall-clock and process-CPU figures are both
printed: on a machine shared with other jobs the CPU ratio says what a step costs.

  python benchmarks/bench_env.py [RECIPE] [--steps 200] [--episodes 2]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _make(recipe: object) -> object:
    from echo_data.envs import EchoDataEnv

    return EchoDataEnv(recipe, split="train")  # type: ignore[arg-type]


def one_process(recipe: object, steps: int, episodes: int) -> tuple[np.ndarray, np.ndarray]:
    """(seconds per EchoDataEnv.step in this process, floor seconds per step), each as (wall, CPU)."""
    from bench_pipeline import floor_times

    env = _make(recipe)
    rng = np.random.default_rng(0)
    low, high = env.action_space.low, env.action_space.high  # type: ignore[attr-defined]
    spent, done, floor = np.zeros(2), 0, []
    for ep in range(episodes):
        env.reset(options={"index": ep})  # type: ignore[attr-defined]
        floor.append(floor_times(env.world, 100))  # type: ignore[attr-defined]
        env.reset(options={"index": ep})  # type: ignore[attr-defined]
        for _ in range(steps):
            a = rng.uniform(low, high).astype(np.float32)
            t0, c0 = time.perf_counter(), time.process_time()
            _, _, term, trunc, _ = env.step(a)  # type: ignore[attr-defined]
            spent += (time.perf_counter() - t0, time.process_time() - c0)
            done += 1
            if term or trunc:
                break
    env.close()  # type: ignore[attr-defined]
    return spent / done, np.median(np.array(floor), axis=0)


def two_processes(recipe: object, steps: int) -> float:
    """Steps/s of both environments of an async vector env over two processes."""
    import functools

    import gymnasium as gym

    envs = gym.vector.AsyncVectorEnv([functools.partial(_make, recipe)] * 2, context="spawn")
    rng = np.random.default_rng(1)
    low, high = envs.single_action_space.low, envs.single_action_space.high
    envs.reset(seed=[0, 1])
    envs.step(rng.uniform(low, high, (2, len(low))).astype(np.float32))  # every process past its first render
    t0 = time.perf_counter()
    for _ in range(steps):
        envs.step(rng.uniform(low, high, (2, len(low))).astype(np.float32))
    dt = time.perf_counter() - t0
    envs.close()
    return 2 * steps / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "multi_event.yaml"))
    ap.add_argument("--steps", type=int, default=200, help="steps per episode / per vector step loop")
    ap.add_argument("--episodes", type=int, default=2)
    args = ap.parse_args()

    from echo_data.recipe import load_recipe

    recipe = load_recipe(args.recipe)
    step, floor = one_process(recipe, args.steps, args.episodes)
    one = 1 / step[0]
    print(f"floor     bare SAPIEN step+render:            {floor[0] * 1e3:7.2f} ms/step = {1 / floor[0]:6.1f} steps/s | CPU {floor[1] * 1e3:7.2f} ms/step")
    print(f"1 process EchoDataEnv.step, all observations: {step[0] * 1e3:7.2f} ms/step = {one:6.1f} steps/s  ratio {step[0] / floor[0]:5.2f}x the floor"
          f" | CPU {step[1] * 1e3:7.2f} ms/step  ratio {step[1] / floor[1]:5.2f}x")
    verdict = "met" if one >= 100 else "not met" + (": the floor itself is below it on this machine" if 1 / floor[0] < 100 else "")
    print(f"          acceptance >= 100 steps/s: {verdict} (floor {1 / floor[0]:.1f} steps/s; the step reaches {floor[0] / step[0]:.0%} of the floor's rate)")
    two = two_processes(recipe, args.steps)
    print(f"2 procs   AsyncVectorEnv of 2:                {two:6.1f} steps/s in all = {two / one:4.2f}x one process")


if __name__ == "__main__":
    main()
