"""Shuffled training-loader throughput: echo-data's StepDataset against Hugging Face `datasets`
on the same Parquet files, both through a torch DataLoader with the same workers and batch size.

Both decode every step column to tensors (images from PNG, arrays, vectors). The HF baseline is
`load_dataset("parquet", ...)` with `with_format("torch")` and a plain shuffled DataLoader; the
echo-data loader is `StepDataset.shuffled()` (row groups dealt to workers, shuffle buffer). Printed:
samples/s of each (best of --repeat epochs after one warm-up epoch) and their ratio.

Usage:  python benchmarks/bench_loader.py DATASET [--workers 2] [--batch 32] [--repeat 3]
        (e.g. after `echo-data build recipes/quickstart.yaml --out out/quickstart`)
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402


def _rate(loader: torch.utils.data.DataLoader, repeat: int) -> float:
    """Samples per second over whole epochs (best of `repeat`, after one warm-up epoch)."""
    best = 0.0
    for k in range(repeat + 1):
        t0, n = time.perf_counter(), 0
        for batch in loader:
            n += len(batch["index"])
        rate = n / (time.perf_counter() - t0)
        if k:
            best = max(best, rate)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="train")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()

    import datasets

    from echo_data.dataset.torch import StepDataset

    torch.set_num_threads(1)
    files = sorted(str(p) for p in (a.dataset / "data").glob(f"{a.split}-*.parquet"))
    ours = StepDataset(a.dataset, a.split)
    kw = dict(batch_size=a.batch, num_workers=a.workers, persistent_workers=a.workers > 0)
    echo_loader = torch.utils.data.DataLoader(ours.shuffled(seed=0), **kw)
    hf = datasets.load_dataset("parquet", data_files=files, split="train").with_format("torch")
    hf_loader = torch.utils.data.DataLoader(hf, shuffle=True, **kw)
    plain_loader = torch.utils.data.DataLoader(ours, shuffle=True, **kw)
    r_hf = _rate(hf_loader, a.repeat)
    r_ours = _rate(echo_loader, a.repeat)
    r_plain = _rate(plain_loader, a.repeat)
    print(f"{len(ours)} steps of {a.dataset}, {a.workers} workers, batch {a.batch}, every column")
    print(f"HF datasets, shuffled DataLoader:         {r_hf:8.0f} samples/s (baseline)")
    print(f"StepDataset.shuffled (row-group buffer):  {r_ours:8.0f} samples/s = {r_ours / r_hf:.2f}x baseline")
    print(f"StepDataset, uniform shuffle=True:        {r_plain:8.0f} samples/s = {r_plain / r_hf:.2f}x baseline")


if __name__ == "__main__":
    main()
