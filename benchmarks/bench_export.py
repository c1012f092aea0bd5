"""Export throughput per format: source MB read and steps written per second of wall time.

Each format exports the same dataset once per repeat (best of --repeat); the baseline measured in
the same run is a plain copy of the source's Parquet shards and WAVs (`shutil.copytree`), so the
ratio says what decoding, re-encoding and statistics cost over moving the bytes. Printed per
format: seconds, source MB/s, steps/s, output MB, and the ratio to the copy's MB/s.

Usage:  python benchmarks/bench_export.py DATASET [--repeat 2] [--formats lerobot,lerobot-video,robomimic,zarr]
        (e.g. after `echo-data build recipes/quickstart.yaml`: DATASET = out/quickstart)
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

from echo_data.dataset.lerobot import export_lerobot
from echo_data.dataset.robomimic import export_robomimic
from echo_data.dataset.zarr_export import export_zarr


def _size(p: Path) -> int:
    return p.stat().st_size if p.is_file() else sum(f.stat().st_size for f in p.rglob("*") if f.is_file())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--formats", default="lerobot,lerobot-video,robomimic,zarr")
    a = ap.parse_args()
    src = a.dataset
    manifest = json.loads((src / "manifest.json").read_text())
    steps = sum(manifest["counts"]["steps"].values())
    mb = (_size(src / "data") + _size(src / "audio")) / 2**20
    runs = {
        "copy": lambda out: shutil.copytree(src, out),
        "lerobot": lambda out: export_lerobot(src, out),
        "lerobot-video": lambda out: export_lerobot(src, out, video=("rgb",)),
        "robomimic": lambda out: export_robomimic(src, out.with_suffix(".hdf5")),
        "zarr": lambda out: export_zarr(src, out.with_suffix(".zarr")),
    }
    print(f"{src.name}: {steps} steps, {mb:.1f} MB of shards and WAVs")
    base = None
    for name in ["copy", *a.formats.split(",")]:
        best, size = float("inf"), 0
        for _ in range(a.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "export"
                t = time.perf_counter()
                runs[name](out)
                best = min(best, time.perf_counter() - t)
                size = sum(_size(p) for p in Path(tmp).iterdir())
        rate = mb / best
        base = base or rate
        print(f"{name:14s} {best:7.2f} s  {rate:7.1f} MB/s  {steps / best:8.0f} steps/s  out {size / 2**20:7.1f} MB  x{rate / base:.3f} of copy")


if __name__ == "__main__":
    main()
