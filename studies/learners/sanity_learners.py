"""The privileged sanity learner per manipulation skill (issue 28, point 5), closed loop: build the
camera-free training data, train each learner of `LEARNERS` (ACT, a chunked MLP) on proprioception + the skill's
`observation.privileged.*` columns (no images, so nothing is rendered, in the build or in
evaluation), choose the checkpoint and the learner closed loop on the validation split, then evaluate on the test
split (test sounds) and write studies/learners/results/sanity_learners.json.

It separates "the demonstrations cannot teach this skill" from "the cameras are too weak": a
learner that knows where the target is and still fails points at the data.

Two test rows per skill, both "the skill alone" as studies/paper_table/paper_table.py scores it (the
learner drives its skill, the experts every other one, success = the skill's success test over
its attempts):
- `skills`: the experts before it hand over exactly (Navigate stops at the interaction pose,
  `experts.handover_noise` 0: recipes/sanity_test_<group>.yaml);
- `skills_handover`: the oracle Navigate stops anywhere in its success region
  (`handover_noise` 1.0: recipes/sanity_test_<group>_handover.yaml), where a learned Navigate
  hands over. The same test episodes: the hand-over point has its own random stream.

Data: studies/paper_table/recipes/sanity_pick_place.yaml and studies/paper_table/recipes/sanity_door_sink.yaml (episode counts in
studies/paper_table/recipes/sanity.yaml), train split only; the val split is sampled by `--select-every`.

Resumable: a complete dataset is not built again (an incomplete one resumes), a run folder with
a summary.json is not trained again, an evaluation with its JSON is not run again. A skill that
fails is reported and the next one goes on.

The same path serves the camera learners (studies/learners/camera_learners.py: `CAMERAS` below): the
same episodes rendered with the head and wrist depth cameras on, learners that read depth and
proprioception, no privileged column and no target position. Each is a `Study`: its data and
test recipes, inputs, learners and default output.

Usage:
  python studies/learners/sanity_learners.py --workers 14                  # every skill
  python studies/learners/sanity_learners.py --skills Pick --workers 14    # one skill
  python studies/learners/sanity_learners.py --tiny --work /tmp/s --out /tmp/s.json   # the whole path in minutes
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))
from runner import commit  # noqa: E402  (re-exported: navigate_from_sound imports it from here)

# The recipes every learner here builds and is scored on: the paper table's family (paper_table.yaml, sanity*, cameras_*).
RECIPES = ROOT / "studies" / "paper_table" / "recipes"

from echo_data.records import PRIVILEGED_COLUMNS, PRIVILEGED_PREFIX  # noqa: E402

P = PRIVILEGED_PREFIX
# Most informative first (Pick is the hardest grasp, OpenDoor the multimodal one, Place shares
# Pick's data): the order `scripts/gpu_sanity.sh` runs them in under its budget.
SKILLS = ("Pick", "OpenDoor", "CloseSink", "Place")
# Skill -> its training recipe and its test recipes' group (recipes/sanity_test_<group>[_handover].yaml).
DATA = {"Pick": "sanity_pick_place", "Place": "sanity_pick_place", "OpenDoor": "sanity_door_sink", "CloseSink": "sanity_door_sink"}
TEST = {"Pick": "pick_place", "Place": "pick_place", "OpenDoor": "door", "CloseSink": "sink"}
# What each skill's learner reads: base-frame proprioception, the target kind (the grasp differs
# per object), the target's pose and the hand's offset to it; the door and the lever also their
# angle. Place's target pose is its place spot (docs/privileged_observations.md). Pick, Place and
# CloseSink also read `target`, the goal position of the paper's starred rows: the target's
# interaction pose (`skills.navigate.goal_pose`), which the learner sees in training as the
# segment's final base pose; for Pick and Place the two are the same pose, CloseSink's stance is
# 10 cm behind it along the facing direction in every episode checked (a fixed offset a learner
# takes in). Without it a learner cannot tell where its base must stop after a hand-over
# (validation, Pick after a hand-over: 2/10 without, 4/10 with; docs/learners.md). OpenDoor's base
# moves on with the leaf, so its final pose is not known when it starts: it does not read it.
INPUTS = {
    "Pick": ("state", "kind", "target", P + "target_pose", P + "tcp_to_target"),
    "Place": ("state", "kind", "target", P + "target_pose", P + "tcp_to_target"),
    "OpenDoor": ("state", "kind", P + "target_pose", P + "tcp_to_target", P + "joint_angle"),
    "CloseSink": ("state", "kind", "target", P + "target_pose", P + "tcp_to_target", P + "joint_angle"),
}
NON_PRIVILEGED = ("state", "kind", "target")
ACTION_COLUMNS = ("action.ee", "action")
# The learners tried per skill, each with its own options; the one with the best closed-loop
# validation success is tested (ties: the first listed). ACT as in docs/learners.md (chunk 20,
# temporal ensembling); "bc": an MLP over the state predicting 10-step chunks, acting on each new
# chunk's first action, its gripper switching when the chunk switches it within 6 steps
# (`--switch-ahead`, chosen on validation: docs/learners.md).
LEARNERS: dict[str, tuple[str, str]] = {
    "act": ("act", "--epochs 20 --select-every 10"),
    "bc": ("bc", "--epochs 150 --select-every 50 --chunk 10 --execute 1 --switch-ahead 6 --hidden 512 --batch-size 256"),
}
TINY_EPISODES = 3  # --tiny: train episodes built per dataset (`build --limit`)


@dataclass(frozen=True)
class Study:
    """One comparison of skill learners: which data each skill learns from (recipes/NAME.yaml),
    which test recipes score it (recipes/TEST.yaml and TEST_handover.yaml), what each learner
    reads, the candidate learners, and where the driver writes by default."""

    script: str  # the driver that runs it, as the results JSON names it
    data: dict[str, str]
    test: dict[str, str]
    inputs: dict[str, tuple[str, ...]]
    learners: dict[str, tuple[str, str]]
    plain_inputs: tuple[str, ...]  # the non-privileged inputs --inputs may name
    privileged: bool  # whether --inputs may name observation.privileged.* columns
    out: str  # default results file, relative to the checkout
    work: str  # default work folder, relative to the checkout
    default_learners: tuple[str, ...] = ()  # the candidates without --learners (empty: every learner)


PRIVILEGED = Study("studies/learners/sanity_learners.py", DATA, {s: f"sanity_test_{g}" for s, g in TEST.items()}, INPUTS, LEARNERS,
                   NON_PRIVILEGED, True, "studies/learners/results/sanity_learners.json", "out/sanity")

# The camera learners (issue 29's goal rows "each skill alone, from cameras and proprioception"):
# the sanity episodes rendered (recipes/cameras_*.yaml: the same recipes with head and wrist depth
# on), read as head depth, wrist depth (both area-downsampled to 64 px, random shift of 4 px:
# robomimic's augmentation), base-frame proprioception and the target kind. No privileged column
# and no target position. The learner is the privileged study's ACT, so the two compare the
# inputs alone.
CAMERA_INPUTS = ("depth", "wrist_depth", "state", "kind")
CAMERAS = Study("studies/learners/camera_learners.py",
                {"Pick": "cameras_pick_place", "Place": "cameras_pick_place", "OpenDoor": "cameras_door_sink", "CloseSink": "cameras_door_sink"},
                {s: f"cameras_test_{g}" for s, g in TEST.items()}, {s: CAMERA_INPUTS for s in SKILLS},
                {"act": ("act", "--epochs 20 --select-every 10 --shift 4"),
                 "act_chunk1": ("act", "--epochs 20 --select-every 10 --shift 4 --chunk 1"),  # the chunking ablation (--learners act_chunk1)
                 "diffusion": ("diffusion", "--epochs 20 --select-every 10 --shift 4")},  # multimodal actions (--learners diffusion)
                CAMERA_INPUTS, False, "studies/learners/results/camera_learners.json", "out/cameras", ("act",))  # what recipes/cameras_*.yaml store: no RGB


SPENT: list[str] = []  # one line per echo-data command: seconds, what, on what (printed at the end)


class Failed(Exception):
    """A step of one skill failed (its command, exit status and last output lines)."""


def usage_error(message: str) -> None:
    """Bad input: one line, exit 2, nothing written."""
    print(f"sanity_learners.py: {message}", file=sys.stderr)
    sys.exit(2)


def skill_override(flag: str, item: str, what: str) -> tuple[str, str]:
    """(skill, value) of one `SKILL=VALUE` option; anything else is a one-line usage error."""
    skill, sep, value = item.partition("=")
    if not sep or skill not in SKILLS:
        usage_error(f"{flag} {item!r}: expected SKILL={what} with SKILL one of {', '.join(SKILLS)}")
    return skill, value


def parse_inputs(overrides: list[str], study: Study = PRIVILEGED) -> dict[str, tuple[str, ...]]:
    """The study's inputs with `SKILL=a,b,...` overrides; every name checked before any work."""
    inputs = dict(study.inputs)
    known = study.plain_inputs + (tuple(PRIVILEGED_COLUMNS) if study.privileged else ())
    why = "no images: this learner renders nothing" if study.privileged else "no privileged column: this learner sees what a robot sees"
    for item in overrides:
        skill, cols = skill_override("--inputs", item, "COLUMN,...")
        names = tuple(c.strip() for c in cols.split(",") if c.strip())
        bad = [c for c in names if c not in known]
        if bad or not names:
            usage_error(f"--inputs {skill}: unknown column {', '.join(bad) or '(none given)'} (known: {', '.join(known)}; {why})")
        inputs[skill] = names
    return inputs


