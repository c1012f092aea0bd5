"""Navigate from sound without cameras (issue 29's goal row "Navigate from audio without depth"),
closed loop: build the camera-free Navigate data, train each candidate learner on the binaural
audio (each ear's level and their difference), base-frame proprioception and the target's kind
(the skill's argument: which object the planner sent it to), choose the learner closed loop on
the validation split, then score the chosen one on the test split (test sounds).

Nothing is rendered in the build or in evaluation (studies/paper_table/recipes/nav_audio.yaml has both
cameras off): the learner reads no image, so its actions are what they would be with cameras.
The test row is "Navigate alone" as studies/paper_table/paper_table.py scores it: the learner drives
Navigate, the scripted experts every skill after it; success = Navigate's success test over its
attempts (one per episode: object relocation and state transition, 50 test episodes each).

Resumable like studies/learners/sanity_learners.py, whose helpers it uses: a complete dataset is not
built again, a run folder with a summary.json is not trained again, an evaluation with its JSON
is not run again.

Usage:
  python studies/learners/navigate_from_sound.py --workers 2 --work WORK
  python studies/learners/navigate_from_sound.py --learners bc-rnn --work WORK   # one candidate
  python studies/learners/navigate_from_sound.py --tiny --work /tmp/n --out /tmp/n.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from sanity_learners import (  # noqa: E402
    SPENT,
    TINY_EPISODES,
    best_run,
    best_val_success,
    commit,
    echo_data,
    machine,
    public,
    score,
    shown,
)

RECIPE = ROOT / "studies" / "paper_table" / "recipes" / "nav_audio.yaml"
SKILL = "Navigate"
INPUTS = ("--inputs", "audio,state,kind", "--audio-form", "level_ild")
# The recipe acts in ee_delta (studies/paper_table/recipes/sanity.yaml), so the learners clone that form's column.
COLUMN = "action.ee"
# Candidates, each with its own options: a GRU over the skill's steps (memory: where the sound
# was), the memoryless MLP, ACT's chunks. The one with the best closed-loop validation is tested.
LEARNERS: dict[str, tuple[str, str]] = {
    "bc-rnn": ("bc-rnn", "--epochs 20 --select-every 5"),
    "bc": ("bc", "--epochs 30 --select-every 10"),
    "act": ("act", "--epochs 20 --select-every 10"),
}


def usage_error(message: str) -> None:
    """Bad input: one line naming this driver, exit 2, nothing written."""
    print(f"navigate_from_sound.py: {message}", file=sys.stderr)
    sys.exit(2)


def build(work: Path, workers: int, tiny: bool, log: Path) -> dict[str, Any]:
    """The recipe's train split in WORK/data/nav_audio (resumed when incomplete, kept when complete)."""
    out = work / "data" / "nav_audio"
    manifest = out / "manifest.json"
    args = ["build", str(RECIPE), "--split", "train", "--workers", str(workers), "--out", str(out), "--no-progress"]
    if tiny:
        args += ["--limit", str(TINY_EPISODES)]
    seconds = 0.0
    if not (manifest.is_file() and json.loads(manifest.read_text()).get("complete")):
        _, seconds = echo_data(args + (["--resume"] if manifest.is_file() else []), log)
    meta = json.loads(manifest.read_text())
    return {"command": shown(args, work), "seconds": round(seconds, 1), "episodes": meta["counts"]["episodes"], "skills": meta.get("skills", {})}


def train(learner: str, data: Path, a: argparse.Namespace, log: Path) -> dict[str, Any]:
    """`echo-data train` of one candidate unless its run folder holds this driver's summary."""
    folder = a.work / "runs" / f"{SKILL}-{learner}"
    done = folder / "summary.json"
    if done.is_file():
        return {**json.loads(done.read_text()), "reused": True}
    algo, options = LEARNERS[learner]
    tiny = ["--epochs", "1", "--select-every", "1"] if a.tiny else []
    args = ["train", algo, str(data), "--skill", SKILL, *INPUTS, "--action-column", COLUMN, *options.split(), *tiny,
            "--select-episodes", str(a.select_episodes), "--device", a.device, "--seed", str(a.seed),
            "--out", str(folder), "--no-progress", *(["--overwrite"] if folder.exists() else [])]
    stdout, seconds = echo_data(args, log)
    summary = json.loads(stdout)
    entry = {"command": shown(args, a.work), "seconds": round(seconds, 1), "run": folder.name, "learner": learner,
             "steps": summary.get("step"), "rows": summary.get("rows"), "best_val_success": best_val_success(folder)}
    done.write_text(json.dumps(entry, indent=1) + "\n")
    return entry


