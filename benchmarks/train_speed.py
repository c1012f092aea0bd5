"""Training speed of one skill learner on the CPU and, where there is one, on a CUDA GPU, measured
in the same run: optimiser steps per second and training samples per second, and their ratio.

    python benchmarks/train_speed.py DATASET --skill Pick --algo act --steps 50 \
        [--inputs depth,wrist_depth,state] [--threads 1] [--batch-size 64] \
        [--action-column action.ee] [--shift 4] [--devices cpu,cuda]

The camera learners' Pick (studies/learners/camera_learners.py) is `--inputs depth,wrist_depth,state,kind
--action-column action.ee --shift 4` on a `studies/paper_table/recipes/cameras_pick_place.yaml` build.

Samples per second are over every optimiser step by the fit loop's own clock (data decoding,
the same on both devices, is left out; it shows in the run seconds). Each device trains `WARMUP`
steps, then resumes to `WARMUP + steps` (so resume is exercised on the GPU too). Prints one JSON
document (no paths of the machine); with `--full-steps`, the short rows first and then the whole
document again with the long run as `full`."""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path
from typing import Any

WARMUP = 5


def timed_run(data: Path, algo: str, skill: str, inputs: tuple[str, ...], device: str, steps: int, threads: int, batch: int | None,
              over: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train `WARMUP` then `WARMUP + steps` optimiser steps (a resumed run) and time the second part;
    `over` holds more config fields (the action column, the random shift)."""
    from echo_data.learn.algos import algorithm
    from echo_data.learn.fit import train_skill

    cls = algorithm(algo).config
    over = {**(over or {}), **({"batch_size": batch} if batch else {})}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        t0 = time.perf_counter()
        train_skill(cls(dataset=str(data), skill=skill, inputs=inputs, device=device, threads=threads, max_steps=WARMUP, **over), out, progress=False)
        warm = time.perf_counter() - t0
        t1 = time.perf_counter()
        s = train_skill(cls(dataset=str(data), skill=skill, inputs=inputs, device=device, threads=threads, max_steps=WARMUP + steps, **over), out,
                        resume=True, progress=False)
        total = time.perf_counter() - t1
    cfg = cls(skill=skill, **over)
    return {"device": s["device"], "steps": steps, "batch_size": cfg.batch_size, "first_run_seconds": round(warm, 2),
            "resumed_run_seconds": round(total, 2), "train_seconds": s["seconds"]}


def samples_per_second(row: dict[str, Any]) -> float:
    """Rows per second of a `timed_run` row: `train_seconds` is the loop's own clock over all its
    steps (the warm-up's included)."""
    return round(row["batch_size"] * (WARMUP + row["steps"]) / max(row["train_seconds"], 1e-9), 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path)
    ap.add_argument("--skill", default="Pick")
    ap.add_argument("--algo", default="act")
    ap.add_argument("--inputs", default="depth,wrist_depth,state")
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--batch-size", type=int, default=None)
    ap.add_argument("--action-column", default=None, help="The action column cloned (the learner's default when left out).")
    ap.add_argument("--shift", type=int, default=None, help="Random-shift augmentation in pixels (the learner's default when left out).")
    ap.add_argument("--devices", default="cpu,cuda", help="Devices in order; cuda is skipped where there is none.")
    ap.add_argument("--full-steps", type=int, default=0,
                    help="Then train this many steps on the first device (a whole skill's optimisation: the camera learners' Pick is 7,500) ...")
    ap.add_argument("--full-budget", type=float, default=math.inf,
                    help="... or as many as its measured rate fits in this many seconds (the row says it was cut).")
    a = ap.parse_args()
    import torch

    inputs = tuple(a.inputs.split(","))
    over: dict[str, Any] = {k: v for k, v in (("action_column", a.action_column), ("shift", a.shift)) if v is not None}
    rows = []
    for dev in a.devices.split(","):
        if dev == "cuda" and not torch.cuda.is_available():
            continue
        rows.append(timed_run(a.data, a.algo, a.skill, inputs, dev, a.steps, a.threads, a.batch_size, over))
        if dev == "cuda":
            rows[-1]["gpu"] = torch.cuda.get_device_name(0)
    for r in rows:
        r["samples_per_second"] = samples_per_second(r)
    doc: dict[str, Any] = {"algo": a.algo, "skill": a.skill, "inputs": list(inputs), **over, "rows": rows}
    if a.full_steps and rows:
        first = rows[0]
        fits = int(a.full_budget * first["samples_per_second"] / first["batch_size"]) if math.isfinite(a.full_budget) else a.full_steps
        steps = max(1, min(a.full_steps, fits))
        print(json.dumps(doc, indent=1), flush=True)  # the short rows survive if the long run is stopped
        full = timed_run(a.data, a.algo, a.skill, inputs, first["device"], max(1, steps - WARMUP), a.threads, a.batch_size, over)
        full.update(asked_steps=a.full_steps, cut=steps < a.full_steps, total_steps=full["steps"] + WARMUP,
                    train_minutes=round(full["train_seconds"] / 60, 2), samples_per_second=samples_per_second(full))
        doc["full"] = full
    by = {r["device"]: r["samples_per_second"] for r in rows}
    if "cpu" in by and "cuda" in by:
        doc["gpu_over_cpu_samples_per_second"] = round(by["cuda"] / by["cpu"], 2)
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