def parse_data(overrides: list[str], study: Study) -> dict[str, str]:
    """The study's training recipe per skill with `SKILL=RECIPE` overrides; each recipe must exist."""
    data = dict(study.data)
    for item in overrides:
        skill, value = skill_override("--data", item, "RECIPE")
        name = value.strip().removesuffix(".yaml").rsplit("/", 1)[-1]
        if not name:
            usage_error(f"--data {item!r}: expected SKILL=RECIPE with SKILL one of {', '.join(SKILLS)}")
        if not (RECIPES / f"{name}.yaml").is_file():
            usage_error(f"--data {skill}: no recipe {(RECIPES / f'{name}.yaml').relative_to(ROOT)}")
        data[skill] = name
    return data


def machine() -> str:
    """The machine in words (no paths, no host name): cores, accelerator, Python, torch."""
    words = [f"{os.cpu_count()} CPU cores", platform.machine(), f"Python {platform.python_version()}"]
    try:
        import torch

        words.append(f"torch {torch.__version__}")
        words.append(torch.cuda.get_device_name(0) if torch.cuda.is_available() else "no CUDA device")
    except ImportError:
        words.append("no torch")
    return ", ".join(words)


def shown(args: list[str], work: Path) -> str:
    """A command as the JSON records it (`public` words)."""
    return "echo-data " + " ".join(public(str(a), work) if not str(a).startswith("--policy=") else
                                   "=".join([*str(a).split("=")[:2], public(str(a).split("=", 2)[2], work)]) for a in args)


