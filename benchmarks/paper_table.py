"""The paper's main table on echo-data, closed loop: build the training data, train every skill
learner, evaluate the rows, write benchmarks/results/paper_table.json and its markdown table.

Rows, as the paper lays them out (planning / completion / progressive success per setting, Wilson
95 % intervals, test split = test sounds only, nothing tuned on it):
- oracle planner + scripted experts (the upper bound the data allows);
- oracle planner + learned skills, the drives without the target position (the paper's "Oracle")
  and with it ("Oracle*", `--inputs ...,target`): the paper gives it to Navigate; here Place
  gets it too, because our Place drives the held object to its receptacle (named only by its
  kind otherwise), which is a navigation of its own;
- learned planner (trained here from recipes/planner_fresh.yaml, or `--planner-run`) + scripted
  experts, measured; + learned skills without / with the target, composed from that row and the
  oracle-planner rows (`composed` says why that is the closed-loop result);
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
# The planner learns from recipes/planner_fresh.yaml (episodes cut after 10 frames, a fresh
# synthesised voice per training event; built whole: `train planner` scores its own test split).
# Dataset -> (recipe, split built: None = every split).
DATASETS: dict[str, tuple[str, str | None]] = {
    "paper_table": ("paper_table.yaml", "train"), "paper_table_pick_place": ("paper_table_pick_place.yaml", "train"),
    "paper_table_door_sink": ("paper_table_door_sink.yaml", "train"), "planner_fresh": ("planner_fresh.yaml", None),
    "paper_table_door_sink_300": ("paper_table_door_sink_300.yaml", "train")}
# The planner run: audio only, the checkpoint of the best balanced validation accuracy of 20
# epochs (chosen on validation among the planner_fresh runs: benchmarks/results/planner_fresh.json).
PLANNER = ("planner_fresh", ("--inputs", "audio", "--select", "accuracy", "--epochs", "20"))
# Skill learners: run name -> (dataset, skill, inputs, options). Manipulation sees head and wrist
# depth (the paper's Table 3c: both cameras decisive) and proprioception, and predicts its torso
# and arm targets as changes from the measured joints (`--action-form delta`: absolute targets
# stalled short of the object, docs/learners.md); every learner gets the target kind its chain
# entry names. Navigate: a GRU over the skill's steps (the sound is a cue to integrate over
# time), reset at each skill's start.
MANIPULATION = ("--action-form", "delta", "--shift", "4", "--epochs", "15")
LEARNERS: dict[str, tuple[str, str, str, tuple[str, ...]]] = {
    "Navigate": ("paper_table", "Navigate", "audio,depth,rgb,state,kind", ("bc-rnn", "--epochs", "30")),
    "Navigate-target": ("paper_table", "Navigate", "audio,depth,rgb,state,kind,target", ("bc-rnn", "--epochs", "30")),
    **{s: ("paper_table_pick_place", s, "depth,wrist_depth,state,kind", MANIPULATION) for s in ("Pick", "Place")},
    "Place-target": ("paper_table_pick_place", "Place", "depth,wrist_depth,state,kind,target", MANIPULATION),
    **{s: ("paper_table_door_sink", s, "depth,wrist_depth,state,kind", MANIPULATION) for s in ("OpenDoor", "CloseSink")},
    # Five times the demonstrations (recipes/paper_table_door_sink_300.yaml): what more data does.
    **{f"{s}-300": ("paper_table_door_sink_300", s, "depth,wrist_depth,state,kind", MANIPULATION) for s in ("OpenDoor", "CloseSink")},
}
SKILLS = ("Navigate", "Pick", "Place", "OpenDoor", "CloseSink")
# Where each skill alone is scored: the single-event settings in which it occurs.
# OpenDoor and CloseSink: recipes/paper_table_door.yaml and _sink.yaml, 50 test episodes of their
# own event each (the mixed state-transition split has 35 doors and 15 sinks).
ALONE_SETTINGS = {"Navigate": ("object_relocation", "state_transition"), "Pick": ("object_relocation",),
                  "Place": ("object_relocation",), "OpenDoor": ("door",), "CloseSink": ("sink",)}


def rows(planner_run: str | None) -> dict[str, dict[str, Any]]:
    """Row name -> {"policy": run names per skill ("oracle" = expert), "planner", "settings"}, or,
    for a row computed from two measured ones, {"compose": (plan row, execution row), "settings"}
    or {"derive": source row, "skill", "settings"} (see `composed` and `derived`).

    `planner_run`: the learned planner's run folder (None: the learned-planner rows are left out)."""
    learned = {s: s for s in SKILLS}
    starred = {**learned, "Navigate": "Navigate-target", "Place": "Place-target"}  # the drives are given their target
    out: dict[str, dict[str, Any]] = {
        "oracle planner + scripted experts": {"policy": {}, "planner": "oracle", "settings": SETTINGS},
        "oracle planner + learned skills": {"policy": learned, "planner": "oracle", "settings": SETTINGS},
        "oracle planner + learned skills*": {"policy": starred, "planner": "oracle", "settings": SETTINGS},
    }
    if planner_run:
        out["learned planner + scripted experts"] = {"policy": {}, "planner": planner_run, "settings": SETTINGS}
        for star in ("", "*"):
            out[f"learned planner + learned skills{star}"] = {
                "compose": ("learned planner + scripted experts", f"oracle planner + learned skills{star}"), "settings": SETTINGS}
    for s in SKILLS:
        out[f"{s} alone"] = {"policy": {s: s}, "planner": "oracle", "settings": ALONE_SETTINGS[s], "skill": s}
    for s in ("Navigate", "Place"):  # the starred learners alone
        out[f"{s}* alone"] = {"policy": {s: starred[s]}, "planner": "oracle", "settings": ALONE_SETTINGS[s], "skill": s}
    for s in ("OpenDoor", "CloseSink"):  # from five times the demonstrations
        out[f"{s}-300 alone"] = {"policy": {s: f"{s}-300"}, "planner": "oracle", "settings": ALONE_SETTINGS[s], "skill": s}
    # Navigate is the first skill of every single-event chain, so its outcome alone (experts after
    # it) is its outcome in the oracle-planner chain row, step for step (an episode is a pure
    # function of recipe, split, index and policies; checked: `derived`'s docstring).
    out["Navigate alone"] = {"derive": "oracle planner + learned skills", "skill": "Navigate", "settings": ALONE_SETTINGS["Navigate"]}
    out["Navigate* alone"] = {"derive": "oracle planner + learned skills*", "skill": "Navigate", "settings": ALONE_SETTINGS["Navigate"]}
    return out


