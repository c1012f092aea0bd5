"""Where the expert takes over a DAgger rollout (`--dagger-chunk takeover`), what the learner was
commanding and what the expert commands: the base velocities of both, per take-over.

Why: DAgger assumes the expert's label is a function of the state the learner reached. Our
manipulation experts are phase machines (docs/manipulation_experts.md: drive to a step back from
the counter, unfold, drive in, hover, ...); the labeller advances the expert once per learner step,
so its phase follows its own schedule, not the learner's progress. This measures the gap at the
take-over step, on the train episodes a DAgger round would roll (never test).

    python studies/handover/takeover_switches.py RUN DATASET --episodes 24 --json OUT.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # runner.py
from runner import commit  # noqa: E402

from echo_data.dataset.storage import atomic_write_json  # noqa: E402
from echo_data.learn.dagger import collect

REVERSE = -0.2  # m/s: a base command below this is a reverse drive (the experts drive at 0.4 m/s)


def switches(run: Path, dataset: Path, episodes: int, seed: int) -> dict:
    """Roll `run` on the first `episodes` train episodes with the expert taking over; the record."""
    ro = collect(run, dataset, list(range(episodes)), takeover_seed=seed)
    mine = np.array([m[:3] for m, _ in ro.switches], dtype=float).reshape(-1, 3)
    theirs = np.array([t[:3] for _, t in ro.switches], dtype=float).reshape(-1, 3)
    return {
        "takeovers": len(ro.switches),
        "base_command_names": ["vx", "vy", "wz"],
        "learner_mean": [round(float(v), 3) for v in mine.mean(axis=0)] if len(mine) else None,
        "expert_mean": [round(float(v), 3) for v in theirs.mean(axis=0)] if len(theirs) else None,
        "learner_reverses": int((mine[:, 0] < REVERSE).sum()),
        "expert_reverses": int((theirs[:, 0] < REVERSE).sum()),
        "per_takeover": [{"learner": [round(float(v), 3) for v in m], "expert": [round(float(v), 3) for v in t]}
                         for m, t in zip(mine, theirs, strict=True)],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--episodes", type=int, default=24)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path, required=True)
    a = ap.parse_args()
    doc = switches(a.run, a.dataset, a.episodes, a.seed)
    doc = {"commit": commit(), "command": f"python studies/handover/takeover_switches.py RUN DATASET --episodes {a.episodes} --seed {a.seed}",
           "reverse_below_m_s": REVERSE, **doc}
    atomic_write_json(a.json, doc)
    json.dump({k: v for k, v in doc.items() if k != "per_takeover"}, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
