"""The result tables of the studies' READMEs, rendered from their results JSON: each README holds
a copy between two markers (`<!-- results: NAME ... -->` and `<!-- end of results: NAME -->`),
which `python studies/results_tables.py` rewrites and tests/test_docs.py checks. (The paper
table renders its own: studies/paper_table/rows.py.)"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from typing import Any

from runner import ROOT

sys.path.insert(0, str(ROOT))
from echo_data.evaluation.table import block, with_block  # noqa: E402

STUDIES = ROOT / "studies"


def interval(c: dict[str, Any] | None) -> str:
    """A {successes, n, low, high} or {k, n, ci95} or {correct, n, ci95} cell as k/n [low, high]."""
    if not c:
        return "–"
    k = c.get("successes", c.get("k", c.get("correct")))
    lo, hi = (c["low"], c["high"]) if "low" in c else c["ci95"]
    return f"{k}/{c['n']} [{lo:.2f}, {hi:.2f}]"


def skills(doc: dict[str, Any]) -> str:
    """A learner study's skills: alone (exact hand-over) and after a spread hand-over."""
    lines = ["| skill | alone | after a hand-over |", "|---|---|---|"]
    for s in doc["skills"]:
        lines.append(f"| {s} | {interval(doc['skills'][s])} | {interval(doc.get('skills_handover', {}).get(s))} |")
    return "\n".join(lines) + "\n"


def navigate(doc: dict[str, Any]) -> str:
    """Navigate from sound on the test split: overall and per setting, and its SPL."""
    t = doc["test"]
    lines = ["| test episodes | Navigate success |", "|---|---|", f"| all | {interval(t['navigate'])} |"]
    lines += [f"| {s.replace('_', ' ')} | {interval(c)} |" for s, c in t["by_setting"].items()]
    return "\n".join(lines) + f"\n\nMean SPL {t['spl']:.2f}.\n"


def ablation(doc: dict[str, Any]) -> str:
    """The Navigate ablation's rows: the learner's inputs, first and all Navigate successes, SPL."""
    lines = ["| inputs | first Navigate | every Navigate | mean SPL |", "|---|---|---|---|"]
    for r in doc["navigate"]:
        spl = "–" if r.get("spl_mean") is None else f"{r['spl_mean']:.2f}"
        lines.append(f"| {r['inputs']} | {interval(r['first_navigate'])} | {interval(r['all_navigate'])} | {spl} |")
    return "\n".join(lines) + "\n"


