"""Where the build's Navigate hands over under `experts.handover_noise`, and whether it still succeeds.

    python studies/experts/handover_starts.py --recipes recipes/object_relocation.yaml recipes/state_transition.yaml --levels 0 0.5 1 -n 20

Runs the scripted Navigate alone (the first skill of train episodes 0..n-1, physics only, through
`run_episode` as the build does) with only `experts.handover_noise` changed, and writes
`studies/experts/results/handover_starts.json`: per level the Navigate successes (Wilson 95 %) and, at
the hand-over, the base's distance from the interaction point and its heading error to the target
(median and quartiles). docs/learners.md measured where a learned Navigate hands over (0.99 m
short, median) for comparison.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
from pathlib import Path

import numpy as np

from echo_data.agents.builtin import OraclePlanner, OracleSkills
from echo_data.agents.runtime import run_episode
from echo_data.envs.env import EchoDataEnv
from echo_data.evaluation.metrics import wilson
from echo_data.recipe import load_recipe
from echo_data.scene.nav import target_point
from echo_data.scene.sampling import SamplingError
from echo_data.skills.navigate import goal_pose

ROOT = Path(__file__).resolve().parents[2]


def quartiles(xs: list[float]) -> list[float] | None:
    return [round(float(q), 3) for q in np.percentile(xs, [25, 50, 75])] if xs else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recipes", nargs="+", default=["recipes/object_relocation.yaml", "recipes/state_transition.yaml"])
    ap.add_argument("--levels", nargs="+", type=float, default=[0.0, 1.0])
    ap.add_argument("-n", type=int, default=20)
    ap.add_argument("--out", default=str(Path(__file__).with_name("results") / "handover_starts.json"))
    a = ap.parse_args()
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    doc: dict[str, object] = {"commit": commit, "command": "python studies/experts/handover_starts.py " + " ".join(
        ["--recipes", *a.recipes, "--levels", *map(str, a.levels), "-n", str(a.n)]), "runs": []}
    for path in a.recipes:
        for level in a.levels:
            run_level(path, level, a.n, doc, a.out)


def run_level(path: str, level: float, n_episodes: int, doc: dict[str, object], out: str) -> None:
    """Navigate alone on train episodes 0..n_episodes-1 of `path` at one handover_noise level; appends a row to `doc`."""
    base = load_recipe(ROOT / path)
    recipe = base.model_copy(update={"experts": base.experts.model_copy(update={"handover_noise": level})})
    env = EchoDataEnv(recipe, split="train", images=False, audio=False, recipe_dir=(ROOT / path).parent)
    ok, dist, heading = 0, [], []
    n = 0
    try:
        for i in range(n_episodes):
            try:
                spec = env.sample_spec("train", i)
            except SamplingError:
                continue
            obs, info = env.reset(options={"spec": spec})
            call = spec.chain[0]
            exact = goal_pose(env.world, call.target, env.nav_grid())
            expert = OracleSkills()
            run = run_episode(env, obs, info, OraclePlanner(), expert, skills=1)
            expert.close()
            n += 1
            if not run.outcomes or not run.outcomes[0].success:
                continue
            ok += 1
            x, y, yaw = env.world.robot.base_pose()
            tx, ty = target_point(env.world.plan, call.target, env.world.door_angles() or None)
            dist.append(math.hypot(x - exact[0], y - exact[1]))
            heading.append(math.degrees(abs(math.remainder(math.atan2(ty - y, tx - x) - yaw, 2 * math.pi))))
    finally:
        env.close()
    lo, hi = wilson(ok, n)
    row = {"recipe": path, "handover_noise": level, "n": n, "successes": ok, "low": lo, "high": hi,
           "distance_m_quartiles": quartiles(dist), "heading_error_deg_quartiles": quartiles(heading)}
    doc["runs"].append(row)  # type: ignore[union-attr]
    print(json.dumps(row), flush=True)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
