"""The paper's main table on echo-data, closed loop: build the training data, train every skill
learner, evaluate the rows, write studies/paper_table/results/paper_table.json (every command and commit,
and a `summary` block), its markdown table and, with --render, the copies in this study's README and the repository's README.

What the rows are and what each needs: `rows.py` beside this driver; how entries are read,
composed, summarised and rendered: `echo_data.evaluation.table`. This driver only runs `echo-data` (build, train, evaluate) for the
rows asked for and merges what it measured into the JSON. Test split = test sounds only,
nothing tuned on it; Wilson 95 % intervals.

Evaluation recipes: `recipes/cameras_test_<setting>.yaml` (this folder's) put all test episodes of
`studies/paper_table/recipes/sanity.yaml`'s seed and sound split in one setting (or one event, or after a hand-over),
so `-n N` scores N episodes of it (`echo-data evaluate` samples them; the test split is never
built). A row whose recipe is not in this folder's recipes/ yet (the paper-comparable ones: `_magic`) waits,
said on stderr; so does a learner whose dataset's recipe is not there.

Training seeds: a learner of several (`LearnerSpec.seeds`) is trained once per seed, into RUNS/<learner>
for seed 0 (the folder a single-seed learner has always had) and RUNS/<learner>-s<seed> for the others,
and its rows are evaluated with the runs joined by `+` (`evaluation.seeds`: the -n episodes dealt out
over the seeds, so N is unchanged); the entry records the seeds, each seed's weights and figures.

Resumable: the data build resumes, finished run folders (a `summary.json` written here) are not
trained again, and an evaluation already in the JSON is not run again (they are the long part).
Several runs of this script (one row each, on their own cores) share one JSON: each merges what
it measured under a lock and writes atomically.

Usage:
  python studies/paper_table/paper_table.py                      # the whole table (hours on 2 cores)
  python studies/paper_table/paper_table.py --rows "Pick alone"  # one row
  python studies/paper_table/paper_table.py --learners Pick      # only build the data of and train a learner
  python studies/paper_table/paper_table.py --adopt EVAL.json ...  # take in evaluations run before (same recipe and weights)
  python studies/paper_table/paper_table.py --render             # only re-render the markdown and its copies (this README, the repository's) from the JSON
  python studies/paper_table/paper_table.py --tiny --data D --out J   # the test: a quickstart build D, a few steps, 1 episode of D's recipe (per training seed)
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
import rows as catalogue  # noqa: E402  (this folder's rows.py: the paper's catalogue)
from rows import LEARNERS, PLANNER, ROWS  # noqa: E402
from runner import ROOT, cli, commit  # noqa: E402

from echo_data.dataset.lock import BuildLock
from echo_data.dataset.storage import atomic_write_bytes, atomic_write_json
from echo_data.evaluation import table
from echo_data.evaluation.seeds import MEMBER_SEPARATOR as SEP
from echo_data.evaluation.table import ComposedRow, DerivedRow, EvaluatedRow, run_name
from echo_data.learn import runs as run_files

HERE = Path(__file__).resolve().parent
RECIPES = HERE / "recipes"  # the evaluation recipes (cameras_test_<setting>.yaml) and the training data's
DEFAULT_OUT = HERE / "results" / "paper_table.json"  # the README's copy renders this one


def rel(p: Path) -> str:
    """A path as the JSON stores it: relative to the repository when inside it (symbolic links
    kept: a dataset folder linked in from elsewhere is still named by its place here)."""
    p = Path(os.path.abspath(p))
    return str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p)


def command(args: list[str]) -> str:
    """The `echo-data` command as the JSON records it (paths relative to the repository, also the
    run folder of a `--policy=SKILL=RUN`)."""

    def shown(x: str) -> str:
        if x.startswith("--policy=") and x.count("=") == 2:  # a run, or one per training seed joined by `+`
            skill, runs = x.removeprefix("--policy=").split("=")
            return f"--policy={skill}=" + SEP.join(rel(Path(r)) for r in runs.split(SEP))
        return rel(Path(x)) if Path(x).exists() else x

    return "echo-data " + " ".join(shown(x) for x in args)


def eval_json(runs: Path, name: str, setting: str) -> Path:
    """Where the `echo-data evaluate --json` document of row `name` on `setting` lives."""
    for a, b in ((" ", "_"), ("*", "star"), ("(", ""), (")", "")):
        name = name.replace(a, b)
    return runs / f"eval-{name}-{setting}.json"


def build(recipe: Path, split: str | None, out: Path, workers: int, doc: dict[str, Any]) -> Path:
    """Build (or resume) `split` of `recipe` (None: every split) into `out` unless complete; records the command."""
    manifest = out / "manifest.json"
    if not (manifest.is_file() and json.loads(manifest.read_text()).get("complete")):
        args = ["build", str(recipe), *(["--split", split] if split else []), "--workers", str(workers), "--out", str(out), "--no-progress"]
        _, seconds = cli(*args, *(["--resume"] if manifest.is_file() else []))
        doc.setdefault("datasets", {})[out.name] = {"command": command(args), "wall_seconds": round(seconds, 1), "commit": commit()}
    return out


def finished(folder: Path) -> dict[str, Any] | None:
    """The summary of a finished run folder; an unfinished one is removed (a resumed run would
    need its exact options), None."""
    done = folder / "summary.json"
    if done.is_file():
        return dict(json.loads(done.read_text()))
    if folder.exists():
        shutil.rmtree(folder)
    return None


def seed_runs(learner: str) -> list[str]:
    """The run folders (names under RUNS, the JSON's `training` keys) of `learner`, one per training seed."""
    return [run_name(learner, seed) for seed in LEARNERS[learner].trained_seeds]


def policy_args(row: EvaluatedRow, runs: Path, skills: set[str] | None = None) -> list[str]:
    """`--policy=SKILL=RUN` per learned skill of `row` (of those in `skills`, when given); a learner
    of several seeds gives its runs joined by `+`, so the evaluation shares the episodes out over
    them (`evaluation.seeds`)."""
    return [f"--policy={s}=" + SEP.join(str(runs / r) for r in seed_runs(learner)) for s, learner in row.policy.items()
            if skills is None or s in skills]


def drive_end_args(row: EvaluatedRow) -> list[str]:
    """`--drive-end X` for a row whose learned drive ends otherwise than evaluate's default."""
    return [] if row.drive_end == "handover" else ["--drive-end", row.drive_end]


def called(doc: dict[str, Any]) -> set[str]:
    """The skills some episode of an `echo-data evaluate --json` document called."""
    return {s["skill"] for e in doc["episodes"] for s in e.get("skills", [])}


def row_seeds(row: EvaluatedRow) -> dict[str, list[int]]:
    """The training seeds of each skill of `row` whose learner has several ({} for one training
    each): the entry's `seeds`, member j of its `per_seed` being the j-th."""
    return {s: list(LEARNERS[learner].trained_seeds) for s, learner in row.policy.items() if len(LEARNERS[learner].trained_seeds) > 1}


def train(data: Path, runs: Path, name: str, tiny: bool) -> dict[str, dict[str, Any]] | None:
    """Train learner `name` on dataset `data`, once per training seed, unless the seed's run folder
    holds a finished run: {run name: its summary}; None when its skill has no rows."""
    from echo_data.learn.data import skills_in

    spec = LEARNERS[name]
    if spec.skill not in skills_in(data, "train"):
        return None
    out = {}
    for seed in spec.trained_seeds:
        folder = runs / run_name(name, seed)
        if (summary := finished(folder)) is None:
            args = ["train", spec.algo, str(data), "--skill", spec.skill, "--inputs", spec.inputs, *spec.options_for(seed), "--out", str(folder),
                    "--no-progress", *(["--max-steps", "2"] if tiny else [])]
            stdout, seconds = cli(*args)
            summary = {**json.loads(stdout), "command": command(args), "wall_seconds": round(seconds, 1), "run": rel(folder), "commit": commit()}
            run_files.write_json(folder, "summary.json", summary)  # listed in the run's marker: train --overwrite may replace it
        out[folder.name] = summary
    return out


def train_planner(data: Path, runs: Path, tiny: bool) -> dict[str, Any]:
    """Train the planner (`echo-data train planner`, options fixed in PLANNER, chosen on
    validation) unless its run folder holds a finished run, then score it once on the test split
    of its own dataset (`echo-data evaluate-planner`: training never reads it); its summary: both
    commands, the validation choice (eval.json) and the test-split scores (test.json)."""
    folder = runs / "planner"
    done = folder / "summary.json"
    if done.is_file():
        return dict(json.loads(done.read_text()))
    args = ["train", "planner", str(data), *PLANNER.options, "--out", str(folder), "--overwrite", "--no-progress", *(["--max-steps", "2"] if tiny else [])]
    stdout, seconds = cli(*args)
    report = json.loads(stdout)
    test_args = ["evaluate-planner", str(folder), str(data)]
    scored = json.loads(cli(*test_args)[0])
    summary = {"command": command(args), "test_command": command(test_args), "wall_seconds": round(seconds, 1), "run": rel(folder), "commit": commit(),
               **{k: report[k] for k in ("episodes", "best") if k in report}, "test": scored["test"]}
    summary["episodes"] = {**summary.get("episodes", {}), **scored["episodes"]}
    run_files.write_json(folder, done.name, summary)
    return summary


def evaluate(recipe: Path, row: EvaluatedRow, planner: str, runs: Path, n: int, workers: int, out: Path) -> dict[str, Any]:
    """`echo-data evaluate` of one row on one recipe: the row's entry (command, commit, seconds, measurement)."""
    args = ["evaluate", str(recipe), "--split", "test", "-n", str(n), *policy_args(row, runs),
            "--policy", "oracle", "--planner", planner, "--workers", str(workers), *drive_end_args(row), "--json", str(out)]
    if out.with_suffix(".episodes.jsonl").is_file():  # a killed evaluation's journal: continue it
        args.append("--resume")
    _, seconds = cli(*args)
    return {"command": command(args), "wall_seconds": round(seconds, 1), "commit": commit(), **table.measured(json.loads(out.read_text())),
            **({"seeds": seeds} if (seeds := row_seeds(row)) else {})}


def checkpoints(doc: dict[str, Any]) -> dict[str, list[str | None]]:
    """Per learned skill of an `echo-data evaluate --json` document, the checkpoint SHA-256 of its
    run folder (`folder_sha256`) in each member (one per training seed; one member without `+`)."""
    members = doc["policy"].get("members") or [doc["policy"]]
    each = [{s: v.get("checkpoint_sha256") for s, v in m.get("skills", {}).items() if s != "*"} for m in members]
    return {s: [m.get(s) for m in each] for s in each[0]}


def adopt(path: Path, runs: Path, n: int, workers: int) -> tuple[str, str, dict[str, Any]]:
    """Take an evaluation measured before (an `echo-data evaluate --json` document, e.g. a study's
    run of a skill alone) into the table as the entry of the row and setting it is: the same
    recipe file and content, the test split, `n` episodes, the oracle planner, and for every
    learned skill the same weights as the table's learner (`folder_sha256` of RUNS/<learner>),
    seed by seed for a learner of several (the evaluation's `+` list in the learner's seed order).
    Anything else is refused (exit 2, one line): an adopted entry is exactly what `evaluate`
    would have measured, so its command is the one that repeats it. Returns (row, setting, entry)."""
    from echo_data.agents.loading import folder_sha256
    from echo_data.recipe import load_recipe

    doc = json.loads(path.read_text())
    recipe = Path(doc["recipe"]["path"]).name
    evaluated = checkpoints(doc)
    why = []
    for name, row in ROWS.items():
        # A row's learner that no episode of the setting calls (Pick in state transition) need not
        # be in the evaluation: the episodes are the same with it or without it.
        if not isinstance(row, EvaluatedRow) or row.planner != "oracle" or not set(evaluated) <= set(row.policy) \
                or (set(row.policy) - set(evaluated)) & called(doc) or doc.get("drive_end", "handover") != row.drive_end:
            continue
        # In an evaluation over several seeds, a skill of one training acts in every member with the
        # same run: that is one run, as the row's learner is.
        learned = {s: hs[:1] if len(seed_runs(row.policy[s])) == 1 and len(set(hs)) == 1 else hs for s, hs in evaluated.items()}
        for setting in row.settings:
            if catalogue.recipe(row, setting) != recipe:
                continue
            if (h := load_recipe(RECIPES / recipe).content_hash()) != doc["recipe"]["content_hash"]:
                why.append(f"recipes/{recipe} changed since (content hash {h[:12]}, the evaluation's {doc['recipe']['content_hash'][:12]})")
            elif doc["split"] != "test" or doc["n"] != n:
                why.append(f"it scored {doc['n']} episodes of {doc['split']}, the table {n} of test")
            elif any(len(hs) != len(seed_runs(row.policy[s])) for s, hs in learned.items()):
                why.append(f"row {name!r}: " + ", ".join(f"{s} has {len(seed_runs(row.policy[s]))} training seed(s), the evaluation {len(hs)} run(s)"
                                                          for s, hs in learned.items()))
            elif any(not (runs / r).is_dir() or folder_sha256(runs / r) != h for s, hs in learned.items() for r, h in zip(seed_runs(row.policy[s]), hs, strict=True)):
                why.append(f"row {name!r}: its learners in {rel(runs)} ({', '.join(r for s in learned for r in seed_runs(row.policy[s]))}) are not the evaluated weights")
            else:
                out = eval_json(runs, name, setting)
                atomic_write_json(out, doc)  # where the driver keeps the row's document (a computed row may read it)
                args = ["evaluate", str(RECIPES / recipe), "--split", "test", "-n", str(n), *policy_args(row, runs, set(learned)),
                        "--policy", "oracle", "--planner", "oracle", "--workers", str(workers), *drive_end_args(row), "--json", str(out)]
                shas = ", ".join(f"{s} {SEP.join(str(h)[:12] for h in hs)}" for s, hs in learned.items())
                return name, setting, {"command": command(args), "wall_seconds": round(float(doc["wall_seconds"]), 1), "commit": commit(),
                                       "adopted": f"measured before this run of the table by the same command on the same recipe and weights "
                                                  f"(checkpoint sha256 {shas}); taken from its --json document",
                                       **table.measured(doc), **({"seeds": seeds} if (seeds := row_seeds(row)) else {})}
    print(f"error: --adopt {path}: " + ("; ".join(why) if why else f"no oracle-planner row evaluates {', '.join(evaluated) or 'the experts'} on recipes/{recipe}"),
          file=sys.stderr)
    sys.exit(2)


def tiny_recipe(data: Path, runs: Path) -> Path:
    """--tiny's evaluation recipe: the one `data` was built from (its manifest's copy, written to
    RUNS/tiny_recipe.yaml), so the learners act in the action space they cloned."""
    import yaml

    out = runs / "tiny_recipe.yaml"
    atomic_write_bytes(out, yaml.safe_dump(json.loads((data / "manifest.json").read_text())["recipe"], sort_keys=False).encode())
    return out


def computed(row: ComposedRow | DerivedRow, setting: str, runs: Path) -> dict[str, Any] | None:
    """The entry of a row computed from measured rows' evaluation documents; None (said on stderr)
    while one is missing."""
    sources = [eval_json(runs, src, setting) for src in ((row.plans, row.outcomes) if isinstance(row, ComposedRow) else (row.source,))]
    if not all(p.is_file() for p in sources):
        print(f"{row.name} / {setting}: waits for {', '.join(rel(p) for p in sources if not p.is_file())}", file=sys.stderr)
        return None
    docs = [json.loads(p.read_text()) for p in sources]
    how = f"python studies/paper_table/paper_table.py --rows '{row.name}' (from {' and '.join(rel(p) for p in sources)})"
    if isinstance(row, ComposedRow):
        return {"command": how, "wall_seconds": 0.0, "commit": commit(), **table.composed(docs[0], docs[1]), "computed_from": [rel(p) for p in sources]}
    return {"command": how, "commit": commit(), **table.derived(docs[0], row.skill), "computed_from": [rel(p) for p in sources]}


def render(doc: dict[str, Any], out: Path, readme: bool) -> str:
    """Write the markdown of `doc` beside the JSON (and, with `readme`, the copies in this study's
    README and the repository's README: `rows.copies`)."""
    md = catalogue.markdown(doc)
    atomic_write_bytes(out.with_suffix(".md"), md.encode())
    if readme:
        for path, begin, end, rendered in catalogue.copies(ROOT):
            atomic_write_bytes(path, catalogue.with_rendered_copy(path.read_text(), begin, end, rendered(doc)).encode())
    return md


def save(out: Path, mine: dict[str, Any]) -> dict[str, Any]:
    """Merge this run's datasets, training and rows into the JSON on disk and write it (with its
    summary) and its markdown atomically, under a lock: several runs of this script share one
    JSON, and each only adds what it measured. Returns the merged document."""
    with BuildLock(out.parent, name=f".{out.name}.lock", wait=True):
        doc: dict[str, Any] = json.loads(out.read_text()) if out.is_file() else {}
        for key in ("datasets", "training"):
            doc.setdefault(key, {}).update(mine.get(key, {}))
        for name, per in mine.get("rows", {}).items():  # per setting: a row's other settings stay
            doc.setdefault("rows", {}).setdefault(name, {}).update(per)
        doc.setdefault("rows", {})
        doc.update({k: v for k, v in mine.items() if k not in ("datasets", "training", "rows")})
        doc["summary"] = catalogue.summary(doc)
        atomic_write_json(out, doc)
        render(doc, out, readme=False)
    return doc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data-root", type=Path, default=ROOT / "out", help="the training datasets are built (or resumed) in DATA_ROOT/<recipe name>")
    ap.add_argument("--data", type=Path, default=None, help="with --tiny: the one dataset every learner trains on")
    ap.add_argument("--runs", type=Path, default=ROOT / "runs" / "paper_table", help="run folders of the learners and evaluation JSONs")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("-n", "--episodes", type=int, default=50, help="test episodes per setting and row")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--planner-run", default=None, help="a trained planner run folder for the learned-planner rows (default: the planner this script trains, RUNS/planner)")
    ap.add_argument("--no-planner", action="store_true", help="leave out the learned-planner rows (and the planner's data and training)")
    ap.add_argument("--rows", nargs="*", default=None, help="only these rows (names as in the JSON)")
    ap.add_argument("--learners", nargs="*", default=None, help="only build the data of and train these learners (names as in LEARNERS, or planner); no evaluation")
    ap.add_argument("--render", action="store_true", help="run nothing: rewrite the JSON's summary and the markdown from its entries (and its copies in the READMEs, for the default --out)")
    ap.add_argument("--adopt", nargs="*", type=Path, default=None, metavar="EVAL_JSON",
                    help="take these `echo-data evaluate --json` documents (same recipe, test split, -n, weights as RUNS/<learner>) in as their rows' entries; nothing else runs")
    ap.add_argument("--tiny", action="store_true", help="the test's version: --data's build (a quickstart), 2 training steps, 1 episode of its recipe")
    a = ap.parse_args()
    if a.render:
        if not a.out.is_file():
            ap.error(f"--render: {rel(a.out)} does not exist")
        print(render(save(a.out, {}), a.out, readme=a.out.resolve() == DEFAULT_OUT.resolve()))
        return
    n = 1 if a.tiny else a.episodes
    if a.adopt is not None:
        for path in a.adopt:
            name, setting, entry = adopt(path, a.runs, n, a.workers)
            save(a.out, {"commit": commit(), "rows": {name: {setting: entry}}})
            print(f"{name} / {setting}: {table.cell(table.skill_success(json.loads(path.read_text())['episodes'], ROWS[name].skill_alone) if ROWS[name].skill_alone else entry['metrics'].get('skill_completion'))} (adopted)", file=sys.stderr)
        return
    if a.tiny and a.data is None:
        ap.error("--tiny needs --data (a quickstart dataset)")
    unknown = sorted(set(a.rows or ()) - set(ROWS)) + sorted(set(a.learners or ()) - {*LEARNERS, "planner"})
    if unknown:
        ap.error(f"unknown rows or learners {unknown} (rows: {', '.join(ROWS)}; learners: {', '.join([*LEARNERS, 'planner'])})")
    mine: dict[str, Any] = {"episodes_per_setting": n, "commit": commit(), "datasets": {}, "training": {}, "rows": {}}
    trained = dict(json.loads(a.out.read_text()).get("training", {})) if a.out.is_file() else {}
    a.runs.mkdir(parents=True, exist_ok=True)

    planner_run = a.planner_run or str(a.runs / "planner")
    chosen = {name: row for name, row in ROWS.items() if (a.rows is None or name in a.rows) and not (a.no_planner and catalogue.needs_learned_planner(row))}
    if a.learners is not None:  # training only: one lane of a table filled by several runs of this script
        chosen = {}
    evaluated = [r for r in chosen.values() if isinstance(r, EvaluatedRow)]
    needed = [name for name in LEARNERS if any(name in r.policy.values() for r in evaluated) or name in (a.learners or ())]  # only what the rows drive
    wants_planner = a.planner_run is None and not a.no_planner and (any(r.planner == "learned" for r in evaluated) or "planner" in (a.learners or ()))
    data: dict[str, Path] = {}
    for key in dict.fromkeys([*(LEARNERS[name].dataset for name in needed), *([PLANNER.dataset] if wants_planner else [])]):
        recipe = ROOT / catalogue.DATASETS[key].recipe
        if a.tiny:
            data[key] = a.data
        elif recipe.is_file():
            data[key] = build(recipe, catalogue.DATASETS[key].split, a.data_root / key, a.workers, mine)
        else:
            print(f"dataset {key}: waits for {rel(recipe)}", file=sys.stderr)
    for name in needed:  # `training` is keyed by run folder: one per training seed (seed 0's is the learner's name)
        if LEARNERS[name].dataset in data and (done_runs := train(data[LEARNERS[name].dataset], a.runs, name, a.tiny)) is not None:
            mine["training"].update(done_runs)
    if wants_planner and PLANNER.dataset in data:
        mine["training"]["planner"] = train_planner(data[PLANNER.dataset], a.runs, a.tiny)
    trained.update(mine["training"])
    save(a.out, mine)
    for name, row in chosen.items():
        if isinstance(row, EvaluatedRow) and (untrained := [r for learner in row.policy.values() for r in seed_runs(learner) if r not in trained]):
            print(f"{name}: waits for the learners {', '.join(untrained)}", file=sys.stderr)
            continue
        done = json.loads(a.out.read_text()).get("rows", {}).get(name, {})  # another run of this script may have measured it
        for setting in row.settings if not a.tiny else ("quickstart",):
            if setting in done:
                continue  # measured already: evaluations are the long part
            if not isinstance(row, EvaluatedRow):  # from measured rows' episodes, once they are there
                if (entry := computed(row, setting, a.runs)) is not None:
                    mine["rows"] = {name: {setting: entry}}
                    save(a.out, mine)
                continue
            rec = tiny_recipe(a.data, a.runs) if a.tiny else RECIPES / catalogue.recipe(row, setting)
            if not rec.is_file() or (a.tiny and row.grasp != "physical"):
                print(f"{name} / {setting}: waits for {rel(RECIPES / catalogue.recipe(row, setting))}", file=sys.stderr)
                continue
            seeds = max((len(x) for x in row_seeds(row).values()), default=1)
            res = evaluate(rec, row, "oracle" if row.planner == "oracle" else planner_run, a.runs, n * seeds if a.tiny else n, a.workers,
                           eval_json(a.runs, name, setting))  # --tiny: an episode per seed
            mine["rows"] = {name: {setting: res}}
            save(a.out, mine)  # after every evaluation: a kill loses at most the one running (its journal resumes it)
            print(f"{name} / {setting}: {table.cell(res['metrics'].get('skill_completion'))}", file=sys.stderr)
    mine["rows"] = {}
    print(catalogue.markdown(save(a.out, mine)))


if __name__ == "__main__":
    main()
