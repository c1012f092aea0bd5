"""Runs in the LeRobot environment (scripts/setup_lerobot.sh), for benchmarks/bench_export.py:
random-access samples per second of LeRobot's own dataset class on each export root given.

    python lerobot_read.py N ROOT [ROOT ...]

Each root: one warm-up sample, then N samples at random frame indices (seed 0, the same indices
for every root) through `LeRobotDataset.__getitem__` in this process (no DataLoader workers, so
the figure is the decoder's, not the core count's). Prints one JSON line {root: samples/s}.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from ledataset.datasets.lerobot_dataset import LeRobotDataset

n, roots = int(sys.argv[1]), sys.argv[2:]
out = {}
for root in roots:
    ds = LeRobotDataset("echo-data/bench", root=root, video_backend="pyav")
    idx = np.random.default_rng(0).integers(0, len(ds), n)
    ds[int(idx[0])]
    t = time.perf_counter()
    for i in idx:
        ds[int(i)]
    out[root] = n / (time.perf_counter() - t)
print(json.dumps(out))