def public(arg: str, work: Path) -> str:
    """One command-line word as the results may show it: no path of this machine (inside the
    checkout: relative; under the work folder: WORK/...; elsewhere: OUT/<file name>)."""
    p = Path(arg)
    if not p.is_absolute():
        return arg
    p = Path(os.path.abspath(p))
    if p.is_relative_to(ROOT):
        return str(p.relative_to(ROOT))
    if p.is_relative_to(work):
        return str(Path("WORK") / p.relative_to(work))
    return str(Path("OUT") / p.name)


def echo_data(args: list[str], log: Path) -> tuple[str, float]:
    """Run `echo-data ARGS` from this checkout, its output appended to `log`; (stdout, seconds).
    Raises Failed with the last lines of its errors when it exits non-zero."""
    t0 = time.perf_counter()
    # One torch thread per process: evaluation runs --workers processes that each act with the
    # network on the CPU; with torch's default (all cores each) a 2-core machine under load took
    # 700 ms per ACT step instead of 9 ms (measured here).
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-m", "echo_data.cli", *args], cwd=ROOT, capture_output=True, text=True, env=env)
    seconds = time.perf_counter() - t0
    words = [str(x) for x in args]
    what = " ".join(words[:2] if words[0] == "train" else words[:1])
    about = next((w.rsplit("/", 1)[-1] for w in words if w.endswith(".yaml")), words[2].rsplit("/", 1)[-1] if len(words) > 2 else "")
    skill = words[words.index("--skill") + 1] if "--skill" in words else next((w.split("=")[1] for w in words if w.startswith("--policy=")), "")
    SPENT.append(f"{seconds:9.1f} s  {what} {skill} {about} (exit {r.returncode})")
    with log.open("a") as f:
        f.write(f"$ echo-data {' '.join(args)}\n# exit {r.returncode} after {seconds:.1f} s\n{r.stdout}{r.stderr}\n")
    if r.returncode != 0:
        tail = " | ".join((r.stderr or r.stdout).strip().splitlines()[-3:])
        raise Failed(f"echo-data {args[0]} {args[1] if len(args) > 1 else ''} exited {r.returncode}: {tail}")
    return r.stdout, seconds


