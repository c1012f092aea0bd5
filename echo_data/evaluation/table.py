"""The paper's main table (its Fig. 4a) on echo-data, as data: which rows exist and what each
needs, how a row's entry is read from `echo-data evaluate --json` documents, how two measured
rows compose into a third, the `summary` block a script reads without knowing the layout, and
the markdown the README shows.

Running anything (builds, training, evaluations, git) is `benchmarks/paper_table.py`'s job; this
module only describes and reads. Rows:
- oracle planner + scripted experts (the upper bound the data allows);
- oracle planner + learned skills, the drives without the target position (the paper's
  "Oracle") and with it ("*", the paper's "Oracle*"): the paper gives it to Navigate; here Place
  gets it too, because our Place drives the held object to its receptacle (named only by its
  kind otherwise), which is a navigation of its own;
- learned planner + scripted experts, measured; + learned skills, composed from that row and the
  oracle-planner row (`composed` says why that is the closed-loop result);
- each skill alone: its learner drives that skill, the scripted experts the others; success =
  the skill's success test over every attempt of it;
- the paper-comparable rows: the same with Habitat's grasp (`robot.grasp: magic`, which the
  paper's skills use) instead of our physical one; starred, the target position given. Specs
  until measured: the table says "not measured", never a number.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from typing import Any, Literal

from echo_data.evaluation.metrics import plan_right_without_receptacle, proportion, summarise, wilson
from echo_data.evaluation.provenance import composed_weights, stale_rows

SKILLS = ("Navigate", "Pick", "Place", "OpenDoor", "CloseSink")
SETTINGS = ("object_relocation", "state_transition", "multi_event")
PAPER_ORDER = ("state_transition", "object_relocation", "multi_event")  # the paper's column order
PAPER_COMPARABLE = " (paper-comparable)"
NOT_MEASURED = "not measured"
STOP_CHAIN = "oracle planner + learned skills, Navigate says STOP"
STOP_NEAR_CHAIN = STOP_CHAIN + ", OpenDoor from near starts"
Grasp = Literal["physical", "magic"]


@dataclass(frozen=True)
class DatasetSpec:
    """A training dataset: its recipe (a file in recipes/) and the split built (None: every split)."""

    recipe: str
    split: str | None = "train"


@dataclass(frozen=True)
class LearnerSpec:
    """A skill learner: `echo-data train ALGO DATASET --skill SKILL --inputs INPUTS OPTIONS...`."""

    dataset: str
    skill: str
    inputs: str
    algo: str = "bc"
    options: tuple[str, ...] = ()


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

    @property
    def skill_alone(self) -> str | None:
        return self.skill

    def recipe(self, setting: str) -> str:
        """The evaluation recipe of `setting` (a file in recipes/): every test episode in one
        setting (or one event, or after a hand-over), so `-n N` scores N episodes of it; `_magic`
        the same with `robot.grasp: magic`."""
        return f"cameras_test_{setting}{'_magic' if self.grasp == 'magic' else ''}.yaml"


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

# Training data: dataset (its folder under --data-root) -> recipe (a path from the repository
# root). The learners clone the closed-loop experts' end-effector actions (`action.ee`) from
# demonstrations under the shipped perturbation whose manipulation starts anywhere in Navigate's
# success region (recipes/sanity.yaml says what they share): Pick and Place from
# recipes/cameras_pick_place.yaml (150 object-relocation episodes), OpenDoor and CloseSink from
# recipes/cameras_door_sink.yaml (300 state-transition episodes), both with head and wrist depth;
# Navigate from benchmarks/recipes/nav_audio.yaml (600 episodes, no camera: it hears its way).
# The planner learns from recipes/planner_fresh.yaml (episodes cut after 10 frames, a fresh
# synthesised voice per training event; built whole: once trained (choosing on validation), the
# planner is scored on that build's own test split by `echo-data evaluate-planner RUN`). The
# magic-grasp build (recipes/cameras_pick_place_magic.yaml: the same 150 episodes with
# `robot.grasp: magic`) is the paper-comparable rows' Pick and Place data.
DATASETS: dict[str, DatasetSpec] = {
    "cameras_pick_place": DatasetSpec("recipes/cameras_pick_place.yaml"),
    "cameras_door_sink": DatasetSpec("recipes/cameras_door_sink.yaml"),
    "nav_audio": DatasetSpec("benchmarks/recipes/nav_audio.yaml"),
    "planner_fresh": DatasetSpec("recipes/planner_fresh.yaml", None),
    "cameras_pick_place_magic": DatasetSpec("recipes/cameras_pick_place_magic.yaml"),
    "nav_audio_stop": DatasetSpec("benchmarks/recipes/nav_audio_stop.yaml"),
    "cameras_door_near": DatasetSpec("recipes/cameras_door_near.yaml"),
}
# The planner run: audio only, the checkpoint of the best balanced validation accuracy of 20
# epochs (chosen on validation among the planner_fresh runs: benchmarks/results/planner_fresh.json).
PLANNER = PlannerSpec("planner_fresh", ("--inputs", "audio", "--select", "accuracy", "--epochs", "20"))
# Skill learners, each chosen on validation by its study. Manipulation: ACT (chunk 20, temporal
# ensembling) over head and wrist depth, proprioception and the target kind, random shift 4, the
# checkpoint of the best closed-loop validation success at epochs 10 and 20
# (benchmarks/camera_learners.py; its ablations: benchmarks/results/camera_ablations.json).
# Navigate: a GRU over the skill's steps reading the binaural level and ILD (no camera), chosen
# every 5 epochs on validation (benchmarks/navigate_from_sound.py); the chain hands over at the
# first step Navigate's success test holds. Every learner gets the target
# kind its chain entry names; the starred ones also the target position (the paper's Oracle*).
MANIPULATION = ("--action-column", "action.ee", "--device", "auto", "--epochs", "20", "--select-every", "10", "--shift", "4",
                "--select-episodes", "10", "--seed", "0")
MANIPULATION_INPUTS = "depth,wrist_depth,state,kind"
NAVIGATE = ("--audio-form", "level_ild", "--action-column", "action.ee", "--epochs", "20", "--select-every", "5", "--select-episodes", "10",
            "--device", "auto", "--seed", "0")
LEARNERS: dict[str, LearnerSpec] = {
    "Navigate": LearnerSpec("nav_audio", "Navigate", "audio,state,kind", "bc-rnn", NAVIGATE),
    "Navigate-target": LearnerSpec("nav_audio", "Navigate", "audio,state,kind,target", "bc-rnn", NAVIGATE),
    **{s: LearnerSpec("cameras_pick_place", s, MANIPULATION_INPUTS, "act", MANIPULATION) for s in ("Pick", "Place")},
    "Place-target": LearnerSpec("cameras_pick_place", "Place", MANIPULATION_INPUTS + ",target", "act", MANIPULATION),
    **{s: LearnerSpec("cameras_door_sink", s, MANIPULATION_INPUTS, "act", MANIPULATION) for s in ("OpenDoor", "CloseSink")},
    # Paper-comparable: Pick and Place cloned from demonstrations with the magic grasp (the grasp
    # changes what Pick and Place do; the drives and the door and sink skills are the same).
    "Pick-magic": LearnerSpec("cameras_pick_place_magic", "Pick", MANIPULATION_INPUTS, "act", MANIPULATION),
    "Place-magic": LearnerSpec("cameras_pick_place_magic", "Place", MANIPULATION_INPUTS, "act", MANIPULATION),
    "Place-target-magic": LearnerSpec("cameras_pick_place_magic", "Place", MANIPULATION_INPUTS + ",target", "act", MANIPULATION),
    # The hand-over study: Navigate's options plus a STOP output (`--stop`), cloned from the same
    # episodes with the expert's Navigate ending at the interaction pose (nav_audio_stop.yaml), so
    # the learner ends its own skill there instead of being cut at the rim of its success region.
    "Navigate-stop": LearnerSpec("nav_audio_stop", "Navigate", "audio,state,kind", "bc-rnn", (*NAVIGATE, "--stop")),
    # The stance study (docs/learners.md, "OpenDoor stands where it is"): cloned from door
    # episodes whose expert grasps from where Navigate stopped when it can, hand-overs within 0.3
    # of the success region (cameras_door_near.yaml); the table's OpenDoor options with a
    # spatial-softmax encoder (keypoints: where the bar is), chosen on 20 validation episodes over
    # the strided CNN at 64 px (5/20) and at 128 px (8/20, tied: the smaller input kept).
    "OpenDoor-near": LearnerSpec("cameras_door_near", "OpenDoor", MANIPULATION_INPUTS, "act", (*MANIPULATION, "--encoder", "spatial_softmax")),
}
# Where each manipulation skill is scored alone: recipes/cameras_test_<setting>.yaml, 50 test
# episodes of its own event, the skills before it done by the experts with Navigate stopping at
# the exact interaction pose; "after a hand-over", the same episodes with the oracle Navigate
# stopping anywhere in its success region (`experts.handover_noise` 1.0), as a learned Navigate
# hands over. Navigate alone is read from the chain rows (`_rows`).
ALONE_SETTINGS = {"Navigate": ("object_relocation", "state_transition"), "Pick": ("pick_place",), "Place": ("pick_place",),
                  "OpenDoor": ("door",), "CloseSink": ("sink",)}


def _rows() -> dict[str, Row]:
    """The catalogue in the paper's order: oracle-planner rows, then learned-planner rows, each
    ours (physical grasp) before the paper-comparable ones; then the skills alone."""
    learned = {s: s for s in SKILLS}
    starred = {**learned, "Navigate": "Navigate-target", "Place": "Place-target"}  # the drives are given their target
    magic = {**learned, "Pick": "Pick-magic", "Place": "Place-magic"}
    magic_starred = {**starred, "Pick": "Pick-magic", "Place": "Place-target-magic"}
    experts = "oracle planner + scripted experts"
    chain: list[Row] = [EvaluatedRow(name=experts, planner="oracle", settings=SETTINGS)]
    pc = PAPER_COMPARABLE
    grasps: tuple[Grasp, Grasp] = ("physical", "magic")
    variants: list[tuple[dict[str, str], str, Grasp]] = [(learned, "", "physical"), (starred, "*", "physical"), (magic, "", "magic"), (magic_starred, "*", "magic")]
    for policy, star, grasp in variants:
        suffix = star + (pc if grasp == "magic" else "")
        chain.append(EvaluatedRow(name=f"oracle planner + learned skills{suffix}", planner="oracle", policy=policy, settings=SETTINGS, grasp=grasp))
    for grasp in grasps:
        tail = pc if grasp == "magic" else ""
        chain.append(EvaluatedRow(name=f"learned planner + scripted experts{tail}", planner="learned", settings=SETTINGS, grasp=grasp))
        for star in ("", "*"):
            chain.append(ComposedRow(name=f"learned planner + learned skills{star}{tail}", plans=f"learned planner + scripted experts{tail}",
                                     outcomes=f"oracle planner + learned skills{star}{tail}", settings=SETTINGS, grasp=grasp))
    alone: list[Row] = []
    for s in SKILLS:
        alone.append(EvaluatedRow(name=f"{s} alone", planner="oracle", policy={s: s}, settings=ALONE_SETTINGS[s], skill=s))
    for s in ("Pick", "Place", "OpenDoor", "CloseSink"):  # where the chain hands them over
        alone.append(EvaluatedRow(name=f"{s} after a hand-over", planner="oracle", policy={s: s}, settings=tuple(f"{x}_handover" for x in ALONE_SETTINGS[s]),
                                  skill=s))
    alone.append(EvaluatedRow(name="Place* alone", planner="oracle", policy={"Place": "Place-target"}, settings=ALONE_SETTINGS["Place"], skill="Place"))
    for s, learner in (("Pick", "Pick-magic"), ("Place", "Place-magic")):
        alone.append(EvaluatedRow(name=f"{s} alone{pc}", planner="oracle", policy={s: learner}, settings=ALONE_SETTINGS[s], skill=s, grasp="magic"))
    alone.append(EvaluatedRow(name=f"Place* alone{pc}", planner="oracle", policy={"Place": "Place-target-magic"}, settings=ALONE_SETTINGS["Place"],
                              skill="Place", grasp="magic"))
    # The hand-over study (docs/learners.md, "A Navigate that says STOP"): Navigate-stop alone (the
    # experts after it), and the state-transition chain after it; object relocation and multi-event
    # would add Pick and Place to the row's policy.
    stop = {"Navigate": "Navigate-stop"}
    chain.append(EvaluatedRow(name=STOP_CHAIN, planner="oracle", policy={**stop, "OpenDoor": "OpenDoor", "CloseSink": "CloseSink"},
                              settings=("state_transition",)))
    # ... and with the OpenDoor cloned from near hand-overs (the stance study): a STOP that hands
    # over near the interaction pose is what that learner was trained for.
    chain.append(EvaluatedRow(name=STOP_NEAR_CHAIN, planner="oracle", policy={**stop, "OpenDoor": "OpenDoor-near", "CloseSink": "CloseSink"},
                              settings=("state_transition",)))
    alone.append(EvaluatedRow(name="Navigate (STOP) alone", planner="oracle", policy=stop, settings=ALONE_SETTINGS["Navigate"], skill="Navigate"))
    for name, settings in (("OpenDoor (near starts) alone", ALONE_SETTINGS["OpenDoor"]), ("OpenDoor (near starts) after a hand-over", ("door_handover",))):
        alone.append(EvaluatedRow(name=name, planner="oracle", policy={"OpenDoor": "OpenDoor-near"}, settings=settings, skill="OpenDoor"))
    out = {r.name: r for r in [*chain, *alone]}
    # Navigate is the first skill of every single-event chain, so its outcome alone (experts after
    # it) is its outcome in the oracle-planner chain row, step for step (an episode is a pure
    # function of recipe, split, index and policies; `derived`'s docstring).
    for star in ("", "*"):
        name = f"Navigate{star} alone"
        out[name] = DerivedRow(name=name, source=f"oracle planner + learned skills{star}", skill="Navigate", settings=ALONE_SETTINGS["Navigate"])
    return out


ROWS: dict[str, Row] = _rows()


def needs_learned_planner(row: Row) -> bool:
    """Whether `row` (or a row it is computed from) runs the learned planner."""
    if isinstance(row, EvaluatedRow):
        return row.planner == "learned"
    return any(needs_learned_planner(ROWS[src]) for src in ((row.plans, row.outcomes) if isinstance(row, ComposedRow) else (row.source,)))


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
    return {"metrics": {**{k: metrics[k] for k in ("episodes", "task_planning", "skill_completion", "progressive", "navigate_success") if k in metrics},
                        "planning_without_place_target": planning_without_place_target(doc["episodes"]),
                        "navigate_shortfall": handover(doc["episodes"])},
            "skills": {s: skill_success(doc["episodes"], s) for s in SKILLS},
            **({"weights": doc["weights"]} if doc.get("weights") else {})}  # what it was measured with (evaluation.provenance)


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


def interval(k: int, n: int) -> dict[str, Any]:
    """A summary cell: successes, N and the Wilson 95 % interval."""
    lo, hi = wilson(k, n)
    return {"successes": k, "n": n, "low": round(lo, 4), "high": round(hi, 4)}


def summary(doc: dict[str, Any]) -> dict[str, Any]:
    """The block a script reads without knowing the table's layout (None: not measured):
    `skills_alone.<label>` (label: the skill-alone row's name without " alone"),
    `completion.<row>.<setting>`, `planning.<row>.<setting>` (exact chain) and
    `planning_without_receptacle.<row>.<setting>`, each {successes, n, low, high}; a skill-alone
    cell taken from the previous session says so (`"previous_session": true`)."""
    out: dict[str, Any] = {"skills_alone": {}, "completion": {}, "planning": {}, "planning_without_receptacle": {}}
    for row in ROWS.values():
        per, previous = entries(doc, row.name)
        skill = row.skill_alone
        if skill is not None:
            cell = interval(*alone_count(per, skill)) if per else None
            out["skills_alone"][row.label] = cell if cell is None or not previous else {**cell, "previous_session": True}
            continue
        for key, metric in (("completion", "skill_completion"), ("planning", "task_planning"), ("planning_without_receptacle", "planning_without_place_target")):
            out[key][row.name] = {}
            for setting in dict.fromkeys([*row.settings, *per]):
                p = per.get(setting, {}).get("metrics", {}).get(metric)
                out[key][row.name][setting] = None if p is None else interval(p["k"], p["n"])
    return out


# --- the markdown ------------------------------------------------------------------------------

def cell(p: dict[str, Any] | None) -> str:
    """A proportion as k/n = value [95 % interval]."""
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['k']}/{p['n']} = {p['value']:.2f} [{lo:.2f}, {hi:.2f}]"


def short(p: dict[str, Any] | None) -> str:
    """A proportion as a cell of the paper-shaped table: value [95 % interval] (k/n)."""
    if not p or p.get("value") is None:
        return "–"
    lo, hi = p["ci95"]
    return f"{p['value']:.2f} [{lo:.2f}, {hi:.2f}] ({p['k']}/{p['n']})"


def _words(setting: str) -> str:
    return setting.replace("_", " ")


def markdown(doc: dict[str, Any]) -> str:
    """The README tables, in the catalogue's order: the paper's layout (a row per planner/skills
    combination, planning and completion per setting), the progressive success of each row and
    setting, exact and receptacle-free planning where they differ, the skills alone. A row with
    no entry reads "not measured"."""
    read = {name: entries(doc, name) for name in ROWS}
    stale = stale_rows({name: per for name, (per, _) in read.items()})  # measured with weights no longer shipped (evaluation.provenance)
    mark = {name: " †" * any("computed_from" in e for e in per.values()) + " ‡" * previous + " §" * (name in stale) for name, (per, previous) in read.items()}
    chain = [r for r in ROWS.values() if r.skill_alone is None]
    head = ["| row | " + " | ".join(f"{_words(s)}: planning | completion" for s in PAPER_ORDER) + " |", "|---|" + "---|---|" * len(PAPER_ORDER)]
    prog = ["| row | setting | progressive success (through skill 1, 2, ...) |", "|---|---|---|"]
    both = ["| row | setting | planning, exact chain | planning without the Place receptacle (the paper's sense) |", "|---|---|---|---|"]
    for row in chain:
        per = read[row.name][0]
        if not per:
            head.append(f"| {row.name} | " + " | ".join([NOT_MEASURED] * 2 * len(PAPER_ORDER)) + " |")
            continue
        cells = []
        for setting in PAPER_ORDER:
            m = per.get(setting, {}).get("metrics", {})
            cells += [short(m.get("task_planning")), short(m.get("skill_completion"))] if setting in per else [NOT_MEASURED] * 2
        head.append(f"| {row.name}{mark[row.name]} | " + " | ".join(cells) + " |")
        for setting in PAPER_ORDER:
            if setting not in per:
                continue
            m = per[setting].get("metrics", {})
            prog.append(f"| {row.name}{mark[row.name]} | {_words(setting)} | " + "; ".join(cell(p) for p in m.get("progressive", [])) + " |")
            if m.get("planning_without_place_target") and m["planning_without_place_target"]["k"] != m.get("task_planning", {}).get("k"):
                both.append(f"| {row.name}{mark[row.name]} | {_words(setting)} | {cell(m['task_planning'])} | {cell(m['planning_without_place_target'])} |")
    if len(both) > 2:
        prog += ["", *both]
    alone = ["| skill alone | settings | success |", "|---|---|---|"]
    for row in ROWS.values():
        skill = row.skill_alone
        if skill is None:
            continue
        per = read[row.name][0]
        settings = ", ".join(_words(s) for s in (per or row.settings))
        alone.append(f"| {row.label}{mark[row.name]} | {settings} | {cell(proportion(*alone_count(per, skill))) if per else NOT_MEASURED} |")
    notes = []
    if any("†" in m for m in mark.values()):
        notes.append("† computed from the episodes of two measured rows (the same test episodes): a learned-planner row takes each "
                     "episode's plan from the learned planner's run with the experts and, where that plan is right, the outcome of the "
                     "oracle-planner row's run of the same episode; a derived skill-alone row reads the skill's attempts in a chain row "
                     "(`composed` and `derived` in echo_data/evaluation/table.py say why this is exact).")
    if any("‡" in m for m in mark.values()):
        notes.append("‡ the previous session's measurement (`previous_session` in the JSON): " + doc["previous_session"].get("note", ""))
    if stale:
        notes.append("§ stale: measured with weights that are not the shipped reference learners' (echo_data/reference/manifest.json); re-measure it.")
    if any(r.grasp == "magic" for r in ROWS.values()):
        notes.append("paper-comparable: Habitat's grasp (`robot.grasp: magic`, the one the paper's skills use) instead of "
                     "ours (finger friction alone), Pick and Place cloned from demonstrations with that grasp; starred, the drives are "
                     f"given the target position as in the paper's Oracle*. \"{NOT_MEASURED}\": a row the table defines and has "
                     "not run yet.")
    return "\n".join(head) + "\n\n" + "\n".join(prog) + "\n\n" + "\n".join(alone) + "\n" + "".join(f"\n{n}\n" for n in notes)


# --- the README's copy -------------------------------------------------------------------------

README_BEGIN = "<!-- paper table: rendered from benchmarks/results/paper_table.json by echo_data.evaluation.table.markdown"
README_END = "<!-- end of the paper table -->"


def readme_block(readme: str) -> str:
    """The table as the README holds it, between its two markers."""
    begin = readme.index(README_BEGIN)
    start = readme.index("\n", begin) + 1
    return readme[start:readme.index(README_END, start)]


def with_readme_block(readme: str, table: str) -> str:
    """`readme` with the table between its markers replaced by `table`."""
    begin = readme.index(README_BEGIN)
    start = readme.index("\n", begin) + 1
    return readme[:start] + table + readme[readme.index(README_END, start):]
