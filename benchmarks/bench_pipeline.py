"""Seconds per control step of the full observation loop, as a ratio to bare SAPIEN step+render.

Floor (measured in the same run, same scene, same cameras): per control step, the
physics sub-steps of one control period, `update_render`, and `take_picture` + `get_picture`
of every robot camera — the floor no pipeline on SAPIEN can go under.
Measured against it:
  rollout   the expert chain with observations (planning, control, proprioception, images)
  episode   the whole episode: sampling + world build + rollout + binaural audio + features
  written   the episode plus its encoding for the dataset (PNG images, Parquet-ready columns)
A second floor: the same bare step+render driven by the rollout's own actions (`World.step` with
the recorded actions, cameras read back, nothing else): what physics of a moving robot in
contact with its world, and the views it sees on the way (a lavapipe picture costs what its view
holds), add to the standing robot of the first. The goal is judged against this one, as
`bench_env.py` judges the env step against the floor on its own path (docs/vector_envs.md).
and the written cost grouped by apartment size (rooms) and by number of sounding sources.
The floor is timed before and after each episode's stages (the median of those is used) and
the second floor over the whole episode, so a load that changes during the run moves the
floors with the stages. Each figure is given twice: wall-clock time, and this process's CPU time (`time.process_time`,
every thread of the process). On a machine shared with other jobs the wall-clock figures move
with the load; the CPU ratios say what a worker costs. Once-per-process costs (the renderer's
first picture, the HRTF table and its kernel bank) are paid before the clock starts and printed
on their own line: a build worker pays them once, not per episode.
Usage: python benchmarks/bench_pipeline.py [RECIPE] [-n EPISODES]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from timing import Clock, floor_row, floor_times, ratio_row, replay_times  # noqa: E402

from echo_data.recipe import load_recipe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FLOOR_STEPS = 200  # per episode: enough that the floor does not move with a moment's load


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "quickstart.yaml"))
    ap.add_argument("-n", type=int, default=3, help="episodes")
    args = ap.parse_args()

    from echo_data.acoustics.binaural import binaural_length
    from echo_data.acoustics.hrtf import Hrtf
    from echo_data.acoustics.types import AcousticResponse
    from echo_data.app.pipeline import generate_episode, simulate
    from echo_data.dataset.encode import encode_episode
    from echo_data.dataset.schema import StepLayout
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    recipe = load_recipe(args.recipe)
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    layout = StepLayout.from_recipe(recipe)
    clock = Clock()
    cfg = recipe.acoustics
    hrtf = Hrtf.load(cfg.hrtf, cfg.sample_rate)  # the table and its kernel bank: once per process
    binaural_length(AcousticResponse(hrtf.fs, [], np.zeros(0, dtype=np.float32), 1), hrtf)
    t_hrtf = clock.lap()[0]
    base: list[tuple[float, float]] = []
    rows: list[tuple[int, int, int, float, float]] = []  # (rooms, sources, steps, written wall, written CPU) per episode
    ncam = 0
    roll_steps = full_steps = 0
    roll = np.zeros(2)
    full = np.zeros(2)
    enc = np.zeros(2)
    t_first = 0.0
    moving = np.zeros(2)  # (wall, CPU) seconds of the replay floor, summed over episodes
    for i in range(args.n):
        spec, _ = sample_episode(recipe, "train", i, library)
        w = World(spec, recipe, render=True)
        clock = Clock()
        w.observe()  # first-render cost is not part of either measurement
        if i == 0:
            t_first = clock.lap()[0]
        base.append(floor_times(w, FLOOR_STEPS))
        ncam = len(w.robot.cameras)
        w.close()
        clock = Clock()
        ro = simulate(spec, recipe, observe=True)  # experts acting in the env, cameras, no ears
        roll += clock.lap()
        roll_steps += len(ro.steps)
        with World(spec, recipe, render=True) as w:
            w.observe()
            moving += np.array(replay_times(w, [s.action_executed for s in ro.steps])) * len(ro.steps)
        clock = Clock()
        res = generate_episode(recipe, "train", i, library)
        t1 = np.array(clock.lap())
        encode_episode(res, layout)
        t2 = np.array(clock.lap())
        with World(spec, recipe, render=True) as w:  # the floor again after the stages: a changing load moves both
            w.observe()
            base.append(floor_times(w, FLOOR_STEPS))
        full += t1
        enc += t2 - t1
        full_steps += len(res.steps)
        rows.append((len(spec.plan.rooms), len(spec.events), len(res.steps), float(t2[0]), float(t2[1])))
        print(f"episode {i}: {spec.setting:18s} rooms {len(spec.plan.rooms)} sources {len(spec.events)} steps {len(res.steps):4d} success {res.success}")
    b = (float(np.median([x[0] for x in base])), float(np.median([x[1] for x in base])))
    print(f"once per process (not in the figures below): HRTF table and kernels {t_hrtf:.1f} s, first render {t_first:.1f} s")
    print(f"floor     bare SAPIEN step+render ({ncam} cameras): {b[0] * 1e3:7.2f} ms/step              | CPU {b[1] * 1e3:7.2f} ms/step")
    m = moving / max(roll_steps, 1)
    print(floor_row(m[0], m[1], "same, driven by the rollout's actions:"))
    r = roll / max(roll_steps, 1)
    f = full / max(full_steps, 1)
    e = (full + enc) / max(full_steps, 1)
    print(ratio_row("rollout", "experts + observations:", r[0], r[1], b))
    print(ratio_row("episode", "sampling+world+rollout+audio:", f[0], f[1], b))
    print(ratio_row("written", "episode + dataset encoding:", e[0], e[1], b))
    print(ratio_row("", "the same against the driven floor:", e[0], e[1], (float(m[0]), float(m[1])), "  (goal <= 1.5x)"))
    for label, col in (("rooms", 0), ("sounding sources", 1)):
        for k in sorted({row[col] for row in rows}):
            sel = [row for row in rows if row[col] == k]
            steps = sum(row[2] for row in sel)
            wall, cpu = sum(row[3] for row in sel) / steps, sum(row[4] for row in sel) / steps
            print(ratio_row(f"by {label} = {k}:", f"{len(sel)} episodes, {steps} steps, written", wall, cpu, b))
    print(f"throughput: {(full[0] + enc[0]) / args.n:.1f} s/episode on one process, {full_steps / max(full[0] + enc[0], 1e-9):.1f} steps/s")


if __name__ == "__main__":
    main()