def evaluate(run: str, a: argparse.Namespace, log: Path) -> dict[str, Any]:
    """The chosen run closed loop on the test split: Navigate's k/n (Wilson 95 %), SPL, the command."""
    out = a.work / "eval" / f"{run}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    args = ["evaluate", str(RECIPE), "--split", "test", "-n", str(a.episodes), f"--policy={SKILL}={a.work / 'runs' / run}",
            "--policy", "oracle", "--planner", "oracle", "--workers", str(a.workers), "--json", str(out)]
    seconds = 0.0
    if not out.is_file():
        _, seconds = echo_data(args + (["--resume"] if out.with_suffix(".episodes.jsonl").is_file() else []), log)
    doc = json.loads(out.read_text())
    by_setting = {s: score([e for e in doc["episodes"] if e.get("setting") == s], SKILL) for s in sorted({e.get("setting") for e in doc["episodes"]})}
    spl = doc["metrics"]["all"].get("navigate_spl", {})
    return {"navigate": score(doc["episodes"], SKILL), "by_setting": by_setting, "spl": round(float(spl.get("value", 0.0)), 4),
            "command": shown(args, a.work), "seconds": round(seconds, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=2, help="build and evaluation worker processes")
    ap.add_argument("--work", type=Path, default=ROOT / "out" / "navigate_from_sound", help="dataset, run folders, evaluation JSONs, log")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("results") / "navigate_from_sound.json")
    ap.add_argument("-n", "--episodes", type=int, default=100, help="test episodes (half object relocation, half state transition)")
    ap.add_argument("--learners", default=",".join(LEARNERS), help=f"comma list of {', '.join(LEARNERS)}: each trained, the best on validation tested")
    ap.add_argument("--select-episodes", type=int, default=10, help="validation episodes per checkpoint choice")
    ap.add_argument("--device", default="auto")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tiny", action="store_true", help=f"{TINY_EPISODES} train episodes, 1 epoch, 1 val and 2 test episodes: the path in minutes")
    a = ap.parse_args()
    learners = [k.strip() for k in a.learners.split(",") if k.strip()]
    if not learners or any(k not in LEARNERS for k in learners):
        usage_error(f"--learners {a.learners!r}: each must be one of {', '.join(LEARNERS)}")
    if a.workers < 1 or a.episodes < 1 or a.select_episodes < 1:
        usage_error("--workers, --episodes and --select-episodes must be >= 1")
    if a.tiny:
        a.episodes, a.select_episodes = 2, 1
    a.work = a.work.resolve()
    a.work.mkdir(parents=True, exist_ok=True)
    log = a.work / "navigate_from_sound.log"
    t0 = time.perf_counter()
    data = build(a.work, a.workers, a.tiny, log)
    trained = {k: train(k, a.work / "data" / "nav_audio", a, log) for k in learners}
    chosen = best_run(trained)
    test = evaluate(trained[chosen]["run"], a, log)
    argv = " ".join(public(x, a.work) for x in sys.argv[1:])
    doc = {"command": f"python studies/learners/navigate_from_sound.py {argv}".strip(), "commit": commit(), "machine": machine(),
           "inputs": list(INPUTS), "action_column": COLUMN, "dataset": data, "training": trained, "chosen": chosen, "test": test,
           "seconds": round(time.perf_counter() - t0, 1)}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    nav = test["navigate"]
    print(f"Navigate from sound ({chosen}): {nav['successes']}/{nav['n']} [{nav['low']}, {nav['high']}], SPL {test['spl']}", file=sys.stderr)
    print("where the time went:\n" + "\n".join(SPENT), file=sys.stderr)


if __name__ == "__main__":
    main()
