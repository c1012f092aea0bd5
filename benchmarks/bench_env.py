"""Environment steps per second with every observation (cameras and audio), in 1 and 2 processes.

  floor    bare SAPIEN physics sub-steps + render + picture readback of the robot's cameras
           (`timing.floor_times`), in this process, on each episode's world at its start pose;
           and the same along the env's own path (`timing.replay_times`: the joint commands the
           timed steps gave `World.step`, replayed from the same reset), which the goal is
           measured against: on lavapipe a picture's cost depends on the view
  1 proc   `EchoDataEnv.step` in this process: physics, cameras, the control period heard
           online (`OnlineTrack`), its spectrogram and log-mel, the skills' success tests
  2 procs  `gymnasium.vector.AsyncVectorEnv` of two environments, each in its own process
           (what `gymnasium.make_vec(..., vectorization_mode="async")` builds): steps of both / s
Actions are seeded uniform draws from the action space; resets are not timed (an episode that
ends is reset and the clock paused). Goal: a step at most 1.3x the floor (on the path) in one process. Figures
are printed as `timing.ratio_row` prints them (wall-clock and process-CPU, each with its ratio):
on a machine shared with other jobs the CPU ratio says what a step costs. `ECHO_DATA_LISTENER=0`
hears in the caller's thread instead of the listening thread (to compare; docs/vector_envs.md).

  python benchmarks/bench_env.py [RECIPE] [--steps 200] [--episodes 2]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from timing import floor_row, ratio_row  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _make(recipe: object) -> object:
    from echo_data.envs import EchoDataEnv

    return EchoDataEnv(recipe, split="train")  # type: ignore[arg-type]


def one_process(recipe: object, steps: int, episodes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(seconds per EchoDataEnv.step in this process, floor at the start pose, floor on the
    env's own path) per step, each as (wall, CPU).

    The floor on the path replays the joint commands the env gave `World.step` in the timed
    steps, from the same reset, with the same picture reads: the same views rendered (a
    camera's cost on lavapipe depends on what it sees: on this recipe the start pose is
    cheaper than the random walk), without echo-data's observation, audio or success tests.
    """
    from timing import floor_times, replay_times

    env = _make(recipe)
    rng = np.random.default_rng(0)
    low, high = env.action_space.low, env.action_space.high  # type: ignore[attr-defined]
    spent, done, floor, path = np.zeros(2), 0, [], np.zeros(2)
    for ep in range(episodes):
        env.reset(options={"index": ep})  # type: ignore[attr-defined]
        floor.append(floor_times(env.world, 100))  # type: ignore[attr-defined]
        env.reset(options={"index": ep})  # type: ignore[attr-defined]
        world, sent = env.world, []  # type: ignore[attr-defined]
        world_step = world.step
        world.step = lambda a, _s=world_step, _r=sent: (_r.append(np.array(a, copy=True)), _s(a))[1]
        for _ in range(steps):
            a = rng.uniform(low, high).astype(np.float32)
            t0, c0 = time.perf_counter(), time.process_time()
            _, _, term, trunc, _ = env.step(a)  # type: ignore[attr-defined]
            spent += (time.perf_counter() - t0, time.process_time() - c0)
            done += 1
            if term or trunc:
                break
        world.step = world_step
        env.reset(options={"index": ep})  # type: ignore[attr-defined]
        path += np.array(replay_times(env.world, sent)) * len(sent)  # type: ignore[attr-defined]
    env.close()  # type: ignore[attr-defined]
    return spent / done, np.median(np.array(floor), axis=0), path / done


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
    step, floor, path = one_process(recipe, args.steps, args.episodes)
    one = 1 / step[0]
    print(floor_row(floor[0], floor[1]))
    print(floor_row(path[0], path[1], "same, on the env's own path:"))
    print(ratio_row("1 process", "EchoDataEnv.step, all observations:", step[0], step[1], tuple(floor)))
    print(ratio_row("", "the same against the path's floor:", step[0], step[1], tuple(path)))
    ratio = step[0] / path[0]
    print(f"          goal <= 1.3x the floor on the path: {'met' if ratio <= 1.3 else 'not met'} ({ratio:.2f}x wall, {step[1] / path[1]:.2f}x CPU;"
          f" {one:.1f} steps/s against the floor's {1 / path[0]:.1f})")
    two = two_processes(recipe, args.steps)
    print(f"2 procs   AsyncVectorEnv of 2:                {two:6.1f} steps/s in all = {two / one:4.2f}x one process")


if __name__ == "__main__":
    main()