def build(name: str, work: Path, workers: int, tiny: bool, log: Path) -> dict[str, Any]:
    """Build (or resume) the train split of recipes/NAME.yaml into WORK/data/NAME unless complete."""
    out = work / "data" / name
    manifest = out / "manifest.json"
    done = work / "data" / f"{name}.build.json"
    recipe_hash = recipe_of(name).content_hash()
    if manifest.is_file() and json.loads(manifest.read_text()).get("complete") and done.is_file() \
            and json.loads(done.read_text()).get("recipe_hash") in (recipe_hash, None):
        return {**json.loads(done.read_text()), "reused": True}  # (a changed recipe: `build --resume` decides)
    args = ["build", str(RECIPES / f"{name}.yaml"), "--split", "train", "--workers", str(workers), "--out", str(out), "--no-progress"]
    if tiny:
        args += ["--limit", str(TINY_EPISODES)]
    _, seconds = echo_data(args + (["--resume"] if manifest.is_file() else []), log)
    meta = json.loads(manifest.read_text())
    entry = {"command": shown(args, work), "seconds": round(seconds, 1), "counts": meta.get("counts", {}), "skills": meta.get("skills", {}), "recipe_hash": recipe_hash}
    done.write_text(json.dumps(entry, indent=1) + "\n")
    return entry


def recipe_of(name: str) -> Any:
    """recipes/NAME.yaml, loaded."""
    from echo_data.recipe import load_recipe

    return load_recipe(RECIPES / f"{name}.yaml")


def check_columns(data: Path, inputs: tuple[str, ...]) -> None:
    """A privileged input the dataset does not hold: one line naming the file and the column, exit 2."""
    info = data / "meta" / "info.json"
    held = set(json.loads(info.read_text()).get("privileged", [])) if info.is_file() else set()
    missing = [c for c in inputs if c.startswith(P) and c not in held]
    if missing:
        usage_error(f"{info}: no column {', '.join(missing)} in its 'privileged' list (a dataset built before the privileged columns?)")


def train(skill: str, data: Path, inputs: tuple[str, ...], column: str, learner: str, a: argparse.Namespace, log: Path) -> dict[str, Any]:
    """`echo-data train` of one skill, action column and learner (`LEARNERS`) unless its run folder holds a summary."""
    # A run on another recipe than the study's (--data), or from another seed, is named after it too.
    tag = ("" if a.data[skill] == a.study.data[skill] else f"-{a.data[skill]}") + ("" if a.seed == 0 else f"-seed{a.seed}")
    folder = a.work / "runs" / f"{skill}-{column}-{learner}{tag}"
    done = folder / "summary.json"
    if done.is_file():
        return {**json.loads(done.read_text()), "reused": True}
    if folder.exists():
        shutil.rmtree(folder)  # unfinished: train again (a resumed run would need its exact options)
    algo, options = a.study.learners[learner]
    own = [*(["--epochs", str(a.epochs)] if a.epochs is not None else []),  # after the learner's own: the command line wins
           *(["--select-every", str(a.select_every)] if a.select_every is not None else [])]
    args = ["train", algo, str(data), "--skill", skill, "--inputs", ",".join(inputs), "--action-column", column,
            "--device", a.device, *options.split(), *own,
            "--select-episodes", str(a.select_episodes), "--seed", str(a.seed), "--out", str(folder), "--no-progress"]
    stdout, seconds = echo_data(args, log)
    summary = json.loads(stdout)
    entry = {"command": shown(args, a.work), "seconds": round(seconds, 1), "run": folder.name, "learner": learner,
             "steps": summary.get("step"), "device": summary.get("device"), "rows": summary.get("rows"),
             "validation": summary.get("last"),  # the last epoch's validation: loss and closed-loop val_success
             "best_val_success": best_val_success(folder)}  # what best.pt scored: the candidates are compared on it
    done.write_text(json.dumps(entry, indent=1) + "\n")
    return entry