def eval_json(runs: Path, name: str, setting: str) -> Path:
    """Where the `echo-data evaluate --json` document of row `name` on `setting` lives."""
    return runs / f"eval-{name.replace(' ', '_').replace('*', 'star')}-{setting}.json"


def composed(plans: dict[str, Any], runs_of: dict[str, Any], command: str) -> dict[str, Any]:
    """A learned-planner + learned-skills row from two measured evaluations of the same test
    episodes: `plans` (the learned planner with the scripted experts: which plans are right) and
    `runs_of` (the oracle planner with the learned skills: what the skills do). Why this is the
    closed-loop result and not an estimate: `run_episode` ends an episode at a wrong plan, and
    after a right plan (the true chain, which is what the oracle planner gives) the planner is
    never consulted again, so the episode is step for step the oracle-planner episode of the
    same index (SAPIEN's CPU physics and the learners' inference are deterministic: the first
    Navigate of 25 test episodes evaluated in two separate runs was identical, path length and
    steps). Composing saves re-running the expensive half of every episode on two cores."""
    from echo_data.evaluation.metrics import summarise

    out = []
    for p, r in zip(plans["episodes"], runs_of["episodes"], strict=True):
        if p.get("episode_id") != r.get("episode_id"):
            raise SystemExit(f"composed rows need the same episodes: {p.get('episode_id')} != {r.get('episode_id')}")
        if "skipped" in p or "skipped" in r:
            continue
        rec = dict(r, planned_chain=p["planned_chain"], plan_correct=p["plan_correct"])
        if not p["plan_correct"]:
            rec.update(skills=[], skills_completed=0, success=False, navigate=[], failure=p["failure"], steps=p["steps"])
        out.append(rec)
    return scored({"metrics": {"all": summarise(out)}, "episodes": out}, command, 0.0)


