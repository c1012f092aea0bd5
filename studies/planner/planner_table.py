"""The planner rows on `studies/planner/recipes/planner_audio.yaml`: build, train each configuration, write the JSON.

Each row is `echo-data train planner DATA --inputs I [flags] --out RUN` (training chooses on
validation and writes eval.json without reading the test split), then `echo-data evaluate-planner
RUN DATA`, which scores the run on the dataset's test split (test sounds only, never heard in
training) and writes test.json; this script collects both into one JSON with the commands and the
commit. Which row is "the" planner
is chosen on validation only: with `--val-by sounds` the validation episodes play held-out train
instances, unheard like the test's, and the row's best validation accuracy is reported beside
its test scores (docs/learners.md).

Usage (build ~10 min with 2 workers; each row 4-15 min on one core):
  python studies/planner/planner_table.py --data data/planner_audio --runs runs/planner
  python studies/planner/planner_table.py ... --rows "audio" "audio|--val-by sounds --select accuracy --augment --epochs 15"
Fresh training voices (`studies/planner/recipes/planner_fresh.yaml`, docs/learners.md):
  python studies/planner/planner_table.py --recipe studies/planner/recipes/planner_fresh.yaml --data out/planner_fresh --runs runs/planner_fresh \
      --out studies/planner/results/planner_fresh.json --rows "audio|--select accuracy --epochs 20" "audio|--select accuracy --augment --epochs 20"
A tiny run (2 episodes per split, a few steps; the test's):
  python studies/planner/planner_table.py --limit 2 --rows "audio|--epochs 1 --max-steps 2" --data D --runs R --out J
`--reuse` collects run folders whose eval.json was written by the same arguments instead of
training them again (and scores them on the test split where their test.json is missing).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # runner.py
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's echo_data
from runner import ROOT, cli, commit  # noqa: E402

ROWS = (
    "audio",
    "audio,image",
    "audio|--val-by sounds --select accuracy",
    "audio|--val-by sounds --select accuracy --augment --epochs 15",
)


def _name(row: str) -> str:
    return "planner-" + re.sub(r"[^a-z0-9]+", "-", row.replace("--", "")).strip("-")


def _rel(path: str | Path) -> str:
    """A path as the results JSON records it: relative to the checkout when inside it (no machine paths)."""
    p = Path(os.path.abspath(path))  # not resolve(): a symlinked data folder keeps its name in the checkout
    return p.relative_to(ROOT).as_posix() if p.is_relative_to(ROOT) else str(path)


def _validation_max(run: Path) -> dict:
    """The highest plain validation accuracy over all epochs of the run (losses.csv; runs from before
    eval.json's `best` existed have only this), and the number of epochs run."""
    import csv

    rows = list(csv.DictReader((run / "losses.csv").open()))
    return {"max_val_events_accuracy": max(float(r["val_events_accuracy"]) for r in rows), "epochs_run": len(rows)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recipe", default=str(Path(__file__).with_name("recipes") / "planner_audio.yaml"))
    ap.add_argument("--data", default=str(ROOT / "data" / "planner_audio"), help="dataset folder (built unless complete)")
    ap.add_argument("--runs", default=str(ROOT / "runs" / "planner"))
    ap.add_argument("--limit", type=int, default=None, help="build a prefix: N episodes per split (the tiny path: tests/test_study_tiny.py)")
    ap.add_argument("--rows", nargs="*", default=list(ROWS), help='"INPUTS" or "INPUTS|FLAGS" per row')
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--reuse", action="store_true", help="collect run folders whose eval.json has the same arguments")
    ap.add_argument("--out", default=str(Path(__file__).with_name("results") / "planner_audio.json"))
    a = ap.parse_args()

    data, runs, out = Path(a.data), Path(a.runs), Path(a.out)
    runs.mkdir(parents=True, exist_ok=True)
    doc: dict = {"recipe": _rel(a.recipe), "data": _rel(data), "commit": commit(), "commands": [], "rows": []}
    manifest = data / "manifest.json"
    if not (manifest.is_file() and json.loads(manifest.read_text()).get("complete")):
        build = ["build", a.recipe, "--out", str(data), "--workers", str(a.workers), "--no-progress", "--resume" if data.exists() else "--overwrite",
                 *(["--limit", str(a.limit)] if a.limit else [])]
        doc["commands"].append("echo-data " + " ".join(build))
        doc["build_seconds"] = round(cli(*build)[1], 1)
    for row in a.rows:
        inputs, _, flags = row.partition("|")
        run = runs / _name(row)
        args = ["train", "planner", str(data), "--inputs", inputs, *shlex.split(flags), "--out", str(run), "--no-progress"]
        command = "echo-data " + " ".join(args)
        reused = a.reuse and (run / "eval.json").is_file() and (run / "command.txt").is_file() and (run / "command.txt").read_text() == command
        if reused:
            report, secs = json.loads((run / "eval.json").read_text()), None
            doc["commands"].append(command + "  # reused")
        else:
            doc["commands"].append(command)
            text, secs = cli(*args, "--overwrite")
            report = json.loads(text)
            from echo_data.learn.runs import write_file

            write_file(run, "command.txt", command.encode())  # listed in the run's marker: train --overwrite may replace it
        score = ["evaluate-planner", str(run), str(data)]
        if reused and (run / "test.json").is_file():
            tested = json.loads((run / "test.json").read_text())
            doc["commands"].append("echo-data " + " ".join(score) + "  # reused")
        else:
            doc["commands"].append("echo-data " + " ".join(score))
            tested = json.loads(cli(*score)[0])
        doc["rows"].append({"inputs": inputs, "flags": flags, "run": _rel(run), "trained_in": _rel(report["run"]), "wall_seconds": secs, "train_seconds": report["seconds"],
                            "episodes": {**report["episodes"], **tested["episodes"]}, "best": report.get("best"), **_validation_max(run),
                            "val_episodes_hearing_fitted_sounds": report.get("val_episodes_hearing_fitted_sounds"),
                            "test_sounds_heard_in_training": tested["test_sounds_heard_in_training"], "test": tested["test"]})
        t = tested["test"]
        print(f"{row:60s} single {t['single_event']['events_in_order']['correct']}/{t['single_event']['events_in_order']['n']} "
              f"multi {t['multi_event']['events_in_order']['correct']}/{t['multi_event']['events_in_order']['n']}", flush=True)
        out.write_text(json.dumps(doc, indent=1))
    out.write_text(json.dumps(doc, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
