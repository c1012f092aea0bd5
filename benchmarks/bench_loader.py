"""Shuffled training-loader throughput: echo-data's StepDataset against Hugging Face `datasets`
on the same Parquet files, both through a torch DataLoader with the same workers and batch size.

Both decode every step column to tensors (images from PNG, arrays, vectors). The HF baseline is
`load_dataset("parquet", ...)` with `with_format("torch")` and a plain shuffled DataLoader; the
echo-data loader is `StepDataset.shuffled(batch_size=...)` (row groups dealt to workers, a
shuffle buffer, batches gathered column by column). Printed:
samples/s of each (best of --repeat epochs), CPU milliseconds per sample (main process plus
workers, which says what the loader costs when other work shares the cores) and the ratios.

Usage:  python benchmarks/bench_loader.py DATASET [--workers 2] [--batch 32] [--repeat 3] [--uniform]
        (e.g. after `echo-data build recipes/quickstart.yaml --out out/quickstart`)
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402


def _proc_cpu(pid: int) -> float:
    """CPU seconds (user + system) of a live process, from /proc (Linux)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rate(loader: torch.utils.data.DataLoader, repeat: int) -> tuple[float, float]:
    """(samples/s, CPU ms per sample) in steady state: persistent workers, one warm-up epoch,
    then the best wall rate of `repeat` epochs and their mean CPU cost (main process + workers),
    which a busy shared machine disturbs less than wall time."""
    best, cpu, n_all = 0.0, 0.0, 0
    for k in range(repeat + 1):
        it = iter(loader)
        pids = [w.pid for w in getattr(it, "_workers", [])]
        t0, c0 = time.perf_counter(), time.process_time() + sum(_proc_cpu(p) for p in pids)
        n = sum(len(batch["index"]) for batch in it)
        if k:  # the first epoch starts the workers and warms their imports
            best = max(best, n / (time.perf_counter() - t0))
            cpu += time.process_time() + sum(_proc_cpu(p) for p in pids) - c0
            n_all += n
    return best, 1000.0 * cpu / n_all


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="train")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--uniform", action="store_true", help="also time uniform shuffling (slow on data larger than the cache)")
    a = ap.parse_args()

    import datasets

    from echo_data.dataset.torch import StepDataset

    torch.set_num_threads(1)
    files = sorted(str(p) for p in (a.dataset / "data").glob(f"{a.split}-*.parquet"))
    ours = StepDataset(a.dataset, a.split)
    kw = dict(batch_size=a.batch, num_workers=a.workers, persistent_workers=a.workers > 0)
    echo_loader = torch.utils.data.DataLoader(ours.shuffled(seed=0, batch_size=a.batch), batch_size=None, num_workers=a.workers, persistent_workers=a.workers > 0)
    hf = datasets.load_dataset("parquet", data_files=files, split="train").with_format("torch")
    hf_loader = torch.utils.data.DataLoader(hf, shuffle=True, **kw)
    plain_loader = torch.utils.data.DataLoader(ours, shuffle=True, **kw)
    print(f"{len(ours)} steps of {a.dataset}, {a.workers} workers, batch {a.batch}, every column; "
          f"best epoch of {a.repeat}, CPU = main process + workers")
    (r_hf, c_hf) = _rate(hf_loader, a.repeat)
    print(f"HF datasets, shuffle=True:               {r_hf:7.0f} samples/s  {c_hf:5.2f} CPU ms/sample (baseline)")
    r, c = _rate(echo_loader, a.repeat)
    print(f"StepDataset.shuffled() (row-group buffer): {r:7.0f} samples/s  {c:5.2f} CPU ms/sample = {r / r_hf:.2f}x baseline rate, {c / c_hf:.2f}x its CPU")
    if a.uniform:
        r, c = _rate(plain_loader, 1)  # slow: one timed epoch
        print(f"StepDataset, shuffle=True (uniform):       {r:7.0f} samples/s  {c:5.2f} CPU ms/sample = {r / r_hf:.2f}x baseline rate")


if __name__ == "__main__":
    main()