def derived(source: dict[str, Any], skill: str, command: str) -> dict[str, Any]:
    """A skill-alone entry read from a chain row's episodes: the skill's success over its attempts."""
    return {"command": command, "commit": _commit(), "skills": {skill: skill_success(source["episodes"], skill)}}


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
    algo, opts = (opts[0], opts[1:]) if opts and not opts[0].startswith("--") else ("bc", opts)  # `echo-data train <algo>`; bc unless named first
    args = ["train", algo, str(data), "--skill", skill, "--inputs", inputs, *opts, "--out", str(folder), "--no-progress"]
    if tiny:
        args += ["--max-steps", "2"]
    stdout, seconds = cli(*args)
    command = "echo-data " + " ".join(rel(Path(x)) if Path(x).exists() else x for x in args)
    summary = {**json.loads(stdout), "command": command, "wall_seconds": round(seconds, 1)}
    summary["run"] = rel(folder)
    summary["commit"] = _commit()
    done.write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def build(recipe: Path, split: str | None, out: Path, workers: int, doc: dict[str, Any]) -> Path:
    """Build (or resume) `split` of `recipe` (None: every split) into `out` unless complete; records the command."""
    manifest = out / "manifest.json"
    if not (manifest.is_file() and json.loads(manifest.read_text()).get("complete")):
        args = ["build", str(recipe), *(["--split", split] if split else []), "--workers", str(workers), "--out", str(out), "--no-progress"]
        _, seconds = cli(*args, *(["--resume"] if manifest.is_file() else []))
        doc.setdefault("datasets", {})[out.name] = {
            "command": "echo-data " + " ".join(rel(Path(x)) if Path(x).exists() else x for x in args), "wall_seconds": round(seconds, 1), "commit": _commit()}
    return out


def train_planner(data: Path, runs: Path, tiny: bool) -> dict[str, Any]:
    """Train the planner (`echo-data train planner`) unless its run folder holds a finished run;
    its summary: the command and the test-split scores of its own dataset (eval.json)."""
    folder = runs / "planner"
    done = folder / "summary.json"
    if done.is_file():
        return json.loads(done.read_text())
    args = ["train", "planner", str(data), *PLANNER[1], "--out", str(folder), "--overwrite", "--no-progress"]
    if tiny:
        args += ["--max-steps", "2"]
    stdout, seconds = cli(*args)
    report = json.loads(stdout)
    summary = {"command": "echo-data " + " ".join(rel(Path(x)) if Path(x).exists() else x for x in args), "wall_seconds": round(seconds, 1),
               "run": rel(folder), "commit": _commit(), **{k: report[k] for k in ("episodes", "best", "test") if k in report}}
    done.write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def evaluate(recipe: Path, row: dict[str, Any], runs: Path, n: int, workers: int, out: Path) -> dict[str, Any]:
    """`echo-data evaluate` of one row on one recipe; its metrics, the skill-alone success and the command."""
    pol = [f"{s}={runs / r}" for s, r in row["policy"].items()]
    args = ["evaluate", str(recipe), "--split", "test", "-n", str(n), *(f"--policy={p}" for p in pol), "--policy", "oracle",
            "--planner", row["planner"], "--workers", str(workers), "--json", str(out)]
    if out.with_suffix(".episodes.jsonl").is_file():  # a killed evaluation's journal: continue it
        args.append("--resume")
    _, seconds = cli(*args)
    return scored(json.loads(out.read_text()), "echo-data " + " ".join(rel(Path(a)) if Path(a).exists() else a for a in args), seconds)


