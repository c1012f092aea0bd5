"""Seconds per control step of the full observation loop, as a ratio to bare SAPIEN step+render.

Floor (measured in the same run, same scene, same cameras): per control step, the
physics sub-steps of one control period, `update_render`, and `take_picture` + `get_picture`
of every robot camera — the floor no pipeline on SAPIEN can go under.
Measured against it:
  rollout   the expert chain with observations (planning, control, proprioception, images)
  episode   the whole episode: sampling + world build + rollout + binaural audio + features
  written   the episode plus its encoding for the dataset (PNG images, Parquet-ready columns)
and the written cost grouped by apartment size (rooms) and by number of sounding sources.
Usage: python benchmarks/bench_pipeline.py [RECIPE] [-n EPISODES]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from echo_data.recipe import load_recipe  # noqa: E402
from echo_data.robot.robot import COLOR_PICTURE, POSITION_PICTURE  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def bare_step_render(world: object, steps: int) -> float:
    """Seconds per control step of physics + render + picture readback only."""
    scene = world.scene  # type: ignore[attr-defined]
    cams = [comp for comp, _ in world.robot.cameras.values()]  # type: ignore[attr-defined]
    names = {id(comp): cfg for comp, cfg in world.robot.cameras.values()}  # type: ignore[attr-defined]
    t0 = time.perf_counter()
    for _ in range(steps):
        for _ in range(world.substeps):  # type: ignore[attr-defined]
            scene.step()
        scene.update_render()
        for c in cams:
            c.take_picture()
            cfg = names[id(c)]
            if cfg.rgb:
                c.get_picture(COLOR_PICTURE)
            if cfg.depth:
                c.get_picture(POSITION_PICTURE)
    return (time.perf_counter() - t0) / steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "quickstart.yaml"))
    ap.add_argument("-n", type=int, default=3, help="episodes")
    args = ap.parse_args()

    from echo_data.app.pipeline import generate_episode, simulate
    from echo_data.dataset.encode import encode_episode
    from echo_data.dataset.schema import StepLayout
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    recipe = load_recipe(args.recipe)
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    layout = StepLayout.from_recipe(recipe)
    base: list[float] = []
    rows: list[tuple[int, int, int, float]] = []  # (rooms, sources, steps, written seconds) per episode
    ncam = 0
    roll_steps = full_steps = 0
    t_roll = t_full = t_enc = 0.0
    for i in range(args.n):
        spec, _ = sample_episode(recipe, "train", i, library)
        w = World(spec, recipe, render=True)
        w.observe()  # first-render cost is not part of either measurement
        base.append(bare_step_render(w, 50))
        ncam = len(w.robot.cameras)
        w.close()
        t0 = time.perf_counter()
        ro = simulate(spec, recipe, observe=True)  # experts acting in the env, cameras, no ears
        t_roll += time.perf_counter() - t0
        roll_steps += len(ro.steps)
        t0 = time.perf_counter()
        res = generate_episode(recipe, "train", i, library)
        t1 = time.perf_counter()
        encode_episode(res, layout)
        t2 = time.perf_counter()
        t_full += t1 - t0
        t_enc += t2 - t1
        full_steps += len(res.steps)
        rows.append((len(spec.plan.rooms), len(spec.events), len(res.steps), t2 - t0))
        print(f"episode {i}: {spec.setting:18s} rooms {len(spec.plan.rooms)} sources {len(spec.events)} steps {len(res.steps):4d} success {res.success}")
    b = float(np.median(base))
    r = t_roll / max(roll_steps, 1)
    f = t_full / max(full_steps, 1)
    print(f"floor     bare SAPIEN step+render ({ncam} cameras): {b * 1e3:7.2f} ms/step")
    print(f"rollout   experts + observations:          {r * 1e3:7.2f} ms/step  ratio {r / b:5.2f}x")
    print(f"episode   sampling+world+rollout+audio:    {f * 1e3:7.2f} ms/step  ratio {f / b:5.2f}x")
    e = (t_full + t_enc) / max(full_steps, 1)
    print(f"written   episode + dataset encoding:      {e * 1e3:7.2f} ms/step  ratio {e / b:5.2f}x  (acceptance <= 1.5x, goal 1.3x)")
    for label, col in (("rooms", 0), ("sounding sources", 1)):
        for k in sorted({row[col] for row in rows}):
            sel = [row for row in rows if row[col] == k]
            steps, secs = sum(row[2] for row in sel), sum(row[3] for row in sel)
            print(f"by {label} = {k}: {len(sel)} episodes, {steps} steps, written {secs / steps * 1e3:7.2f} ms/step  ratio {secs / steps / b:5.2f}x")
    print(f"throughput: {(t_full + t_enc) / args.n:.1f} s/episode on one process, {full_steps / max(t_full + t_enc, 1e-9):.1f} steps/s")


if __name__ == "__main__":
    main()
