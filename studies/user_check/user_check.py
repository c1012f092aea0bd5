"""The user check: does a learner trained with `echo-data train`'s defaults, on a fresh 60-episode
build of a home seed nobody tuned on, complete its skill after the expert's hand-over?

It runs, as a new user would, only the README's three commands ("Training a skill") through the
CLI: `build` the recipe's train split, `train act DATA --skill SKILL` with no option but where to
write, the seed and the device (every other option is the skill's default, echo_data/learn/defaults.py),
and `evaluate` the recipe's test split with the learner for SKILL and the experts (the oracle
planner and Navigate) for the rest. It writes studies/user_check/results/user_check.json: the
commands, the commit, the seeds, each step's wall time, the options the training resolved, and
SKILL's successes over its attempts with the Wilson 95 % interval.

Resumable: a complete build is reused (an unfinished one resumed), a finished training (its
record in WORK) is reused (an unfinished run folder trained again), an evaluation's JSON is
reused (its journal resumed).

Usage:
  python studies/user_check/user_check.py                     # Pick, 50 test episodes (hours on 2 cores)
  python studies/user_check/user_check.py --render            # only re-render this README's results block
  python studies/user_check/user_check.py --recipe R --tiny --work W --out J   # the test's path: 1 epoch, no closed-loop choice
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # runner.py
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's echo_data
from runner import ROOT, cli, commit  # noqa: E402

from echo_data.dataset.storage import atomic_write_json  # noqa: E402
from echo_data.evaluation.table import interval, skill_success  # noqa: E402
from echo_data.learn import runs  # noqa: E402
from echo_data.learn.defaults import RESOLVED  # noqa: E402
from echo_data.recipe import load_recipe  # noqa: E402

HERE = Path(__file__).resolve().parent
RECIPE = HERE / "recipes" / "user_check.yaml"
RESULTS = HERE / "results" / "user_check.json"
WORK = Path("out/user_check")
# The test's path: 1 epoch, no closed-loop choice (it would render validation episodes), a small ACT
# at the stored image size (its evaluation acts at a fraction of the default network's cost).
TINY = ("--epochs", "1", "--select-every", "0", "--d-model", "32", "--heads", "2", "--layers", "1", "--image-size", "0")


def shown(p: Path | str) -> str:
    """A path as commands and the JSON show it: relative to the checkout when inside it."""
    q = Path(p)
    a = q if q.is_absolute() else ROOT / q
    return str(a.relative_to(ROOT)) if a.is_relative_to(ROOT) else str(q)


def commands(recipe: Path | str, work: Path, skill: str, episodes: int, seed: int | None = None, device: str | None = None,
             workers: int | None = None, tiny: bool = False) -> dict[str, list[str]]:
    """The README's three commands (build, train, evaluate) for `skill` with these paths: what a
    user types. Options left unset are not passed (a user's defaults)."""
    data, run = work / "data", work / "runs" / skill
    many = ["--workers", str(workers)] if workers else []
    return {
        "build": ["build", shown(recipe), "--split", "train", *many, "--out", shown(data)],
        "train": ["train", "act", shown(data), "--skill", skill, *(["--seed", str(seed)] if seed is not None else []),
                  *(["--device", device] if device else []), *(TINY if tiny else ()), "--out", shown(run)],
        "evaluate": ["evaluate", shown(recipe), "--split", "test", "-n", str(episodes), "--policy", f"{skill}={shown(run)}", "--policy", "oracle",
                     "--planner", "oracle", *many, "--json", shown(work / f"eval-{skill}.json")],
    }


def step(name: str, args: list[str], done: bool, work: Path, extra: list[str] | None = None) -> dict[str, Any]:
    """Run `echo-data ARGS EXTRA` unless `done`; the step's record, kept in WORK/step-NAME.json (NAME:
    build, train-SKILL, evaluate-SKILL) and reused with `done`: its command as typed (a work folder
    outside the checkout shown as WORK: no machine paths in results), its wall seconds (None: done
    before, by no run of this script)."""
    kept = work / f"step-{name}.json"
    if done:
        return {**json.loads(kept.read_text()), "reused": True} if kept.is_file() else {"command": None, "seconds": None, "reused": True}
    typed = " ".join([*args, *(extra or [])])
    if not work.is_relative_to(ROOT):
        typed = typed.replace(str(work), "WORK")
    out, seconds = cli(*args, *(extra or []))
    record = {"command": "echo-data " + typed, "seconds": round(seconds, 1), "reused": False, **({"summary": json.loads(out)} if name.startswith("train") else {})}
    atomic_write_json(kept, record)  # (its folder made too)
    return record


def measure(a: argparse.Namespace) -> dict[str, Any]:
    """Build, train and evaluate (each reused when done); the results document."""
    cmd = commands(a.recipe, a.work, a.skill, a.episodes, a.seed, a.device, a.workers, a.tiny)
    work = a.work if a.work.is_absolute() else ROOT / a.work  # the commands run from the checkout
    data, run, evaluated = work / "data", work / "runs" / a.skill, work / f"eval-{a.skill}.json"
    steps: dict[str, Any] = {}
    manifest = data / "manifest.json"
    complete = manifest.is_file() and bool(json.loads(manifest.read_text()).get("complete"))
    steps["build"] = step("build", cmd["build"], complete, work, ["--resume"] if manifest.is_file() and not complete else None)
    # written once the training finished: a run folder without it is unfinished; data built (further) now is trained on again
    trained = (work / f"step-train-{a.skill}.json").is_file() and steps["build"]["reused"]
    journal = evaluated.with_suffix(".episodes.jsonl")
    if not trained:  # trained again: nothing evaluated with other weights is kept
        shutil.rmtree(run, ignore_errors=True)
        for old in (evaluated, journal, work / f"step-evaluate-{a.skill}.json"):
            old.unlink(missing_ok=True)
    steps["train"] = step(f"train-{a.skill}", cmd["train"], trained, work)
    steps["evaluate"] = step(f"evaluate-{a.skill}", cmd["evaluate"], evaluated.is_file(), work, ["--resume"] if journal.is_file() and not evaluated.is_file() else None)
    doc = json.loads(evaluated.read_text())
    config = runs.read_json(run / runs.CONFIG)
    _, weights = runs.load_weights(run)
    acted = doc.get("weights", {}).get("skills", {}).get(a.skill)
    sha = runs.file_sha256(weights)
    if acted != sha:
        sys.exit(f"{shown(evaluated)}: {a.skill} acted with weights {acted}, not the run's {shown(weights)} ({sha}): evaluate again (remove the JSON)")
    tried = skill_success(doc["episodes"], a.skill)
    recipe = load_recipe(a.recipe if a.recipe.is_absolute() else ROOT / a.recipe)
    return {
        "what": f"{a.skill} learned with `echo-data train act`'s defaults from a fresh build of {shown(a.recipe)}'s train split, scored on its "
                f"test split (test sounds) after the expert's Navigate, the oracle planner and experts for the other skills; Wilson 95 %.",
        "command": ("python studies/user_check/user_check.py" + "".join(f" {x}" for x in sys.argv[1:])).replace(str(work), "WORK"),
        "commit": commit(),
        "recipe": {"path": shown(a.recipe), "sha256": recipe.content_hash(), "seed": recipe.seed, "splits": dict(recipe.splits)},
        "seeds": {"recipe": recipe.seed, "training": int(config["seed"])},
        "skill": a.skill,
        "episodes": a.episodes,
        "commands": {k: v["command"] for k, v in steps.items()},
        "seconds": {k: v["seconds"] for k, v in steps.items()},
        "reused": [k for k, v in steps.items() if v["reused"]],
        "training": {"options": {k: config[k] for k in RESOLVED}, "algo": config["algo"], "weights": shown(weights).replace(str(work), "WORK"), "weights_sha256": sha,
                     "best_val_success": steps["train"].get("summary", {}).get("best_val_success")},
        "result": {**interval(tried["k"], tried["n"]), "skipped": sum("skipped" in e for e in doc["episodes"]), "weights_sha256": acted},
    }


def render_readme() -> None:
    """This README's results block from the committed JSON (studies/results_tables.py)."""
    import results_tables

    for study, name, results, render in results_tables.COPIES:
        if study == "user_check":
            readme = HERE / "README.md"
            begin, end = results_tables.markers(name, results)
            readme.write_text(results_tables.with_block(readme.read_text(), begin, end, render(json.loads((HERE / "results" / results).read_text()))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--skill", default="Pick", help="the skill learned (default Pick); the experts do the others")
    ap.add_argument("--episodes", type=int, default=50, help="test episodes evaluated (default 50)")
    ap.add_argument("--work", type=Path, default=WORK, help=f"where the build, the run and the evaluation go (default {WORK})")
    ap.add_argument("--recipe", type=Path, default=RECIPE, help=f"the recipe built and evaluated (default {shown(RECIPE)})")
    ap.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    ap.add_argument("--device", default=None, help="train --device (default: the CLI's)")
    ap.add_argument("--workers", type=int, default=None, help="build and evaluate --workers (default: the CLI's)")
    ap.add_argument("--tiny", action="store_true", help=f"train with {' '.join(TINY)} added (the test's path; not the user's defaults)")
    ap.add_argument("--out", type=Path, default=RESULTS, help=f"results JSON (default {shown(RESULTS)}, which the README renders)")
    ap.add_argument("--render", action="store_true", help="only re-render this README's results block from the committed JSON")
    a = ap.parse_args()
    if a.render:
        render_readme()
        return
    if a.episodes < 1 or (a.workers is not None and a.workers < 1):
        ap.error("--episodes and --workers must be >= 1")
    # One torch thread in every command (training's default already): evaluate's learner otherwise
    # runs on every core, whose spinning on a shared machine cost several times the CPU (measured
    # on one test episode here), and a thread count of its own makes the episodes the same anywhere.
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    doc = {**measure(a), "environment": {"OMP_NUM_THREADS": os.environ["OMP_NUM_THREADS"]}}
    atomic_write_json(a.out, doc)
    print(json.dumps(doc["result"]))
    if a.out.resolve() == RESULTS:
        render_readme()


if __name__ == "__main__":
    main()