def planning_without_place_target(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """The share of plans right but for the Place receptacle: the paper's chains name skills and
    sounding objects, while ours also name where Place puts the object (the nearest free
    receptacle, which no sound tells), so this is the planning figure to set beside the paper's."""
    from echo_data.evaluation.metrics import proportion

    def blank(chain: list[dict[str, Any]] | None) -> list[dict[str, Any]] | None:
        return None if chain is None else [dict(c, target=None) if c["skill"] == "Place" else c for c in chain]

    eps = [e for e in episodes if "skipped" not in e]
    return proportion(sum(e["planned_chain"] is not None and blank(e["planned_chain"]) == blank(e["true_chain"]) for e in eps), len(eps))


def handover(episodes: list[dict[str, Any]]) -> dict[str, Any] | None:
    """Where the first Navigate handed over: per successful first Navigate, the expert's planned
    path from the skill's start minus the path the base drove (m; > 0: stopped short of where the
    expert stops, the pose every manipulation demonstration starts from), as quartiles and N.
    docs/learners.md, "In the chain", says why this decides the chain."""
    import statistics

    short = [nv["expert_length"] - nv["path_length"] for e in episodes if "skipped" not in e
             for nv in e["navigate"][:1] if nv["skill_index"] == 0 and nv["success"] and nv["expert_length"] is not None]
    if len(short) < 2:
        return None
    q1, median, q3 = statistics.quantiles(short, n=4)
    return {"n": len(short), "quartiles_m": [round(q1, 3), round(median, 3), round(q3, 3)]}


def scored(doc: dict[str, Any], command: str, seconds: float) -> dict[str, Any]:
    """A row's entry from `echo-data evaluate --json`'s document: metrics, per-skill success, the command."""
    metrics: dict[str, Any] = doc["metrics"].get("all") or next(iter(doc["metrics"].values()), {})
    return {"command": command, "wall_seconds": round(seconds, 1), "commit": _commit(),
            "metrics": {**{k: metrics[k] for k in ("episodes", "task_planning", "skill_completion", "progressive", "navigate_success") if k in metrics},
                        "planning_without_place_target": planning_without_place_target(doc["episodes"]),
                        "navigate_shortfall": handover(doc["episodes"])},
            "skills": {s: skill_success(doc["episodes"], s) for s in SKILLS}}


def cell(p: dict[str, Any] | None) -> str:
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['k']}/{p['n']} = {p['value']:.2f} [{lo:.2f}, {hi:.2f}]"


PAPER_ORDER = ("state_transition", "object_relocation", "multi_event")  # the paper's column order


def short(p: dict[str, Any] | None) -> str:
    """A proportion as a table cell of the paper-shaped table: value [95 % interval] (k/n)."""
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['value']:.2f} [{lo:.2f}, {hi:.2f}] ({p['k']}/{p['n']})"


def markdown(doc: dict[str, Any]) -> str:
    """The README tables: the paper's layout (a row per planner/skills combination, planning and
    completion per setting), the progressive success of each row and setting, the skills alone."""
    from echo_data.evaluation.metrics import proportion

    chain = {name: per for name, per in doc["rows"].items() if not name.endswith(" alone")}
    head = ["| row | " + " | ".join(f"{s.replace('_', ' ')}: planning | completion" for s in PAPER_ORDER) + " |",
            "|---|" + "---|---|" * len(PAPER_ORDER)]
    mark = {name: " †" if any("computed_from" in r for r in per.values()) else "" for name, per in doc["rows"].items()}
    for name, per in chain.items():
        cells = []
        for setting in PAPER_ORDER:
            m = per.get(setting, {}).get("metrics", {})
            cells += [short(m.get("task_planning")), short(m.get("skill_completion"))]
        head.append(f"| {name}{mark[name]} | " + " | ".join(cells) + " |")
    prog = ["| row | setting | progressive success (through skill 1, 2, ...) |", "|---|---|---|"]
    for name, per in chain.items():
        for setting in PAPER_ORDER:
            if setting in per:
                prog.append(f"| {name}{mark[name]} | {setting.replace('_', ' ')} | " + "; ".join(cell(p) for p in per[setting]["metrics"].get("progressive", [])) + " |")
    both = ["| row | setting | planning, exact chain | planning without the Place receptacle (the paper's sense) |", "|---|---|---|---|"]
    for name, per in chain.items():
        for setting in PAPER_ORDER:
            m = per.get(setting, {}).get("metrics", {})
            if m.get("planning_without_place_target") and m["planning_without_place_target"]["k"] != m["task_planning"]["k"]:
                both.append(f"| {name}{mark[name]} | {setting.replace('_', ' ')} | {cell(m['task_planning'])} | {cell(m['planning_without_place_target'])} |")
    if len(both) > 2:
        prog += ["", *both]
    alone = ["| skill alone | settings | success |", "|---|---|---|"]
    for name, per in doc["rows"].items():
        if name.endswith(" alone"):
            skill = name.removesuffix(" alone")
            tries = [r["skills"][skill.rstrip("*").split("-")[0]] for r in per.values()]
            k, n = sum(t["k"] for t in tries), sum(t["n"] for t in tries)
            alone.append(f"| {skill}{mark[name]} | {', '.join(s.replace('_', ' ') for s in per)} | {cell(proportion(k, n))} |")
    note = ("\n† computed from the episodes of two measured rows (the same test episodes): a learned-planner row takes each "
            "episode's plan from the learned planner's run with the experts and, where that plan is right, the outcome of the "
            "oracle-planner row's run of the same episode; a derived skill-alone row reads the skill's attempts in a chain row "
            "(`composed` and `derived` in benchmarks/paper_table.py say why this is exact).\n") if any(mark.values()) else ""
    return "\n".join(head) + "\n\n" + "\n".join(prog) + "\n\n" + "\n".join(alone) + "\n" + note