def evaluate(skill: str, run: str, recipe: str, a: argparse.Namespace, log: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Closed loop on the test split of recipes/RECIPE.yaml (test sounds): the learner drives
    `skill`, the experts every other skill; (the skill's k/n with Wilson 95 %, timing and command)."""
    out = a.work / "eval" / f"{run}-{recipe}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    args = ["evaluate", str(RECIPES / f"{recipe}.yaml"), "--split", "test", "-n", str(a.episodes),
            f"--policy={skill}={a.work / 'runs' / run}", "--policy", "oracle", "--planner", "oracle",
            "--workers", str(a.workers), "--json", str(out)]
    seconds = 0.0
    if not out.is_file():
        resume = ["--resume"] if out.with_suffix(".episodes.jsonl").is_file() else []
        _, seconds = echo_data(args + resume, log)
    doc = json.loads(out.read_text())
    return score(doc["episodes"], skill), {"command": shown(args, a.work), "seconds": round(seconds, 1)}


def score(episodes: list[dict[str, Any]], skill: str) -> dict[str, Any]:
    """The skill's successes over its attempts in evaluate's per-episode records, Wilson 95 %."""
    from echo_data.evaluation.metrics import wilson

    tries = [bool(s["success"]) for e in episodes for s in e.get("skills", ()) if s["skill"] == skill]
    low, high = wilson(sum(tries), len(tries))
    return {"successes": sum(tries), "n": len(tries), "low": round(low, 4), "high": round(high, 4)}


def best_val_success(folder: Path) -> float | None:
    """The best closed-loop validation success of a run's checkpoint choices (its best.pt), from
    the run's losses file (None: no closed-loop choice ran)."""
    import csv
    import math

    from echo_data.learn.runs import LOSSES

    with (folder / LOSSES).open() as f:
        seen = [float(r["val_success"]) for r in csv.DictReader(f) if r.get("val_success") not in (None, "", "nan")]
    seen = [v for v in seen if not math.isnan(v)]
    return max(seen) if seen else None


def best_run(trained: dict[str, dict[str, Any]]) -> str:
    """The candidate (action column and learner) whose best checkpoint scored best closed loop on
    validation (ties: the first tried)."""
    def val(entry: dict[str, Any]) -> float:
        best = entry.get("best_val_success")
        return float(best) if isinstance(best, (int, float)) else -1.0
    return max(trained, key=lambda c: val(trained[c]))


def run_skill(skill: str, inputs: tuple[str, ...], a: argparse.Namespace, doc: dict[str, Any], log: Path) -> None:
    """Build, train, choose, evaluate one skill; its entries go into `doc`."""
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    name = a.data[skill]
    if name not in doc["datasets"] or doc["datasets"][name].get("failed"):
        doc["datasets"][name] = build(name, a.work, a.workers, a.tiny, log)
        timing["build_s"] = 0.0 if doc["datasets"][name].get("reused") else doc["datasets"][name]["seconds"]
    else:
        timing["build_s"] = 0.0  # built for an earlier skill of this run
    data = a.work / "data" / name
    check_columns(data, inputs)
    trained = {f"{c}-{k}": train(skill, data, inputs, c, k, a, log) for c in a.action_columns for k in a.learners}
    chosen = best_run(trained)
    column = chosen.rsplit("-", 1)[0]
    timing["train_s"] = round(sum(0.0 if t.get("reused") else t["seconds"] for t in trained.values()), 1)
    run = trained[chosen]["run"]
    alone, cmd_alone = evaluate(skill, run, a.study.test[skill], a, log)
    doc["skills"][skill] = alone
    handover, cmd_handover = evaluate(skill, run, f"{a.study.test[skill]}_handover", a, log)
    doc["skills_handover"][skill] = handover
    timing["eval_s"] = round(cmd_alone["seconds"] + cmd_handover["seconds"], 1)
    timing["total_s"] = round(time.perf_counter() - t0, 1)
    doc["details"][skill] = {"driver": doc["command"], "data": name, "inputs": list(inputs), "action_column": column, "learner": trained[chosen]["learner"], "training": trained,
                             "evaluation": {"skills": cmd_alone["command"], "skills_handover": cmd_handover["command"]}}
    doc["timings"][skill] = timing


def main(study: Study = PRIVILEGED, description: str | None = None) -> None:
    """The driver of `study` (its command line, then every skill asked for)."""
    ap = argparse.ArgumentParser(description=description or __doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--skills", nargs="*", default=list(SKILLS), help=f"in this order (default {' '.join(SKILLS)})")
    ap.add_argument("--workers", type=int, default=2, help="build and evaluation worker processes")
    ap.add_argument("--work", type=Path, default=ROOT / study.work, help="datasets, run folders, evaluation JSONs and the log")
    ap.add_argument("--out", type=Path, default=ROOT / study.out)
    ap.add_argument("-n", "--episodes", type=int, default=50, help="test episodes per row (>= 50 for the acceptance figure)")
    ap.add_argument("--learners", default=",".join(study.default_learners or study.learners),
                    help=f"comma list of {', '.join(f'{k} ({v[0]} {v[1]})' for k, v in study.learners.items())}: each is trained, the best on validation tested")
    ap.add_argument("--epochs", type=int, default=None, help="epochs of every learner (default: each learner's own)")
    ap.add_argument("--select-every", type=int, default=None, help="closed-loop validation every N epochs and after the last (default: each learner's own)")
    ap.add_argument("--select-episodes", type=int, default=10, help="validation episodes per checkpoint choice")
    ap.add_argument("--action-columns", default="action.ee",
                    help="comma list of action columns to train; with two, the one with the better closed-loop validation is tested "
                         "(action needs recipes with robot.action_space: joint, see studies/paper_table/recipes/sanity.yaml)")
    ap.add_argument("--inputs", action="append", default=[], metavar="SKILL=COLUMNS", help="another input list for SKILL (repeatable)")
    ap.add_argument("--data", action="append", default=[], metavar="SKILL=RECIPE",
                    help="another training recipe for SKILL (recipes/RECIPE.yaml, e.g. a perturbation level: studies/paper_table/recipes/cameras_door_sink_p0.yaml); "
                         "its run folders and evaluations carry its name (repeatable)")
    ap.add_argument("--device", default="auto")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tiny", action="store_true", help=f"{TINY_EPISODES} train episodes, 1 epoch (a few steps) chosen on 1 val episode, 2 test episodes per row: the whole path in minutes")
    a = ap.parse_args()
    bad = [s for s in a.skills if s not in SKILLS]
    if bad or not a.skills:
        usage_error(f"--skills: unknown {', '.join(bad) or '(none given)'} (known: {', '.join(SKILLS)})")
    a.learners = [k.strip() for k in a.learners.split(",") if k.strip()]
    if not a.learners or any(k not in study.learners for k in a.learners):
        usage_error(f"--learners {','.join(a.learners)!r}: each must be one of {', '.join(study.learners)}")
    a.action_columns = [c.strip() for c in a.action_columns.split(",") if c.strip()]
    if not a.action_columns or any(c not in ACTION_COLUMNS for c in a.action_columns):
        usage_error(f"--action-columns {','.join(a.action_columns)!r}: each must be one of {', '.join(ACTION_COLUMNS)}")
    if a.workers < 1 or a.episodes < 1:
        usage_error("--workers and --episodes must be >= 1")
    inputs = parse_inputs(a.inputs, study)
    a.data = parse_data(a.data, study)
    a.study = study
    if a.tiny:
        a.episodes, a.epochs, a.select_every, a.select_episodes = 2, 1, 1, 1
    a.work = a.work.resolve()
    a.work.mkdir(parents=True, exist_ok=True)
    log = a.work / f"{Path(study.script).stem}.log"

    argv = " ".join(public(x, a.work) for x in sys.argv[1:])
    doc: dict[str, Any] = {"command": f"python {study.script} {argv}".strip(), "commit": commit(), "machine": machine(),
                           "episodes_per_row": a.episodes, "datasets": {}, "skills": {}, "skills_handover": {}, "timings": {},
                           "details": {}, "failed": {}}
    if a.out.is_file():  # an earlier run's skills stay unless measured again (scripts/gpu_sanity.sh runs one skill a call)
        old = json.loads(a.out.read_text())
        for key in ("skills", "skills_handover", "timings", "details", "failed", "datasets"):
            doc[key].update({s: v for s, v in old.get(key, {}).items() if s not in a.skills})
    for skill in a.skills:
        t0 = time.perf_counter()
        try:
            run_skill(skill, inputs[skill], a, doc, log)
            s, h = doc["skills"][skill], doc["skills_handover"][skill]
            print(f"{skill}: alone {s['successes']}/{s['n']}, after a hand-over {h['successes']}/{h['n']}; "
                  f"{json.dumps(doc['timings'][skill])}", file=sys.stderr)
        except Failed as e:  # go on with the next skill
            doc["failed"][skill] = {"error": str(e), "seconds": round(time.perf_counter() - t0, 1)}
            print(f"{skill}: FAILED after {time.perf_counter() - t0:.0f} s: {e}", file=sys.stderr)
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(doc, indent=1) + "\n")  # after every skill: a kill loses at most the one running
    print(json.dumps({k: doc[k] for k in ("skills", "skills_handover", "timings", "failed")}, indent=1))
    print("where the time went:\n" + "\n".join(SPENT), file=sys.stderr)
    sys.exit(1 if doc["failed"] else 0)


if __name__ == "__main__":
    main()
