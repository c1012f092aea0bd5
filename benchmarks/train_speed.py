"""Training speed of one skill learner on the CPU and, where there is one, on a CUDA GPU, measured
in the same run: optimiser steps per second and training samples per second, and their ratio.

    python benchmarks/train_speed.py DATASET --skill Pick --algo act --steps 50 \
        [--inputs depth,wrist_depth,state] [--threads 1] [--batch-size 64]

Samples per second are over every optimiser step by the fit loop's own clock (data decoding,
the same on both devices, is left out; it shows in the run seconds). Each device trains `WARMUP`
steps, then resumes to `WARMUP + steps` (so resume is exercised on the GPU too). Prints one JSON
document (no paths of the machine)."""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

WARMUP = 5


def timed_run(data: Path, algo: str, skill: str, inputs: tuple[str, ...], device: str, steps: int, threads: int, batch: int | None) -> dict[str, Any]:
    """Train `WARMUP` then `WARMUP + steps` optimiser steps (a resumed run) and time the second part."""
    from echo_data.learn.algos import algorithm
    from echo_data.learn.fit import train_skill

    cls = algorithm(algo).config
    over = {"batch_size": batch} if batch else {}
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path)
    ap.add_argument("--skill", default="Pick")
    ap.add_argument("--algo", default="act")
    ap.add_argument("--inputs", default="depth,wrist_depth,state")
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--batch-size", type=int, default=None)
    a = ap.parse_args()
    import torch

    inputs = tuple(a.inputs.split(","))
    rows = [timed_run(a.data, a.algo, a.skill, inputs, "cpu", a.steps, a.threads, a.batch_size)]
    if torch.cuda.is_available():
        rows.append(timed_run(a.data, a.algo, a.skill, inputs, "cuda", a.steps, a.threads, a.batch_size))
        rows[-1]["gpu"] = torch.cuda.get_device_name(0)
    for r in rows:
        # `train_seconds` is the loop's own clock over all steps so far (warm-up included in the resumed total).
        r["samples_per_second"] = round(r["batch_size"] * (WARMUP + r["steps"]) / max(r["train_seconds"], 1e-9), 1)
    doc: dict[str, Any] = {"algo": a.algo, "skill": a.skill, "inputs": list(inputs), "rows": rows}
    if len(rows) == 2:
        doc["gpu_over_cpu_samples_per_second"] = round(rows[1]["samples_per_second"] / rows[0]["samples_per_second"], 2)
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
