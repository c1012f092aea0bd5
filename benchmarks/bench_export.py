"""Export throughput per format: source MB read and steps written per second of wall time.

Each format exports the same dataset once per repeat (best of --repeat); the baseline measured in
the same run is a plain copy of the source's Parquet shards and WAVs (`shutil.copytree`), so the
ratio says what decoding, re-encoding and statistics cost over moving the bytes. Printed per
format: seconds, source MB/s, steps/s, output MB, and the ratio to the copy's MB/s.

With `--reads N`, the read side as the consumers read (each against a baseline in the same run):
robomimic's SequenceDataset samples (state, spectrogram, head RGB and depth of one random step)
from the export with one frame per HDF5 chunk against the same export chunked by whole
trajectory (the earlier layout), in ms per sample; and LeRobot's LeRobotDataset random samples
per second (in the LeRobot environment, `benchmarks/lerobot_read.py`) from the `--video rgb`
export with a keyframe every 2 frames against the encoder's default GOP and against the PNG export.
The 1-minute load average is printed before and after (the machine is shared).

Usage:  python benchmarks/bench_export.py DATASET [--repeat 2] [--formats lerobot,lerobot-video,robomimic,zarr] [--reads 200]
        (e.g. after `echo-data build recipes/quickstart.yaml`: DATASET = out/quickstart)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from echo_data.dataset import lerobot, robomimic
from echo_data.dataset.lerobot import export_lerobot
from echo_data.dataset.robomimic import export_robomimic
from echo_data.dataset.zarr_export import export_zarr
from echo_data.media import LEROBOT_VIDEO

LEROBOT_PYTHON = Path(os.environ.get("ECHO_LEROBOT_PYTHON", Path(__file__).resolve().parents[1] / ".venv-lerobot" / "bin" / "python"))


def _size(p: Path) -> int:
    return p.stat().st_size if p.is_file() else sum(f.stat().st_size for f in p.rglob("*") if f.is_file())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--formats", default="lerobot,lerobot-video,robomimic,zarr")
    ap.add_argument("--reads", type=int, default=0, help="also time N random reads per consumer (0: export only)")
    a = ap.parse_args()
    src = a.dataset
    print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    if a.reads:
        read_side(src, a.reads)
        print(f"load average after: {os.getloadavg()[0]:.1f}")
        if not a.formats:
            return
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


def _robomimic_ms(path: Path, n: int) -> float:
    """Milliseconds per random SequenceDataset sample (low-dim cached in memory, images from the file)."""
    import robomimic.utils.obs_utils as obs_utils
    from robomimic.utils.dataset import SequenceDataset

    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": ["state", "spectrogram"], "rgb": ["head_rgb"], "depth": ["head_depth"]}})
    seq = SequenceDataset(hdf5_path=str(path), obs_keys=("state", "spectrogram", "head_rgb", "head_depth"), dataset_keys=("actions",), seq_length=1,
                          hdf5_cache_mode="low_dim", hdf5_use_swmr=False, filter_by_attribute="train", load_next_obs=False)
    idx = np.random.default_rng(0).integers(0, len(seq), n)
    seq[int(idx[0])]
    t = time.perf_counter()
    for i in idx:
        seq[int(i)]
    return (time.perf_counter() - t) / n * 1000


def read_side(src: Path, n: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        export_robomimic(src, t / "frame.hdf5")
        robomimic.CHUNK_FRAMES = 10**9  # the earlier layout: one chunk per trajectory
        export_robomimic(src, t / "trajectory.hdf5")
        robomimic.CHUNK_FRAMES = 1
        ms = {k: _robomimic_ms(t / f"{k}.hdf5", n) for k in ("frame", "trajectory")}
        print(f"robomimic sample  per-frame chunks {ms['frame']:7.2f} ms  per-trajectory chunks {ms['trajectory']:7.2f} ms  x{ms['trajectory'] / ms['frame']:.1f} faster")
        export_lerobot(src, t / "gop2", video=("rgb",))
        lerobot.VIDEO_ENCODING = dataclasses.replace(LEROBOT_VIDEO, options={k: v for k, v in LEROBOT_VIDEO.options.items() if k != "g"})  # the encoder's default keyframe interval
        export_lerobot(src, t / "gopdefault", video=("rgb",))
        lerobot.VIDEO_ENCODING = LEROBOT_VIDEO
        export_lerobot(src, t / "png")
        if not LEROBOT_PYTHON.is_file():
            print(f"LeRobot read: no LeRobot environment at {LEROBOT_PYTHON} (bash scripts/setup_lerobot.sh)")
            return
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")} | {"HF_HUB_OFFLINE": "1", "HF_HOME": str(t / "hf")}
        roots = [str(t / k) for k in ("gop2", "gopdefault", "png")]
        p = subprocess.run([str(LEROBOT_PYTHON), str(Path(__file__).with_name("lerobot_read.py")), str(n), *roots], capture_output=True, text=True, env=env, check=True)
        rate = dict(zip(("gop2", "gopdefault", "png"), json.loads(p.stdout.strip().splitlines()[-1]).values()))
        print(f"LeRobot samples/s  video GOP 2 {rate['gop2']:6.1f}  video default GOP {rate['gopdefault']:6.1f} (x{rate['gop2'] / rate['gopdefault']:.1f})  PNG {rate['png']:6.1f}")


if __name__ == "__main__":
    main()