def save(out: Path, mine: dict[str, Any]) -> dict[str, Any]:
    """Merge this run's datasets, training and rows into the JSON on disk and write it atomically,
    under a lock: several runs of this script (one row each, on their own cores) share one JSON,
    and each only adds what it measured. Returns the merged document."""
    import fcntl

    out.parent.mkdir(parents=True, exist_ok=True)
    with (out.parent / (out.name + ".lock")).open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        doc: dict[str, Any] = json.loads(out.read_text()) if out.is_file() else {}
        for key in ("datasets", "training"):
            doc.setdefault(key, {}).update(mine.get(key, {}))
        for name, per in mine.get("rows", {}).items():  # per setting: a row's other settings stay
            doc.setdefault("rows", {}).setdefault(name, {}).update(per)
        doc.setdefault("rows", {})
        doc.pop("recipe", None)  # one recipe per dataset now: see "datasets"
        doc.update({k: v for k, v in mine.items() if k not in ("datasets", "training", "rows")})
        tmp = out.with_name(out.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        os.replace(tmp, out)
        md = out.with_suffix(".md")
        md.with_name(md.name + ".tmp").write_text(markdown(doc))
        os.replace(md.with_name(md.name + ".tmp"), md)
    return doc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data-root", type=Path, default=ROOT / "out", help="the training datasets are built (or resumed) in DATA_ROOT/<recipe name>")
    ap.add_argument("--data", type=Path, default=None, help="with --tiny: the one dataset every learner trains on")
    ap.add_argument("--runs", type=Path, default=ROOT / "runs" / "paper_table", help="run folders of the learners and evaluation JSONs")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "paper_table.json")
    ap.add_argument("-n", "--episodes", type=int, default=50, help="test episodes per setting and row")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--planner-run", default=None, help="a trained planner run folder for the learned-planner rows (default: the planner this script trains, RUNS/planner)")
    ap.add_argument("--no-planner", action="store_true", help="leave out the learned-planner rows (and the planner's data and training)")
    ap.add_argument("--rows", nargs="*", default=None, help="only these rows (names as in the JSON)")
    ap.add_argument("--learners", nargs="*", default=None, help="only build the data of and train these learners (names as in LEARNERS, or planner); no evaluation")
    ap.add_argument("--tiny", action="store_true", help="the test's version: quickstart recipe, 2 training steps, 1 episode")
    a = ap.parse_args()
    n = 1 if a.tiny else a.episodes
    if a.tiny and a.data is None:
        ap.error("--tiny needs --data (a quickstart dataset)")
    mine: dict[str, Any] = {"episodes_per_setting": n, "commit": _commit(), "datasets": {}, "training": {}, "rows": {}}
    trained = dict(json.loads(a.out.read_text()).get("training", {})) if a.out.is_file() else {}
    a.runs.mkdir(parents=True, exist_ok=True)

    planner_run = None if a.no_planner else a.planner_run or str(a.runs / "planner")
    chosen = {name: row for name, row in rows(planner_run).items() if a.rows is None or name in a.rows}
    if a.learners is not None:  # training only: one lane of a table filled by several runs of this script
        unknown = sorted(set(a.learners) - {*LEARNERS, "planner"})
        if unknown:
            ap.error(f"--learners: unknown {unknown} (known: {', '.join([*LEARNERS, 'planner'])})")
        chosen = {}
    needed = [n for n in LEARNERS if any(n in row.get("policy", {}).values() for row in chosen.values()) or n in (a.learners or ())]  # only what the rows drive
    wants_planner = a.planner_run is None and (any(row.get("planner") == planner_run for row in chosen.values()) or "planner" in (a.learners or ()))
    data: dict[str, Path] = {}
    for key in dict.fromkeys([*(LEARNERS[name][0] for name in needed), *([PLANNER[0]] if wants_planner else [])]):
        recipe, split = DATASETS[key]
        data[key] = a.data if a.tiny else build(ROOT / "recipes" / recipe, split, a.data_root / key, a.workers, mine)
    mine["training"].update({name: s for name in needed if (s := train(data[LEARNERS[name][0]], a.runs, name, a.tiny)) is not None})
    if wants_planner:
        mine["training"]["planner"] = train_planner(data[PLANNER[0]], a.runs, a.tiny)
    trained.update(mine["training"])
    save(a.out, mine)
    for name, row in chosen.items():
        if any(r not in trained for r in row.get("policy", {}).values()):
            continue
        done = json.loads(a.out.read_text()).get("rows", {}).get(name, {})  # another run of this script may have measured it
        for setting in row["settings"] if not a.tiny else ("quickstart",):
            if setting in done:
                continue  # measured already: evaluations are the long part
            if "compose" in row or "derive" in row:  # from measured rows' episodes, once they are there
                sources = [eval_json(a.runs, src, setting) for src in (row.get("compose") or (row["derive"],))]
                if not all(p.is_file() for p in sources):
                    print(f"{name} / {setting}: waits for {', '.join(rel(p) for p in sources if not p.is_file())}", file=sys.stderr)
                    continue
                docs = [json.loads(p.read_text()) for p in sources]
                how = f"python benchmarks/paper_table.py --rows '{name}' (from {' and '.join(rel(p) for p in sources)})"
                entry = composed(docs[0], docs[1], how) if "compose" in row else derived(docs[0], row["skill"], how)
                mine["rows"] = {name: {setting: {**entry, "computed_from": [rel(p) for p in sources]}}}
                save(a.out, mine)
                continue
            rec = ROOT / "recipes" / ("quickstart.yaml" if a.tiny else f"paper_table_{setting}.yaml")
            res = evaluate(rec, row, a.runs, n, a.workers, eval_json(a.runs, name, setting))
            mine["rows"] = {name: {setting: res}}
            save(a.out, mine)  # after every evaluation: a kill loses at most the one running (its journal resumes it)
            print(f"{name} / {setting}: {cell(res['metrics'].get('skill_completion'))}", file=sys.stderr)
    mine["rows"] = {}  # entries measured before a metric was added get it from their evaluation's episodes
    for name, per in json.loads(a.out.read_text()).get("rows", {}).items():
        for setting, entry in per.items():
            if "metrics" in entry and "navigate_shortfall" not in entry["metrics"] and (p := eval_json(a.runs, name, setting)).is_file():
                episodes = json.loads(p.read_text())["episodes"]
                entry["metrics"].update(planning_without_place_target=planning_without_place_target(episodes), navigate_shortfall=handover(episodes))
                mine["rows"].setdefault(name, {})[setting] = entry
    print(markdown(save(a.out, mine)))


if __name__ == "__main__":
    main()