def planner(doc: dict[str, Any]) -> str:
    """The planner rows on the test split: events in order, single and multi-event, and the exact chain."""
    lines = ["| inputs | options | single event: events in order | multi-event: events in order | all: exact chain |", "|---|---|---|---|---|"]
    for r in doc["rows"]:
        t = r.get("test", {})
        cells = [interval(t.get(g, {}).get(m)) for g, m in (("single_event", "events_in_order"), ("multi_event", "events_in_order"), ("all", "chain_exact"))]
        lines.append(f"| {r['inputs']} | `{r.get('flags') or 'defaults'}` | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def drives(doc: dict[str, Any]) -> str:
    """The base motion inside each manipulation skill's demonstrations, per start."""
    lines = ["| start | skill | segments (expert successes) | base path, median / max (m) | base turn, median / max (deg) |", "|---|---|---|---|---|"]
    for start, run in doc["starts"].items():
        for s, x in run["skills"].items():
            lines.append(f"| {start} | {s} | {x['segments']} ({x['expert_success']}) | {x['path_m']['median']:.2f} / {x['path_m']['max']:.2f} | "
                         f"{x['turn_deg']['median']:.0f} / {x['turn_deg']['max']:.0f} |")
    return "\n".join(lines) + f"\n\n{doc['episodes_per_setting']} test episodes of each of {', '.join(doc['settings'])}; commit {doc['commit'][:7]}.\n"


def drive_ends(doc: dict[str, Any]) -> str:
    """A learned Navigate ended two ways: the paper's success, the hand-over, the chains after it."""
    lines = ["| a learned Navigate ends | Navigate success (1.5 m) | ended in the stance | chains completed (experts after it) | median distance to the pose (m) |",
             "|---|---|---|---|---|"]
    for end, r in doc["drive_ends"].items():
        lines.append(f"| {'at its success test' if end == 'success' else 'at the hand-over'} | {interval(r['navigate_success'])} | "
                     f"{interval(r['navigate_handover'])} | {interval(r['skill_completion'])} | {r['median_goal_distance_m']:.2f} |")
    return "\n".join(lines) + f"\n\nOne training (seed {doc['training']['seed']}), 100 test episodes; commit {doc['commit']}.\n"


def foundation(doc: dict[str, Any]) -> str:
    """The experts' chain completion per setting on a seed no test or study uses, and their failures."""
    lines = ["| setting | chains completed | failures |", "|---|---|---|"]
    for s, r in doc["settings"].items():
        fails = ", ".join(f"{why} ({n})" for why, n in sorted(r["failures"].items())) or "none"
        lines.append(f"| {s.replace('_', ' ')} | {interval(r['completion'])} | {fails} |")
    return "\n".join(lines) + f"\n\n{doc['episodes_per_setting']} train-split episodes per setting of seed {doc['seed']}; commit {doc['commit'][:7]}.\n"


def drive_end_seeds(doc: dict[str, Any]) -> str:
    """A learned Navigate over several training seeds, ended at the hand-over: pooled and per seed."""
    lines = ["| learner | seeds | Navigate success (1.5 m) | ended in the stance | per seed: in the stance | chains completed (experts after it) | median distance to the pose (m) |",
             "|---|---|---|---|---|---|---|"]
    for name, r in doc["seeds"].items():
        each = ", ".join(f"{x['navigate_handover']['k']}/{x['navigate_handover']['n']}" for x in r["per_seed"])
        lines.append(f"| {name} | {len(r['seeds'])} | {interval(r['navigate_success'])} | {interval(r['navigate_handover'])} | {each} | "
                     f"{interval(r['skill_completion'])} | {r['median_goal_distance_m']:.2f} |")
    commits = sorted({r["commit"] for r in doc["seeds"].values()})
    return "\n".join(lines) + f"\n\nThe test episodes dealt out over the seeds in turn; commit {', '.join(commits)}.\n"


def user_check(doc: dict[str, Any]) -> str:
    """The user check: the skill learned with the CLI's defaults, completed after the expert's hand-over."""
    r = doc.get("result")
    if not r:
        return f"Not measured yet: results/user_check.json holds no result (`{doc['command']}` measures it).\n"
    o = doc["training"]["options"]
    options = (f"--inputs {','.join(o['inputs'])} --action-column {o['action_column']} --shift {o['shift']} --epochs {o['epochs']} "
               f"--select-every {o['select_every']} --select-episodes {o['select_episodes']}")
    lines = ["| skill | what `train act` resolved | completed after the expert's Navigate (test) | the goal (0.8) |", "|---|---|---|---|",
             f"| {doc['skill']} | `{options}` | {interval(r)} | {'met' if r['successes'] >= 0.8 * r['n'] else 'not met'} |"]
    took = ", ".join(f"{k} {'reused' if s is None else f'{s / 60:.0f} min'}" for k, s in doc["seconds"].items())
    return ("\n".join(lines) + f"\n\n{doc['episodes']} test episodes of recipe seed {doc['seeds']['recipe']}, training seed {doc['seeds']['training']}; "
            f"wall time {took}; commit {doc['commit'][:7]}.\n")


Renderer = Callable[[dict[str, Any]], str]
# (study, copy name, results file in the study's results/, renderer)
COPIES: list[tuple[str, str, str, Renderer]] = [
    ("learners", "privileged", "sanity_learners.json", skills),
    ("learners", "cameras", "camera_learners.json", skills),
    ("learners", "navigate", "navigate_from_sound.json", navigate),
    ("navigation_ablation", "ablation", "ablation.json", ablation),
    ("planner", "fresh", "planner_fresh.json", planner),
    ("handover", "drives", "drives.json", drives),
    ("handover", "drive_ends", "navigate_drive_end.json", drive_ends),
    ("handover", "drive_end_seeds", "navigate_drive_end.json", drive_end_seeds),
    ("experts", "foundation", "foundation.json", foundation),
    ("user_check", "user_check", "user_check.json", user_check),
]


def markers(name: str, results: str) -> tuple[str, str]:
    """The begin and end markers of copy `name` (rendered from `results`)."""
    return f"<!-- results: {name}, rendered from results/{results} by studies/results_tables.py", f"<!-- end of results: {name} -->"


def rendered(study: str, name: str, results: str, render: Renderer) -> tuple[str, str]:
    """(what the README holds between the markers, what the JSON renders to)."""
    doc = json.loads((STUDIES / study / "results" / results).read_text())
    begin, end = markers(name, results)
    return block((STUDIES / study / "README.md").read_text(), begin, end), render(doc)


def main() -> None:
    for study, name, results, render in COPIES:
        readme = STUDIES / study / "README.md"
        begin, end = markers(name, results)
        doc = json.loads((STUDIES / study / "results" / results).read_text())
        readme.write_text(with_block(readme.read_text(), begin, end, render(doc)))


if __name__ == "__main__":
    main()
