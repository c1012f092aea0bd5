"""The paper's ablation on echo-data, closed loop: build, train, evaluate, write the JSON.

Rows (issue: reference policies):
- Navigate BC with inputs {state only (no target), audio, audio + depth, target position,
  audio + target} (proprioception without velocities in every row; docs/learners.md explains the
  leak); scored closed loop with `echo-data evaluate RECIPE --split test --policy
  Navigate=RUN --policy oracle --planner oracle`: the learner drives every Navigate skill, the
  scripted experts do the rest, and Navigate success is the Navigate skill's success test over
  every Navigate skill attempted (and over each episode's first Navigate alone, the one the sound
  has to guide), with 95 % Wilson intervals;
- the planner with {image, audio, audio + image}: `echo-data train planner`, scored on the
  dataset's test split (test sounds only) by `echo-data evaluate-planner RUN` (its `test.json`).
Test episodes come from the recipe's test split (the sounds no training episode uses); nothing
is tuned on them: every hyper-parameter is the CLI default unless given here.

Usage (the full table: `studies/navigation_ablation/recipes/bc_navigate.yaml`, 60 + 60 + 60 train / 54 test episodes,
build ~26 min at 6.7 s per episode with 2 uncontended workers):
  python studies/navigation_ablation/ablation.py --data data/bc_navigate --runs runs/ablation --episodes 54 --audio-form stored
A small run (a prefix of both splits, fewer test episodes, two rows):
  python studies/navigation_ablation/ablation.py --limit 16 --episodes 12 --rows state audio,depth,state --no-planner
Audio as the stored spectrogram (the first table of the README; the default is level + ILD), and
DAgger on a row already trained (its BC run is copied and continued with `--dagger N --resume`,
not trained again):
  python studies/navigation_ablation/ablation.py ... --rows audio,state --audio-form stored --no-planner
  python studies/navigation_ablation/ablation.py ... --rows audio,depth,state --dagger 2 --dagger-episodes 20 --no-planner
`--reuse` scores run folders that already hold a finished run (its `summary.json`, written by this
script) instead of training them again.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # runner.py
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's echo_data
from runner import ROOT, cli, commit  # noqa: E402

NAV_ROWS = ("state", "audio,state", "audio,depth,state", "state,target", "audio,state,target")
PLANNER_ROWS = ("image", "audio", "audio,image")


def navigate_success(doc: dict) -> dict:
    """Navigate success over all attempted Navigate skills and over first Navigates, with Wilson intervals."""
    from echo_data.evaluation.metrics import proportion

    navs = [nv for e in doc["episodes"] if "skipped" not in e for nv in e["navigate"]]
    first = [nv for e in doc["episodes"] if "skipped" not in e for nv in e["navigate"][:1] if nv["skill_index"] == 0]
    spl = [nv["spl"] for nv in navs if nv["spl"] is not None]
    return {
        "all_navigate": proportion(sum(nv["success"] for nv in navs), len(navs)),
        "first_navigate": proportion(sum(nv["success"] for nv in first), len(first)),
        "spl_mean": sum(spl) / len(spl) if spl else None,
        "episodes": len([e for e in doc["episodes"] if "skipped" not in e]),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recipe", default=str(Path(__file__).with_name("recipes") / "bc_navigate.yaml"))
    ap.add_argument("--data", default=str(ROOT / "data" / "bc_navigate"), help="dataset folder (built unless complete)")
    ap.add_argument("--limit", type=int, default=None, help="build a prefix: N episodes per split")
    ap.add_argument("--runs", default=str(ROOT / "runs" / "ablation"))
    ap.add_argument("--episodes", type=int, default=54, help="test episodes evaluated per Navigate row (>= 50 for the table)")
    ap.add_argument("--rows", nargs="*", default=list(NAV_ROWS), help="Navigate input sets")
    ap.add_argument("--no-planner", action="store_true", help="no planner rows and no learning curve")
    ap.add_argument("--planner-rows", nargs="*", default=list(PLANNER_ROWS), help="planner input sets")
    ap.add_argument("--curve", type=int, nargs="*", default=[30, 60, 120],
                    help="also train the audio planner on seeded subsets of this many train episodes (a learning curve)")
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--dagger", type=int, default=0, help="DAgger rounds for every Navigate row (0: BC only)")
    ap.add_argument("--dagger-episodes", type=int, default=8, help="train episodes rolled per DAgger round")
    ap.add_argument("--audio-form", default="level_ild", help="train bc --audio-form for the rows with audio (level_ild, stored)")
    ap.add_argument("--reuse", action="store_true", help="run folders with a summary.json are scored, not trained again")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(Path(__file__).with_name("results") / "ablation.json"))
    a = ap.parse_args()

    data, runs, out = Path(a.data), Path(a.runs), Path(a.out)
    runs.mkdir(parents=True, exist_ok=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc: dict = {"recipe": a.recipe, "data": str(data), "limit": a.limit, "seed": a.seed, "epochs": a.epochs, "dagger": a.dagger,
                 "dagger_episodes": a.dagger_episodes, "audio_form": a.audio_form,
                 "episodes_per_row": a.episodes, "commit": commit(), "commands": [], "navigate": [], "planner": []}

    def run(*args: str) -> tuple[str, float]:
        doc["commands"].append("echo-data " + " ".join(args))
        return cli(*args)

    manifest = data / "manifest.json"
    if not (manifest.is_file() and json.loads(manifest.read_text()).get("complete")):
        build = ["build", a.recipe, "--out", str(data), "--workers", str(a.workers), "--no-progress", "--resume" if data.exists() else "--overwrite"]
        if a.limit:
            build += ["--limit", str(a.limit)]
        _, secs = run(*build)
        doc["build_seconds"] = round(secs, 1)
    for inputs in a.rows:
        form = a.audio_form if "audio" in inputs.split(",") else "stored"
        base = "nav-" + ("ild-" if form == "level_ild" else "") + inputs.replace(",", "-")
        name = base + (f"-dagger{a.dagger}" if a.dagger else "")
        train = ["train", "bc", str(data), "--skill", "Navigate", "--inputs", inputs, "--epochs", str(a.epochs), "--seed", str(a.seed),
                 *(["--audio-form", form] if "audio" in inputs.split(",") else []),  # refused without audio
                 "--select-every", "0",  # the lowest validation loss, as the committed rows chose (not Navigate's per-skill default)
                 "--out", str(runs / name), "--no-progress"]
        done = runs / name / "summary.json"  # what `train` printed, kept beside the run (written below)
        if a.dagger:
            train += ["--dagger", str(a.dagger), "--dagger-episodes", str(a.dagger_episodes)]
        if a.reuse and done.is_file():
            summary, train_s = done.read_text(), 0.0
            doc["commands"].append("echo-data " + " ".join(train) + "  # trained before: its summary.json reused")
        else:
            if a.dagger and (runs / base / "summary.json").is_file():  # DAgger from the finished BC run of the same row
                if (runs / name).exists():
                    shutil.rmtree(runs / name)
                shutil.copytree(runs / base, runs / name, ignore=shutil.ignore_patterns("summary.json", "dagger.csv"))
                train.append("--resume")
            else:
                train.append("--overwrite")
            summary, train_s = run(*train)
            from echo_data.learn.runs import write_file

            write_file(runs / name, done.name, summary.encode())  # listed in the run's marker: train --overwrite may replace it
        res = out.parent / f"{out.stem}-{name}.json"
        evaluate = ["evaluate", a.recipe, "--split", "test", "-n", str(a.episodes), "--policy", f"Navigate={runs / name}", "--policy", "oracle",
                    "--planner", "oracle", "--workers", str(a.workers), "--json", str(res)]
        scored = json.loads(res.read_text()) if a.reuse and res.is_file() else None
        if scored is not None and len(scored["episodes"]) == a.episodes:
            eval_s = scored.get("wall_seconds", 0.0)  # scored before: kept
            doc["commands"].append("echo-data " + " ".join(evaluate) + "  # reused")
        else:
            _, eval_s = run(*evaluate)
        ev = json.loads(res.read_text())
        s = json.loads(summary)
        row = {"inputs": inputs, "audio_form": form, "run": str(runs / name), "train_seconds": round(train_s, 1),
               "train_loop_seconds": s["seconds"], "eval_seconds": round(eval_s, 1),
               "best_val_loss": s["best_val_loss"], "val_loss_of_mean_train_action": s["val_loss_of_mean_train_action"],
               "rows": s["rows"], "results": str(res), **navigate_success(ev)}
        if (runs / name / "dagger.csv").is_file():  # per round: rollouts, rows added, the learner's success on them
            row["dagger_log"] = (runs / name / "dagger.csv").read_text().splitlines()
        doc["navigate"].append(row)
        print(f"{inputs:24s} first Navigate {row['first_navigate']['k']}/{row['first_navigate']['n']} "
              f"all {row['all_navigate']['k']}/{row['all_navigate']['n']} ci95 {row['all_navigate']['ci95']}", flush=True)
        out.write_text(json.dumps(doc, indent=1))
    if not a.no_planner:
        for inputs in a.planner_rows:
            name = "planner-" + inputs.replace(",", "-")
            _, secs = run("train", "planner", str(data), "--inputs", inputs, "--seed", str(a.seed), "--out", str(runs / name), "--overwrite", "--no-progress")
            tested = json.loads(run("evaluate-planner", str(runs / name), str(data))[0])
            doc["planner"].append({"inputs": inputs, "run": str(runs / name), "train_seconds": round(secs, 1), "test": tested["test"]})
            out.write_text(json.dumps(doc, indent=1))
        doc["planner_curve"] = []
        for n in a.curve:
            name = f"planner-audio-{n}ep"
            report, secs = run("train", "planner", str(data), "--inputs", "audio", "--train-episodes", str(n), "--seed", str(a.seed),
                               "--out", str(runs / name), "--overwrite", "--no-progress")
            r, tested = json.loads(report), json.loads(run("evaluate-planner", str(runs / name), str(data))[0])
            doc["planner_curve"].append({"train_episodes": n, "episodes": {**r["episodes"], **tested["episodes"]}, "train_seconds": round(secs, 1), "test": tested["test"]})
            out.write_text(json.dumps(doc, indent=1))
    out.write_text(json.dumps(doc, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
