"""The epoch loop shared by every learner: batches, checkpoints, resume, losses, progress.

Batch order of epoch e is a permutation drawn from (seed, e) alone and the checkpoint records
the epoch and the batch reached, so a resumed run takes exactly the batches an uninterrupted one
would have. checkpoint.pt (with losses.csv and curves.png) is rewritten at an epoch's end when
`CHECKPOINT_SECONDS` have passed since the last one, after the last epoch, and when `max_steps`
stops the run (a killed run resumes from its last checkpoint);
best.pt keeps the weights with the best validation score: the lowest `val_loss` by default, or
the highest value of another column the validation returns (`LoopConfig.select`, e.g. the
planner's validation accuracy); the latest when there is no validation set.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.learn import runs

CHECKPOINT_SECONDS = 30.0  # tiny epochs (the planner's) would otherwise spend their time on disk


def check_finite(model: Any, out: Path, step: int) -> None:
    """Refuse to save weights that are not finite (a diverged run would otherwise load and act NaN)."""
    import torch

    for name, p in model.state_dict().items():
        if p.is_floating_point() and not bool(torch.isfinite(p).all()):
            raise runs.RunError(f"{out}: weight {name} is not finite at optimiser step {step}; nothing saved (lower --lr?)")


def setup_torch(seed: int, threads: int) -> Any:
    """Deterministic training: fixed thread count, deterministic kernels, seeded init.

    One thread by default: with other processes on the cores, two OpenMP threads wait on each
    other (measured here: 1.7 s per BC step with 2 threads against 0.22 s with 1). On CUDA too:
    two seeded ACT and diffusion runs on an H200 gave identical weights; ACT's attention backward
    then takes torch's deterministic kernel, 5x slower than the default one (2,738 against 13,559
    samples/s, the GPU figures in the benchmarks' results) and still 6x one CPU thread."""
    import torch

    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(seed % 2**63)  # torch takes 64-bit seeds; the config allows [0, 2**64)
    return torch


@dataclass(frozen=True)
class LoopConfig:
    epochs: int
    batch_size: int
    seed: int
    max_steps: int | None = None
    select: str = "val_loss"  # validation column that picks best.pt: val_loss is minimised, any other maximised

    def badness(self, val: dict[str, float]) -> float:
        """Lower is better: the loss itself, or minus a score to maximise (nan: no validation)."""
        v = val.get(self.select, math.nan)
        return v if self.select == "val_loss" else -v


def fit(
    model: Any,
    opt: Any,
    train_ix: np.ndarray,
    loss_fn: Callable[[np.ndarray], Any],
    validate: Callable[[], dict[str, float]],
    cfg: LoopConfig,
    out: Path,
    resume: bool,
    progress: bool = True,
    desc: str = "train",
) -> dict[str, Any]:
    """Train until `cfg.epochs` (or `max_steps`); `validate()` returns {"val_loss": ..., other
    columns} at each epoch's end. Returns the loop state (history, step, epoch, best, seconds)."""
    from tqdm import tqdm

    state: dict[str, Any] = {"epoch": 0, "batch": 0, "step": 0, "history": [], "best_val": math.inf, "running": [0.0, 0], "seconds": 0.0}
    if resume:
        ck = runs.load_torch(out / runs.CHECKPOINT)
        model.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optim"])
        state = ck["state"]

    def checkpoint() -> None:
        check_finite(model, out, state["step"])
        runs.save_torch(out, runs.CHECKPOINT, {"model": model.state_dict(), "optim": opt.state_dict(), "state": state})

    per_epoch = math.ceil(len(train_ix) / cfg.batch_size)
    total = per_epoch * cfg.epochs if cfg.max_steps is None else min(per_epoch * cfg.epochs, cfg.max_steps)
    bar = tqdm(total=total, initial=min(state["step"], total), desc=desc, unit="step", disable=not progress)
    t0 = time.perf_counter() - state["seconds"]
    saved = time.perf_counter()
    model.train()
    while state["epoch"] < cfg.epochs and state["step"] < total:
        order = train_ix[np.random.default_rng([cfg.seed, state["epoch"]]).permutation(len(train_ix))]
        while state["batch"] < per_epoch and state["step"] < total:
            ix = order[state["batch"] * cfg.batch_size : (state["batch"] + 1) * cfg.batch_size]
            loss = loss_fn(ix)
            if not math.isfinite(float(loss.detach())):
                raise runs.RunError(f"{out}: the training loss diverged at optimiser step {state['step'] + 1} (loss {float(loss.detach())}); "
                                    "no weights were saved from there on (lower --lr?)")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            state["running"][0] += float(loss.detach()) * len(ix)
            state["running"][1] += len(ix)
            state["batch"] += 1
            state["step"] += 1
            bar.update(1)
        if state["batch"] < per_epoch:  # stopped by max_steps inside the epoch
            break
        model.eval()
        val = validate()
        model.train()
        state["seconds"] = time.perf_counter() - t0
        train_loss = state["running"][0] / max(state["running"][1], 1)
        state["history"].append({"epoch": state["epoch"] + 1, "step": state["step"], "train_loss": train_loss, **val, "seconds": round(state["seconds"], 2)})
        bar.set_postfix(train=f"{train_loss:.4f}", val=f"{val.get('val_loss', float('nan')):.4f}")
        v = cfg.badness(val)
        if (math.isnan(v) and state["best_val"] == math.inf) or v < state["best_val"]:  # unscored epochs stand in only until one is scored
            if not math.isnan(v):
                state["best_val"] = v
            check_finite(model, out, state["step"])
            runs.save_torch(out, runs.BEST, {"model": model.state_dict(), "step": state["step"], "epoch": state["epoch"] + 1, **val})
        state.update(epoch=state["epoch"] + 1, batch=0, running=[0.0, 0])
        if time.perf_counter() - saved >= CHECKPOINT_SECONDS:
            checkpoint()
            runs.write_losses(out, state["history"])
            saved = time.perf_counter()
    bar.close()
    state["seconds"] = time.perf_counter() - t0
    checkpoint()
    runs.write_losses(out, state["history"])
    if not (out / runs.BEST).is_file():  # stopped before the first epoch ended
        runs.save_torch(out, runs.BEST, {"model": model.state_dict(), "step": state["step"], "val_loss": math.nan})
    return state
