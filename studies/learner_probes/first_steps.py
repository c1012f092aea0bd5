"""A skill learner's first actions against the expert's, offline: at steps k = 0, 5, 15, 30 of each
segment of its skill in a dataset's train split, the base forward speed and turn rate the chosen
checkpoint (best.pt) predicts beside what the expert commanded. It shows whether a learner that
stands still closed loop learnt the drive at all (docs/learners.md, "Camera learners").

    python studies/learner_probes/first_steps.py RUN DATASET [--steps 0,5,15,30] [--segments 12]

Prints one JSON document: per step, the expert's and the learner's values per segment and the
mean absolute turn of each (no paths of the machine)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np


def _r(x: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in x]


def first_steps(run: Path, data: Path, steps: tuple[int, ...], segments: int) -> dict[str, Any]:
    """Predicted and expert base commands (forward speed, turn rate) at `steps` of the first
    `segments` segments of the run's skill (segments shorter than a step are left out there)."""
    import torch

    from echo_data.learn import runs
    from echo_data.learn.algos import build_model, config_from_run
    from echo_data.learn.data import load_skill_rows
    from echo_data.learn.features import FeatureSpec
    from echo_data.learn.fit import Units
    from echo_data.records import EE_ACTION_NAMES

    cfg = config_from_run(runs.read_json(run / runs.CONFIG))
    if cfg.action_column != "action.ee" or cfg.SEQUENCE:
        raise SystemExit(f"{run}: first_steps reads end-effector actions of a per-row learner (this run: {cfg.action_column}, {cfg.ALGO})")
    rows = load_skill_rows(data, "train", cfg.skill, FeatureSpec.from_dict(cfg.features), chunk=cfg.window(), action_column=cfg.action_column)
    model = build_model(cfg)
    model.load_state_dict(runs.load_torch(run / runs.BEST)["model"])
    model.eval()
    mean, std = np.asarray(cfg.action_mean, np.float32), np.asarray(cfg.action_std, np.float32)
    units = Units(rows, cfg.SEQUENCE, "cpu", cfg.history())
    ids, first, count = np.unique(rows.segments, return_index=True, return_counts=True)
    first, count = first[:segments], count[:segments]
    v, w = EE_ACTION_NAMES.index("base_vx"), EE_ACTION_NAMES.index("base_wz")
    out: dict[str, Any] = {"skill": cfg.skill, "learner": cfg.ALGO, "segments": int(len(first)), "steps": {}}
    gen = torch.Generator().manual_seed(0)  # a sampling learner (diffusion) draws alike every run
    for k in steps:
        ix = (first + k)[count > k]
        x, *_ = units.inputs(ix)
        with torch.no_grad():
            pred = model.predict(x, None, gen)[0][:, 0].numpy() * std + mean
        exp = rows.actions[ix, 0]
        out["steps"][str(k)] = {
            "expert_v": _r(exp[:, v]), "learner_v": _r(pred[:, v]), "expert_w": _r(exp[:, w]), "learner_w": _r(pred[:, w]),
            "mean_abs_turn": {"expert": round(float(np.abs(exp[:, w]).mean()), 3), "learner": round(float(np.abs(pred[:, w]).mean()), 3)},
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("data", type=Path)
    ap.add_argument("--steps", default="0,5,15,30")
    ap.add_argument("--segments", type=int, default=12)
    a = ap.parse_args()
    print(json.dumps(first_steps(a.run, a.data, tuple(int(s) for s in a.steps.split(",")), a.segments), indent=1))


if __name__ == "__main__":
    main()
