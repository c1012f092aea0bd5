"""Expert success under DART action noise (`experts.action_noise`), as `echo-data trial` counts it.

    python studies/experts/expert_noise.py --levels 0 0.5 1 2 -n 10 --workers 2

Runs episodes 0..n-1 of the train split of each recipe at each noise level (the recipe with only
`experts.action_noise` changed) and writes `studies/experts/results/expert_noise.json`: per recipe
and level the episodes that succeeded, per skill, the failure reasons, with Wilson 95 %
intervals. Cameras are off (`observe=False`): the experts read the world, not the images, and
rendering changes no physics, so the outcomes are those `echo-data trial` reports.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

from echo_data.app.trial import run_trial
from echo_data.evaluation.metrics import wilson
from echo_data.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recipes", nargs="+", default=["recipes/object_relocation.yaml", "recipes/multi_event.yaml"])
    ap.add_argument("--levels", nargs="+", type=float, default=[0.0, 0.5, 1.0, 2.0])
    ap.add_argument("-n", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).with_name("results") / "expert_noise.json"))
    a = ap.parse_args()
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    results: dict[str, object] = {"commit": commit, "n": a.n, "command": "python studies/experts/expert_noise.py " + " ".join(
        ["--recipes", *a.recipes, "--levels", *map(str, a.levels), "-n", str(a.n)]), "runs": []}
    runs: list[dict[str, object]] = []
    results["runs"] = runs
    for path in a.recipes:
        base = load_recipe(ROOT / path)
        for level in a.levels:
            recipe = base.model_copy(update={"experts": base.experts.model_copy(update={"action_noise": level})})
            rep = run_trial(recipe, (ROOT / path).parent, a.n, workers=a.workers, observe=False)
            k = round(rep.success_rate * rep.episodes)
            lo, hi = wilson(k, rep.episodes)
            runs.append({
                "recipe": path, "action_noise": level, "episodes": rep.episodes, "successes": k,
                "success_rate": rep.success_rate, "wilson95": [lo, hi], "skills": rep.skills, "failures": rep.failures,
            })
            print(f"{path} noise {level}: {k}/{rep.episodes} [{lo:.2f}, {hi:.2f}] {rep.skills} {rep.failures}", flush=True)
            Path(a.out).parent.mkdir(parents=True, exist_ok=True)
            Path(a.out).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
