"""The paper's main table on echo-data, closed loop: build the training data, train every skill
learner, evaluate the rows, write benchmarks/results/paper_table.json and its markdown table.

Rows, as the paper lays them out (planning / completion / progressive success per setting, Wilson
95 % intervals, test split = test sounds only, nothing tuned on it):
- oracle planner + scripted experts (the upper bound the data allows);
- oracle planner + learned skills, Navigate without the target position (the paper's "Oracle")
  and with it ("Oracle*", `--inputs ...,target` for Navigate);
- learned planner (`--planner-run`, the planner helper's run) + learned skills, without / with;
- each skill alone: the learner drives that skill, the scripted experts do the others; success =
  the skill's success test over every attempt of it.

Evaluation recipes: `recipes/paper_table_<setting>.yaml` keep the training episodes of
`recipes/paper_table.yaml` and put all test episodes in one setting, so `-n N` scores N episodes
of that setting (`echo-data evaluate` samples them; the test split is never built).

Resumable: the data build resumes, finished run folders (a `summary.json` written here) are not
trained again, and an evaluation already in the JSON is not run again (they are the long part).

Usage:
  python benchmarks/paper_table.py                      # the whole table (hours on 2 cores)
  python benchmarks/paper_table.py --rows "Pick alone"  # one row
  python benchmarks/paper_table.py --tiny --data D --out J   # the test: quickstart, a few steps, 1 episode
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any

from ablation import ROOT, _commit, cli

SETTINGS = ("object_relocation", "state_transition", "multi_event")
# Training data: dataset (its folder under --data-root) -> recipe. Pick and Place learn from their
# own object-relocation build (recipes/paper_table_pick_place.yaml: 100 episodes under DART noise,
# five times the Pick segments of paper_table.yaml), OpenDoor and CloseSink from a
# state-transition build (recipes/paper_table_door_sink.yaml: 60 episodes, same noise), Navigate
# from recipes/paper_table.yaml (all three settings: it serves every chain).
DATASETS = {"paper_table": "paper_table.yaml", "paper_table_pick_place": "paper_table_pick_place.yaml",
            "paper_table_door_sink": "paper_table_door_sink.yaml"}
# Skill learners: run name -> (dataset, skill, inputs, options). Manipulation sees head and wrist
# depth (the paper's Table 3c: both cameras decisive) and proprioception, and predicts its torso
# and arm targets as changes from the measured joints (`--action-form delta`: absolute targets
# stalled short of the object, docs/learners.md); every learner gets the target kind its chain
# entry names. Navigate: a GRU over the skill's steps (the sound is a cue to integrate over
# time), reset at each skill's start.
MANIPULATION = ("--action-form", "delta", "--shift", "4", "--epochs", "15")
LEARNERS: dict[str, tuple[str, str, str, tuple[str, ...]]] = {
    "Navigate": ("paper_table", "Navigate", "audio,depth,rgb,state,kind", ("--gru", "--epochs", "30")),
    "Navigate-target": ("paper_table", "Navigate", "audio,depth,rgb,state,kind,target", ("--gru", "--epochs", "30")),
    **{s: ("paper_table_pick_place", s, "depth,wrist_depth,state,kind", MANIPULATION) for s in ("Pick", "Place")},
    **{s: ("paper_table_door_sink", s, "depth,wrist_depth,state,kind", MANIPULATION) for s in ("OpenDoor", "CloseSink")},
}
SKILLS = ("Navigate", "Pick", "Place", "OpenDoor", "CloseSink")
# Where each skill alone is scored: the single-event settings in which it occurs.
ALONE_SETTINGS = {"Navigate": ("object_relocation", "state_transition"), "Pick": ("object_relocation",),
                  "Place": ("object_relocation",), "OpenDoor": ("state_transition",), "CloseSink": ("state_transition",)}


def rows(planner_run: str | None) -> dict[str, dict[str, Any]]:
    """Row name -> {"policy": run names per skill ("oracle" = expert), "planner", "settings"}."""
    learned = {s: s for s in SKILLS}
    out: dict[str, dict[str, Any]] = {
        "oracle planner + scripted experts": {"policy": {}, "planner": "oracle", "settings": SETTINGS},
        "oracle planner + learned skills": {"policy": learned, "planner": "oracle", "settings": SETTINGS},
        "oracle planner + learned skills*": {"policy": {**learned, "Navigate": "Navigate-target"}, "planner": "oracle", "settings": SETTINGS},
    }
    if planner_run:
        out["learned planner + learned skills"] = {"policy": learned, "planner": planner_run, "settings": SETTINGS}
        out["learned planner + learned skills*"] = {"policy": {**learned, "Navigate": "Navigate-target"}, "planner": planner_run, "settings": SETTINGS}
    for s in SKILLS:
        out[f"{s} alone"] = {"policy": {s: s}, "planner": "oracle", "settings": ALONE_SETTINGS[s], "skill": s}
    return out


def rel(p: Path) -> str:
    """A path as the JSON stores it: relative to the repository when inside it (symbolic links
    kept: a dataset folder linked in from elsewhere is still named by its place here)."""
    p = Path(os.path.abspath(p))
    return str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p)


def skill_success(episodes: list[dict[str, Any]], skill: str) -> dict[str, Any]:
    """Successes of `skill` over every attempt of it in per-episode records, Wilson 95 %."""
    from echo_data.evaluation.metrics import proportion

    tries = [bool(s["success"]) for e in episodes for s in e.get("skills", ()) if s["skill"] == skill]
    return proportion(sum(tries), len(tries))


def train(data: Path, runs: Path, name: str, tiny: bool) -> dict[str, Any] | None:
    """Train learner `name` on dataset `data` unless its run folder holds a finished run; None when
    its skill has no rows."""
    from echo_data.learn.data import skills_in

    _, skill, inputs, opts = LEARNERS[name]
    if skill not in skills_in(data, "train"):
        return None
    folder = runs / name
    done = folder / "summary.json"
    if done.is_file():
        return json.loads(done.read_text())
    if folder.exists():
        shutil.rmtree(folder)  # unfinished: train again (a resumed run would need its exact options)
    args = ["train", "bc", str(data), "--skill", skill, "--inputs", inputs, *opts, "--out", str(folder), "--no-progress"]
    if tiny:
        args += ["--max-steps", "2"]
    stdout, seconds = cli(*args)
    command = "echo-data " + " ".join(rel(Path(x)) if Path(x).exists() else x for x in args)
    summary = {**json.loads(stdout), "command": command, "wall_seconds": round(seconds, 1)}
    summary["run"] = rel(folder)
    done.write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def build(recipe: Path, out: Path, workers: int, doc: dict[str, Any]) -> Path:
    """Build (or resume) the train split of `recipe` into `out` unless complete; records the command."""
    manifest = out / "manifest.json"
    if not (manifest.is_file() and json.loads(manifest.read_text()).get("complete")):
        args = ["build", str(recipe), "--split", "train", "--workers", str(workers), "--out", str(out), "--no-progress"]
        _, seconds = cli(*args, *(["--resume"] if manifest.is_file() else []))
        doc.setdefault("datasets", {})[out.name] = {
            "command": "echo-data " + " ".join(rel(Path(x)) if Path(x).exists() else x for x in args), "wall_seconds": round(seconds, 1)}
    return out


def evaluate(recipe: Path, row: dict[str, Any], runs: Path, n: int, workers: int, out: Path) -> dict[str, Any]:
    """`echo-data evaluate` of one row on one recipe; its metrics, the skill-alone success and the command."""
    pol = [f"{s}={runs / r}" for s, r in row["policy"].items()]
    args = ["evaluate", str(recipe), "--split", "test", "-n", str(n), *(f"--policy={p}" for p in pol), "--policy", "oracle",
            "--planner", row["planner"], "--workers", str(workers), "--json", str(out)]
    if out.with_suffix(".episodes.jsonl").is_file():  # a killed evaluation's journal: continue it
        args.append("--resume")
    _, seconds = cli(*args)
    return scored(json.loads(out.read_text()), "echo-data " + " ".join(rel(Path(a)) if Path(a).exists() else a for a in args), seconds)


def scored(doc: dict[str, Any], command: str, seconds: float) -> dict[str, Any]:
    """A row's entry from `echo-data evaluate --json`'s document: metrics, per-skill success, the command."""
    metrics = doc["metrics"].get("all") or next(iter(doc["metrics"].values()), {})
    return {"command": command, "wall_seconds": round(seconds, 1),
            "metrics": {k: metrics[k] for k in ("episodes", "task_planning", "skill_completion", "progressive", "navigate_success") if k in metrics},
            "skills": {s: skill_success(doc["episodes"], s) for s in SKILLS}}


def cell(p: dict[str, Any] | None) -> str:
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['k']}/{p['n']} = {p['value']:.2f} [{lo:.2f}, {hi:.2f}]"


def markdown(doc: dict[str, Any]) -> str:
    """The README tables: chain rows per setting (planning / completion / progressive), then skills alone."""
    lines = ["| row | setting | planning | completion | progressive (through skill 1, 2, ...) |", "|---|---|---|---|---|"]
    alone = ["| skill alone | settings | success |", "|---|---|---|"]
    for name, per in doc["rows"].items():
        if name.endswith(" alone"):
            skill = name.removesuffix(" alone")
            tries = [r["skills"][skill] for r in per.values()]
            k, n = sum(t["k"] for t in tries), sum(t["n"] for t in tries)
            from echo_data.evaluation.metrics import proportion

            alone.append(f"| {skill} | {', '.join(per)} | {cell(proportion(k, n))} |")
            continue
        for setting, r in per.items():
            m = r["metrics"]
            prog = "; ".join(f"{cell(p)}" for p in m.get("progressive", []))
            lines.append(f"| {name} | {setting} | {cell(m.get('task_planning'))} | {cell(m.get('skill_completion'))} | {prog} |")
    return "\n".join(lines) + "\n\n" + "\n".join(alone) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data-root", type=Path, default=ROOT / "out", help="the training datasets are built (or resumed) in DATA_ROOT/<recipe name>")
    ap.add_argument("--data", type=Path, default=None, help="with --tiny: the one dataset every learner trains on")
    ap.add_argument("--runs", type=Path, default=ROOT / "runs" / "paper_table", help="run folders of the learners and evaluation JSONs")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "paper_table.json")
    ap.add_argument("-n", "--episodes", type=int, default=50, help="test episodes per setting and row")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--planner-run", default=None, help="a trained planner run folder: adds the learned-planner rows")
    ap.add_argument("--rows", nargs="*", default=None, help="only these rows (names as in the JSON)")
    ap.add_argument("--tiny", action="store_true", help="the test's version: quickstart recipe, 2 training steps, 1 episode")
    a = ap.parse_args()
    n = 1 if a.tiny else a.episodes
    if a.tiny and a.data is None:
        ap.error("--tiny needs --data (a quickstart dataset)")
    doc: dict[str, Any] = json.loads(a.out.read_text()) if a.out.is_file() else {}
    doc.setdefault("rows", {})
    doc.pop("recipe", None)  # one recipe per dataset now: see "datasets"
    doc.update(episodes_per_setting=n, commit=_commit())
    a.runs.mkdir(parents=True, exist_ok=True)

    chosen = {name: row for name, row in rows(a.planner_run).items() if a.rows is None or name in a.rows}
    needed = [n for n in LEARNERS if any(n in row["policy"].values() for row in chosen.values())]  # only what the rows drive
    data: dict[str, Path] = {}
    for key in dict.fromkeys(LEARNERS[name][0] for name in needed):
        data[key] = a.data if a.tiny else build(ROOT / "recipes" / DATASETS[key], a.data_root / key, a.workers, doc)
    doc.setdefault("training", {}).update({name: s for name in needed if (s := train(data[LEARNERS[name][0]], a.runs, name, a.tiny)) is not None})
    a.out.parent.mkdir(parents=True, exist_ok=True)
    for name, row in chosen.items():
        if any(r not in doc["training"] for r in row["policy"].values()):
            continue
        for setting in row["settings"] if not a.tiny else ("quickstart",):
            if setting in doc["rows"].get(name, {}):
                continue  # measured already: evaluations are the long part
            rec = ROOT / "recipes" / ("quickstart.yaml" if a.tiny else f"paper_table_{setting}.yaml")
            res = evaluate(rec, row, a.runs, n, a.workers, a.runs / f"eval-{name.replace(' ', '_').replace('*', 'star')}-{setting}.json")
            doc["rows"].setdefault(name, {})[setting] = res
            a.out.write_text(json.dumps(doc, indent=1) + "\n")  # after every evaluation: a kill loses at most one
            print(f"{name} / {setting}: {cell(res['metrics'].get('skill_completion'))}", file=sys.stderr)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    a.out.with_suffix(".md").write_text(markdown(doc))
    print(markdown(doc))


if __name__ == "__main__":
    main()
