"""Where hand-overs land in the stance, and what the next learned skill makes of them: per
evaluation and next skill, the base's distance to the interaction pose and its heading error at
the hand-over, for the episodes the skill then completed and those it did not.

Why: the manipulation learners were taught from the experts' hand-overs, drawn anywhere in the
stance (`experts.handover_noise`); a learned drive cut the first step it enters the stance stops
on its rim. This compares the two from evaluations already run (`echo-data evaluate --json`).

    python studies/handover/handover_spread.py --eval LABEL=EVAL.json ... --json results/handover_spread.json
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # runner.py
from runner import commit  # noqa: E402

from echo_data.dataset.storage import atomic_write_json  # noqa: E402


def spread(doc: dict[str, Any]) -> dict[str, Any]:
    """Per next skill: hand-overs inside the stance, the skill's successes, and median distance
    (m) and heading error (degrees) over the successes, the failures and all."""
    by: dict[str, list[tuple[float, float, bool]]] = {}
    for ep in doc["episodes"]:
        skills = ep["skills"]
        for k, s in enumerate(skills[:-1]):
            h = s.get("handover")
            if s["skill"] == "Navigate" and h and h.get("inside"):
                by.setdefault(h["skill"], []).append((h["goal_distance"], math.degrees(h["heading_error"]), bool(skills[k + 1]["success"])))
    out = {}
    for skill, rows in sorted(by.items()):
        def med(sel: list[tuple[float, float, bool]], i: int) -> float | None:
            return round(statistics.median(r[i] for r in sel), 3 if i == 0 else 1) if sel else None
        ok = [r for r in rows if r[2]]
        bad = [r for r in rows if not r[2]]
        out[skill] = {"handed_over": len(rows), "completed": {"k": len(ok), "n": len(rows)},
                      "distance_m": {"completed": med(ok, 0), "not": med(bad, 0), "all": med(rows, 0)},
                      "heading_deg": {"completed": med(ok, 1), "not": med(bad, 1), "all": med(rows, 1)}}
    return out


def portable(name: str) -> str:
    """A policy's name without this machine's folders: shipped weights as `reference:NAME`, run folders as WORK/runs/NAME."""
    name = re.sub(r"/[^,+=]*/echo_data/reference/([\w.-]+)", r"reference:\1", name)
    return re.sub(r"/[^,+=]*/runs/([\w./-]+)", r"WORK/runs/\1", name)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--eval", action="append", required=True, help="LABEL=EVAL.json (an `echo-data evaluate --json` document)")
    ap.add_argument("--json", type=Path, required=True)
    a = ap.parse_args()
    doc: dict[str, Any] = {"commit": commit(), "how": __doc__.split("\n\n")[0].replace("\n", " "), "evaluations": {}}
    for item in a.eval:
        label, path = item.split("=", 1)
        ev = json.loads(Path(path).read_text())
        eps = [e for e in ev["episodes"] if "skipped" not in e]
        members = sorted({e["member"] for e in eps if e.get("member") is not None})
        doc["evaluations"][label] = {"recipe": Path(ev["recipe"]["path"]).name, "drive_end": ev.get("drive_end"), "n": ev["n"],
                                     "policy": portable(ev["policy"]["name"]),
                                     "chain_completed": {"k": sum(bool(e["success"]) for e in eps), "n": len(eps)},
                                     **({"per_training_seed": [{"k": sum(bool(e["success"]) for e in eps if e.get("member") == m),
                                                                "n": sum(e.get("member") == m for e in eps)} for m in members]} if members else {}),
                                     "by_next_skill": spread(ev)}
    atomic_write_json(a.json, doc)
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
