"""A results table of closed-loop evaluations, as data: the kinds of row (evaluated by `echo-data
evaluate`, composed from two evaluated rows, derived from a chain row's episodes), the training
specs a row's learners need, how a row's entry is read from `echo-data evaluate --json`
documents, how two measured rows compose into a third, the `summary` block a script reads
without knowing the layout, and the markdown of a catalogue of rows.

The package owns the machinery only; a concrete catalogue (which rows, which learners, which
recipes) belongs to the study that measures it: the paper's main table (its Fig. 4a) lives with
its driver, among the studies. Nothing here runs anything (builds, training,
evaluations, git). Row kinds, as the paper's table uses them:
- oracle planner + scripted experts (the upper bound the data allows);
- oracle planner + learned skills, with or without the target position given to the drives;
- learned planner + scripted experts, measured; + learned skills, composed from that row and the
  oracle-planner row (`composed` says why that is the closed-loop result);
- each skill alone: its learner drives that skill, the scripted experts the others; success =
  the skill's success test over every attempt of it.
A row with no entry yet reads "not measured", never a number.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from typing import Any, Literal

from echo_data.evaluation.metrics import plan_right_without_receptacle, proportion, summarise, wilson
from echo_data.evaluation.provenance import composed_weights, stale_rows
from echo_data.skill_table import SKILLS as SKILL_TABLE


def __getattr__(name: str) -> Any:
    """`SKILLS`: every skill a row reports, in the skill table's order, read from the table when
    asked (a copy taken at import would keep whatever the table held then, e.g. a test's toy skill)."""
    if name == "SKILLS":
        return tuple(SKILL_TABLE)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


NOT_MEASURED = "not measured"
Grasp = Literal["physical", "magic"]


@dataclass(frozen=True)
class DatasetSpec:
    """A training dataset: its recipe (a path from the repository root) and the split built (None: every split)."""

    recipe: str
    split: str | None = "train"


@dataclass(frozen=True)
class LearnerSpec:
    """A skill learner: `echo-data train ALGO DATASET --skill SKILL --inputs INPUTS OPTIONS...`,
    trained once per seed of `seeds` (empty: the one seed its options give, `--seed`, else 0).
    A row of a learner with several seeds is measured over all of them, the episodes shared out
    (`evaluation.seeds`): one training is not a figure."""

    dataset: str
    skill: str
    inputs: str
    algo: str = "bc"
    options: tuple[str, ...] = ()
    seeds: tuple[int, ...] = ()

    @property
    def trained_seeds(self) -> tuple[int, ...]:
        """The training seeds, in the order a row's `+` list gives their runs."""
        if self.seeds:
            return self.seeds
        opts = list(self.options)
        return (int(opts[opts.index("--seed") + 1]),) if "--seed" in opts else (0,)

    def options_for(self, seed: int) -> tuple[str, ...]:
        """The training options of seed `seed`: `options` with its `--seed` (or one added)."""
        opts = list(self.options)
        if "--seed" not in opts:
            return (*opts, "--seed", str(seed))
        i = opts.index("--seed")
        return (*opts[: i + 1], str(seed), *opts[i + 2:])


def run_name(learner: str, seed: int) -> str:
    """The run folder of `learner`'s training seed `seed`: seed 0 keeps the learner's own name (the
    folder every single-seed learner has always had), another seed adds `-s<seed>`."""
    return learner if seed == 0 else f"{learner}-s{seed}"


@dataclass(frozen=True)
class PlannerSpec:
    """The learned planner: `echo-data train planner DATASET OPTIONS... --out RUN` (trains and
    chooses on validation), then `echo-data evaluate-planner RUN DATASET` (the test split, asked for once)."""

    dataset: str
    options: tuple[str, ...]


@dataclass(frozen=True, kw_only=True)
class RowSpec:
    """A row of the table: its name (the JSON's key), the settings it is scored on, the grasp."""

    name: str
    settings: tuple[str, ...]
    grasp: Grasp = "physical"

    @property
    def skill_alone(self) -> str | None:
        """The skill a skill-alone row reports (None: a chain row)."""
        return None

    @property
    def label(self) -> str:
        """The row's name in the skill-alone table and the summary: the skill's learner, no " alone"."""
        return self.name.replace(" alone", "")


@dataclass(frozen=True, kw_only=True)
class EvaluatedRow(RowSpec):
    """A row measured by `echo-data evaluate`: the planner ("oracle" or the learned one) and the
    learner that drives each skill named in `policy` (the scripted experts drive the others)."""

    planner: Literal["oracle", "learned"]
    policy: dict[str, str] = field(default_factory=dict)
    skill: str | None = None  # a skill-alone row: the skill whose success it reports
    drive_end: str = "handover"  # how a learned drive that does not STOP ends (`evaluate --drive-end`, agents.runtime.DRIVE_ENDS)

    @property
    def skill_alone(self) -> str | None:
        return self.skill


@dataclass(frozen=True, kw_only=True)
class ComposedRow(RowSpec):
    """A learned-planner + learned-skills row composed from two measured rows' episodes: the
    plans of `plans` (the learned planner with the experts), the outcomes of `outcomes` (the
    oracle planner with the learned skills). `composed` says why this is exact."""

    plans: str
    outcomes: str


@dataclass(frozen=True, kw_only=True)
class DerivedRow(RowSpec):
    """A skill-alone row read from a chain row's episodes (`derived`)."""

    source: str
    skill: str

    @property
    def skill_alone(self) -> str | None:
        return self.skill


Row = EvaluatedRow | ComposedRow | DerivedRow



def needs_learned_planner(row: Row, rows: dict[str, Row]) -> bool:
    """Whether `row` (or a row of `rows` it is computed from) runs the learned planner."""
    if isinstance(row, EvaluatedRow):
        return row.planner == "learned"
    return any(needs_learned_planner(rows[src], rows) for src in ((row.plans, row.outcomes) if isinstance(row, ComposedRow) else (row.source,)))


# --- a row's entry, from `echo-data evaluate --json` documents ------------------------------------

def skill_success(episodes: list[dict[str, Any]], skill: str) -> dict[str, Any]:
    """Successes of `skill` over every attempt of it in per-episode records, Wilson 95 %."""
    tries = [bool(s["success"]) for e in episodes for s in e.get("skills", ()) if s["skill"] == skill]
    return proportion(sum(tries), len(tries))


def planning_without_place_target(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """The share of plans right but for the Place receptacle (`plan_right_without_receptacle`)."""
    eps = [e for e in episodes if "skipped" not in e]
    return proportion(sum(plan_right_without_receptacle(e["planned_chain"], e["true_chain"]) for e in eps), len(eps))


def handover(episodes: list[dict[str, Any]]) -> dict[str, Any] | None:
    """Where the first Navigate handed over: per successful first Navigate, the expert's planned
    path from the skill's start minus the path the base drove (m; > 0: stopped short of where the
    expert stops, the pose every manipulation demonstration starts from), as quartiles and N.
    docs/learners.md, "In the chain", says why this decides the chain."""
    first = [nv for e in episodes if "skipped" not in e for nv in e["navigate"][:1]
             if nv["skill_index"] == 0 and nv["success"] and nv["expert_length"] is not None]
    if len(first) < 2:
        return None

    def quartiles(xs: list[float], scale: float = 1.0) -> list[float]:
        return [round(q * scale, 3) for q in statistics.quantiles(xs, n=4)]

    out: dict[str, Any] = {"n": len(first), "quartiles_m": quartiles([nv["expert_length"] - nv["path_length"] for nv in first])}
    # The hand-over pose against the expert's stop, where recorded (evaluations since the fields
    # were added): base distance from the interaction pose, heading error, how far the arm moved.
    for key, name, scale in (("goal_distance", "goal_distance_m", 1.0), ("heading_error", "heading_error_deg", 180 / math.pi),
                             ("arm_moved", "arm_moved_rad", 1.0)):
        xs = [nv[key] for nv in first if nv.get(key) is not None]
        if len(xs) == len(first):
            out[name] = quartiles(xs, scale)
    return out


def measured(doc: dict[str, Any]) -> dict[str, Any]:
    """A row's measurement from `echo-data evaluate --json`'s document: the paper's metrics, the
    planning without the receptacle, the hand-over, and every skill's success over its attempts."""
    metrics: dict[str, Any] = doc["metrics"].get("all") or next(iter(doc["metrics"].values()), {})
    return {"metrics": {**{k: metrics[k] for k in ("episodes", "task_planning", "skill_completion", "progressive", "navigate_success", "navigate_handover") if k in metrics},
                        "planning_without_place_target": planning_without_place_target(doc["episodes"]),
                        "navigate_shortfall": handover(doc["episodes"])},
            "skills": {s: skill_success(doc["episodes"], s) for s in SKILL_TABLE},  # the table now: a skill added later is in it
            **({"weights": doc["weights"]} if doc.get("weights") else {}),  # what it was measured with (evaluation.provenance)
            **({"per_seed": per_member(doc)} if doc.get("seeds") else {})}


def per_member(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """Each training seed's own figures in an evaluation over several (`evaluation.seeds`: episode
    i acted by member i mod k), member by member: its skill completion (the evaluation's
    `seeds.per_seed`) and the success of every skill it attempted."""
    out = []
    for j, completion in enumerate(doc["seeds"]["per_seed"]):
        eps = [e for e in doc["episodes"] if e.get("member") == j]
        out.append({"skill_completion": completion, "skills": {s: p for s in SKILL_TABLE if (p := skill_success(eps, s))["n"]}})
    return out


def composed(plans: dict[str, Any], runs_of: dict[str, Any]) -> dict[str, Any]:
    """A learned-planner + learned-skills row from two measured evaluations of the same test
    episodes: `plans` (the learned planner with the scripted experts: which plans are right) and
    `runs_of` (the oracle planner with the learned skills: what the skills do). Why this is the
    closed-loop result and not an estimate: `run_episode` ends an episode at a wrong plan, and
    after a right plan (the true chain, which is what the oracle planner gives) the planner is
    never consulted again, so the episode is step for step the oracle-planner episode of the
    same index (SAPIEN's CPU physics and the learners' inference are deterministic: the first
    Navigate of 25 test episodes evaluated in two separate runs was identical, path length and
    steps). Composing saves re-running the expensive half of every episode on two cores."""
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
    return measured({"metrics": {"all": summarise(out)}, "episodes": out, "weights": composed_weights(plans, runs_of)})


def derived(source: dict[str, Any], skill: str) -> dict[str, Any]:
    """A skill-alone entry read from a chain row's episodes: the skill's success over its attempts."""
    return {"skills": {skill: skill_success(source["episodes"], skill)}}


# --- reading the results document ------------------------------------------------------------

def entries(doc: dict[str, Any], name: str) -> tuple[dict[str, Any], bool]:
    """Row `name`'s entries per setting, and whether they are the previous session's (the
    document's `previous_session.rows`, read only where this session has no entry of the row)."""
    if doc.get("rows", {}).get(name):
        return doc["rows"][name], False
    prev = doc.get("previous_session", {}).get("rows", {}).get(name)
    return (prev, True) if prev else ({}, False)


def alone_count(per: dict[str, Any], skill: str) -> tuple[int, int]:
    """A skill-alone row's successes and attempts over all its settings."""
    tries = [e["skills"][skill] for e in per.values()]
    return sum(t["k"] for t in tries), sum(t["n"] for t in tries)


def alone_seed_counts(per: dict[str, Any], skill: str) -> list[tuple[int, int]] | None:
    """A skill-alone row measured over several training seeds: each seed's successes and attempts
    over all its settings (member j of every entry is the same seed); None for one training."""
    each = [e.get("per_seed") for e in per.values()]
    if not each or any(not x for x in each) or len({len(x) for x in each if x}) != 1:
        return None
    counts = [[(m["skills"].get(skill) or {"k": 0, "n": 0}) for m in x] for x in each if x]
    return [(sum(c[j]["k"] for c in counts), sum(c[j]["n"] for c in counts)) for j in range(len(counts[0]))]


def setting_seed_counts(entry: dict[str, Any], metric: str = "skill_completion") -> list[tuple[int, int]] | None:
    """A chain entry's `metric` per training seed; None for one training."""
    each = entry.get("per_seed")
    return [(m[metric]["k"], m[metric]["n"]) for m in each] if each else None


def interval(k: int, n: int, seeds: list[tuple[int, int]] | None = None) -> dict[str, Any]:
    """A summary cell: successes, N and the Wilson 95 % interval (and, measured over several
    training seeds, each seed's successes and N)."""
    lo, hi = wilson(k, n)
    return {"successes": k, "n": n, "low": round(lo, 4), "high": round(hi, 4),
            **({"per_seed": [{"successes": a, "n": b} for a, b in seeds]} if seeds else {})}


def summary(doc: dict[str, Any], rows: dict[str, Row]) -> dict[str, Any]:
    """The block a script reads without knowing the table's layout (None: not measured):
    `skills_alone.<label>` (label: the skill-alone row's name without " alone"),
    `completion.<row>.<setting>`, `planning.<row>.<setting>` (exact chain) and
    `planning_without_receptacle.<row>.<setting>`, each {successes, n, low, high}; a skill-alone
    cell taken from the previous session says so (`"previous_session": true`)."""
    out: dict[str, Any] = {"skills_alone": {}, "completion": {}, "planning": {}, "planning_without_receptacle": {}}
    for row in rows.values():
        per, previous = entries(doc, row.name)
        skill = row.skill_alone
        if skill is not None:
            cell = interval(*alone_count(per, skill), alone_seed_counts(per, skill)) if per else None
            out["skills_alone"][row.label] = cell if cell is None or not previous else {**cell, "previous_session": True}
            continue
        for key, metric in (("completion", "skill_completion"), ("planning", "task_planning"), ("planning_without_receptacle", "planning_without_place_target")):
            out[key][row.name] = {}
            for setting in dict.fromkeys([*row.settings, *per]):
                p = per.get(setting, {}).get("metrics", {}).get(metric)
                seeds = setting_seed_counts(per[setting]) if p is not None and metric == "skill_completion" else None
                out[key][row.name][setting] = None if p is None else interval(p["k"], p["n"], seeds)
    return out


# --- the markdown ------------------------------------------------------------------------------

def cell(p: dict[str, Any] | None) -> str:
    """A proportion as k/n = value [95 % interval]."""
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['k']}/{p['n']} = {p['value']:.2f} [{lo:.2f}, {hi:.2f}]"


def seed_range(seeds: list[tuple[int, int]] | None) -> str:
    """Per-seed successes/N as their range, the lowest share first: "3 seeds 12/17–16/17"
    ("" for one training; "each" when every seed scored the same)."""
    if not seeds:
        return ""
    scored = sorted((k / n, k, n) for k, n in seeds if n)
    if not scored:
        return f"{len(seeds)} seeds –"
    lo, hi = (f"{k}/{n}" for _, k, n in (scored[0], scored[-1]))
    return f"{len(seeds)} seeds {lo} each" if lo == hi and len(scored) == len(seeds) else f"{len(seeds)} seeds {lo}–{hi}"


def short(p: dict[str, Any] | None, seeds: list[tuple[int, int]] | None = None) -> str:
    """A proportion as a cell of the paper-shaped table: value [95 % interval] (k/n), and the
    per-seed range of a row measured over several training seeds."""
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['value']:.2f} [{lo:.2f}, {hi:.2f}] ({p['k']}/{p['n']}{'; ' + seed_range(seeds) if seeds else ''})"


def _words(setting: str) -> str:
    return setting.replace("_", " ")


def markdown(doc: dict[str, Any], rows: dict[str, Row], order: tuple[str, ...]) -> str:
    """The tables of catalogue `rows`, in its order: a row per planner/skills combination,
    planning and completion per setting of `order` (the column order), the progressive success of each row and
    setting, exact and receptacle-free planning where they differ, the skills alone. A row with
    no entry reads "not measured"."""
    read = {name: entries(doc, name) for name in rows}
    stale = stale_rows({name: per for name, (per, _) in read.items()})  # measured with weights no longer shipped (evaluation.provenance)
    mark = {name: " †" * any("computed_from" in e for e in per.values()) + " ‡" * previous + " §" * (name in stale) for name, (per, previous) in read.items()}
    chain = [r for r in rows.values() if r.skill_alone is None]
    head = ["| row | " + " | ".join(f"{_words(s)}: planning | completion" for s in order) + " |", "|---|" + "---|---|" * len(order)]
    prog = ["| row | setting | progressive success (through skill 1, 2, ...) |", "|---|---|---|"]
    both = ["| row | setting | planning, exact chain | planning without the Place receptacle (the paper's sense) |", "|---|---|---|---|"]
    for row in chain:
        per = read[row.name][0]
        if not per:
            head.append(f"| {row.name} | " + " | ".join([NOT_MEASURED] * 2 * len(order)) + " |")
            continue
        cells = []
        for setting in order:
            m = per.get(setting, {}).get("metrics", {})
            cells += [short(m.get("task_planning")), short(m.get("skill_completion"), setting_seed_counts(per[setting]))] if setting in per else [NOT_MEASURED] * 2
        head.append(f"| {row.name}{mark[row.name]} | " + " | ".join(cells) + " |")
        for setting in order:
            if setting not in per:
                continue
            m = per[setting].get("metrics", {})
            prog.append(f"| {row.name}{mark[row.name]} | {_words(setting)} | " + "; ".join(cell(p) for p in m.get("progressive", [])) + " |")
            if m.get("planning_without_place_target") and m["planning_without_place_target"]["k"] != m.get("task_planning", {}).get("k"):
                both.append(f"| {row.name}{mark[row.name]} | {_words(setting)} | {cell(m['task_planning'])} | {cell(m['planning_without_place_target'])} |")
    if len(both) > 2:
        prog += ["", *both]
    alone = ["| skill alone | settings | success |", "|---|---|---|"]
    for row in rows.values():
        skill = row.skill_alone
        if skill is None:
            continue
        per = read[row.name][0]
        settings = ", ".join(_words(s) for s in (per or row.settings))
        seeds = seed_range(alone_seed_counts(per, skill)) if per else ""
        alone.append(f"| {row.label}{mark[row.name]} | {settings} | {cell(proportion(*alone_count(per, skill))) + ('; ' + seeds if seeds else '') if per else NOT_MEASURED} |")
    notes = []
    if any("†" in m for m in mark.values()):
        notes.append("† computed from the episodes of two measured rows (the same test episodes): a learned-planner row takes each "
                     "episode's plan from the learned planner's run with the experts and, where that plan is right, the outcome of the "
                     "oracle-planner row's run of the same episode; a derived skill-alone row reads the skill's attempts in a chain row "
                     "(`composed` and `derived` in echo_data/evaluation/table.py say why this is exact).")
    if any("‡" in m for m in mark.values()):
        notes.append("‡ the previous session's measurement (`previous_session` in the JSON): " + doc["previous_session"].get("note", ""))
    if any(e.get("per_seed") for per, _ in read.values() for e in per.values()):
        notes.append("\"K seeds a/b–c/d\": a row measured over K training seeds of its learners, the test episodes dealt out over "
                     "them in turn (echo_data/evaluation/seeds.py): the pooled figure with its Wilson interval, then the lowest and the "
                     "highest seed's own successes/episodes (each entry's `per_seed` in the JSON, member j the j-th of its `seeds`).")
    if stale:
        notes.append("§ stale: measured with weights that are not the shipped reference learners' (echo_data/reference/manifest.json); re-measure it.")
    if any(r.grasp == "magic" for r in rows.values()):
        notes.append("paper-comparable: Habitat's grasp (`robot.grasp: magic`, the one the paper's skills use) instead of "
                     "ours (finger friction alone), Pick, Place and OpenDoor (on the door's handle bar) cloned from demonstrations with that grasp "
                     "(each entry's command names the learners it ran); starred, the drives are "
                     f"given the target position as in the paper's Oracle*. \"{NOT_MEASURED}\": a row the table defines and has "
                     "not run yet.")
    return "\n".join(head) + "\n\n" + "\n".join(prog) + "\n\n" + "\n".join(alone) + "\n" + "".join(f"\n{n}\n" for n in notes)


# --- a rendered copy inside a document (e.g. a README) ---------------------------------------------

def block(text: str, begin: str, end: str) -> str:
    """What `text` holds between the line that starts with marker `begin` and marker `end`."""
    start = text.index("\n", text.index(begin)) + 1
    return text[start:text.index(end, start)]


def with_block(text: str, begin: str, end: str, table: str) -> str:
    """`text` with what lies between its markers `begin` and `end` replaced by `table`."""
    start = text.index("\n", text.index(begin)) + 1
    return text[:start] + table + text[text.index(end, start):]
