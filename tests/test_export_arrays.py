"""`echo-data export --format robomimic` and `--format zarr`: read back with the consumers' own
readers (robomimic's SequenceDataset; zarr alone) and compared with echo-data's rows."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pyarrow.parquet as pq
import pytest
import zarr
from PIL import Image
from support.optional import needs_torch
from support.synth import build_synth
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.robomimic import normalize_actions

HERE = Path(__file__).resolve().parent


def _needs(*modules: str) -> None:
    """Skip where robomimic's training dependencies are missing (scripts/setup.sh installs them); fail in CI."""
    import importlib.util

    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        if os.environ.get("CI"):
            pytest.fail(f"{', '.join(missing)} missing: scripts/setup.sh installs them")
        pytest.skip(f"{', '.join(missing)} not installed (bash scripts/setup.sh)")


@pytest.fixture(scope="module")
def ds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("arrays") / "synth", {"train": 3, "test": 2})


def _rows(ds: Path) -> list[dict]:
    rows = []
    for split in ("train", "test"):
        for f in sorted((ds / "data").glob(f"{split}-*.parquet")):
            rows += [dict(r, split=split) for r in pq.read_table(f).to_pylist()]
    return rows


def _png(cell: dict) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(cell["bytes"])))


@needs_torch
def test_robomimic_sequence_dataset_reads_the_export(ds: Path, tmp_path: Path) -> None:
    import robomimic.utils.obs_utils as obs_utils
    from robomimic.utils.dataset import SequenceDataset

    out = tmp_path / "demo.hdf5"
    r = CliRunner().invoke(app, ["export", str(ds), "--format", "robomimic", "--out", str(out)])
    assert r.exit_code == 0, r.output
    rows = _rows(ds)
    with h5py.File(out, "r") as f:
        clipped_line = f"{f['data'].attrs['actions_clipped']} action values outside the train split's range clipped to [-1, 1]"
        assert clipped_line in r.output  # export says it, not only the file's attributes
        depth_range = json.loads(f["data"].attrs["depth_range_m"])["head_depth"]
        stats = json.loads((ds / "meta" / "stats.json").read_text())["observation.images.head_depth"]
        assert depth_range == np.ceil(stats["max"][0] / 0.5) * 0.5  # the train split's farthest depth: no train pixel clips
        assert [n.decode() for n in f["mask/train"][:]] == ["demo_0", "demo_1", "demo_2"] and len(f["mask/test"]) == 2
        assert f["data"].attrs["total"] == len(rows) and json.loads(f["data"].attrs["env_args"])["env_name"] == "EchoData"
        d0 = f["data/demo_0"]
        assert d0.attrs["audio_path"] == rows[0]["audio_path"] and (ds / d0.attrs["audio_path"]).is_file()
        assert d0["dones"][-1] == 1 and d0["rewards"][-1] == 1.0 and d0["rewards"][:-1].sum() == 0
        assert "next_obs" not in d0 and d0["obs/head_rgb"].chunks[0] == 1  # one frame per chunk: random reads decode one frame
        norm = json.loads(f["data"].attrs["action_normalization"])
        low, high = np.array(norm["low"]), np.array(norm["high"])
        train_actions = np.array([r["action"] for r in rows if r["split"] == "train"], np.float64)
        np.testing.assert_allclose(low, train_actions.min(axis=0), rtol=1e-6)  # the train split's range, not the test split's
        np.testing.assert_allclose(high, train_actions.max(axis=0), rtol=1e-6)
        acts = np.concatenate([f[f"data/demo_{i}/actions"][:] for i in range(5)])
        assert acts.min() >= -1.0 and acts.max() <= 1.0
        raw = np.array([r["action"] for r in rows], np.float64)
        inside = np.all((raw >= low) & (raw <= high), axis=1)
        back = low + (acts + 1) / 2 * (high - low)  # the stored inverse
        moving = high > low
        np.testing.assert_allclose(back[inside][:, moving], raw[inside][:, moving], atol=1e-5)
        assert f["data"].attrs["actions_clipped"] == int(np.count_nonzero(~((raw >= low) & (raw <= high))[:, moving]))
    # the robomimic tools: its dataset-info script (refuses actions outside [-1, 1]) and BC training steps
    p = subprocess.run([sys.executable, "-m", "robomimic.scripts.get_dataset_info", "--dataset", str(out)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and "total trajectories: 5" in p.stdout, p.stderr[-2000:]
    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": ["state", "spectrogram"], "rgb": ["head_rgb"], "depth": ["head_depth"]}})
    seq = SequenceDataset(
        hdf5_path=str(out), obs_keys=("state", "spectrogram", "head_rgb", "head_depth"), dataset_keys=("actions", "rewards", "dones"),
        seq_length=1, hdf5_cache_mode="low_dim", hdf5_use_swmr=False, filter_by_attribute="train", load_next_obs=False,
    )
    n_train = sum(r["split"] == "train" for r in rows)
    assert len(seq) == n_train
    for i in (0, n_train - 1):
        item = seq[i]
        np.testing.assert_array_equal(item["actions"][0], normalize_actions(np.array(rows[i]["action"], np.float64)[None], low, high)[0][0])
        np.testing.assert_array_equal(item["obs"]["state"][0], np.array(rows[i]["observation.state"], np.float32))
        np.testing.assert_array_equal(item["obs"]["spectrogram"][0], np.array(rows[i]["observation.audio.spectrogram"], np.float32))
        # images as stored (robomimic's ObsUtils.process_obs makes them channel-first floats for its models)
        np.testing.assert_array_equal(item["obs"]["head_rgb"][0], _png(rows[i]["observation.images.head_rgb"]))
        mm = item["obs"]["head_depth"][0][..., 0].astype(np.float64) * depth_range * 1000.0  # the stored fraction of the range
        np.testing.assert_allclose(mm, _png(rows[i]["observation.images.head_depth"]), atol=0.01)
        # robomimic's own observation processing (its `depth` modality: /1, clip to [0, 1], channel first) keeps the picture
        seen = obs_utils.process_obs(item["obs"]["head_depth"][0], obs_key="head_depth")
        assert seen.shape[0] == 1 and np.ptp(seen) > 0.05 and seen.min() >= 0.0 and seen.max() <= 1.0
    again = CliRunner().invoke(app, ["export", str(ds), "--format", "robomimic", "--out", str(out)])
    assert again.exit_code == 2 and "already exists" in again.output


def test_robomimic_next_obs_and_split(ds: Path, tmp_path: Path) -> None:
    """--next-obs writes next_obs (virtual, shifted by one step); --split test holds the test demos only."""
    out = tmp_path / "next.hdf5"
    assert CliRunner().invoke(app, ["export", str(ds), "--format", "robomimic", "--out", str(out), "--next-obs"]).exit_code == 0
    with h5py.File(out, "r") as f:
        d0 = f["data/demo_0"]
        n0 = int(d0.attrs["num_samples"])
        np.testing.assert_array_equal(d0["next_obs/state"][: n0 - 1], d0["obs/state"][1:])
        np.testing.assert_array_equal(d0["next_obs/state"][n0 - 1], d0["obs/state"][n0 - 1])
    test = tmp_path / "test.hdf5"
    assert CliRunner().invoke(app, ["export", str(ds), "--format", "robomimic", "--out", str(test), "--split", "test"]).exit_code == 0
    with h5py.File(test, "r") as f:
        assert list(f["mask"]) == ["test"] and len(f["data"]) == 2
        assert {f[f"data/{d}"].attrs["split"] for d in f["data"]} == {"test"}
    bad = CliRunner().invoke(app, ["export", str(ds), "--format", "robomimic", "--out", str(tmp_path / "v.hdf5"), "--split", "val"])
    assert bad.exit_code == 2 and "--split val" in bad.output and not (tmp_path / "v.hdf5").exists()


@needs_torch
def test_robomimic_bc_trains_on_the_export(ds: Path, tmp_path: Path) -> None:
    """robomimic's own train() (BC, low-dimensional state + spectrogram, train mask) takes steps on the export."""
    _needs("torchvision", "psutil", "imageio")
    out = tmp_path / "demo.hdf5"
    assert CliRunner().invoke(app, ["export", str(ds), "--format", "robomimic", "--out", str(out)]).exit_code == 0
    p = subprocess.run([sys.executable, str(HERE / "robomimic_train.py"), str(out), str(tmp_path / "runs"), "3"], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    got = json.loads(p.stdout.strip().splitlines()[-1])
    assert got["steps"] == 3 and np.isfinite(got["Loss"])


def test_zarr_replay_buffer_reads_back(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "replay.zarr"
    r = CliRunner().invoke(app, ["export", str(ds), "--format", "zarr", "--out", str(out)])
    assert r.exit_code == 0, r.output
    rows = _rows(ds)
    root = zarr.open_group(str(out), mode="r")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # zarr warns about a file it does not know (the export's marker once was one)
        assert {name for name, _ in root.members(max_depth=None)} >= {"data", "meta", "data/action", "meta/episode_ends"}
    ends = root["meta/episode_ends"][:]
    lengths = [sum(1 for x in rows if (x["split"], x["episode_index"]) == key) for key in dict.fromkeys((x["split"], x["episode_index"]) for x in rows)]
    assert ends.tolist() == np.cumsum(lengths).tolist() and root["meta/episode_split"][:].tolist() == [0, 0, 0, 2, 2]
    assert root["data/head_rgb"].chunks[0] == root.attrs["chunk_steps"] == int(np.median(lengths))
    np.testing.assert_array_equal(root["data/action"][:], np.array([x["action"] for x in rows], np.float32))
    np.testing.assert_array_equal(root["data/state"][:], np.array([x["observation.state"] for x in rows], np.float32))
    np.testing.assert_array_equal(root["data/mel"][:], np.array([x["observation.audio.mel"] for x in rows], np.float32))
    np.testing.assert_array_equal(root["data/head_depth"][:], np.stack([_png(x["observation.images.head_depth"]) for x in rows]))
    np.testing.assert_array_equal(root["data/head_rgb"][:], np.stack([_png(x["observation.images.head_rgb"]) for x in rows]))
    np.testing.assert_array_equal(root["data/camera_pose_head"][:].reshape(len(rows), 16), np.array([x["camera_pose.head"] for x in rows], np.float32))
    assert root["data/done"][:].tolist() == [x["done"] for x in rows]
    assert [e["audio_path"] for e in root.attrs["episodes"]][0] == rows[0]["audio_path"]
    bad = CliRunner().invoke(app, ["export", str(ds), "--format", "zarr", "--out", str(tmp_path / "z"), "--video", "rgb"])
    assert bad.exit_code == 2 and not (tmp_path / "z").exists()


def test_zarr_per_split_holds_only_its_split(ds: Path, tmp_path: Path) -> None:
    """--split: one replay buffer per split, each holding only its split's episodes (Diffusion
    Policy draws validation episodes at random from everything in a buffer)."""
    rows = _rows(ds)
    for split, n_eps in (("train", 3), ("test", 2)):
        out = tmp_path / f"{split}.zarr"
        r = CliRunner().invoke(app, ["export", str(ds), "--format", "zarr", "--out", str(out), "--split", split])
        assert r.exit_code == 0, r.output
        root = zarr.open_group(str(out), mode="r")
        mine = [x for x in rows if x["split"] == split]
        ends = root["meta/episode_ends"][:]
        assert len(ends) == n_eps and ends[-1] == len(mine)
        assert set(root["meta/episode_split"][:].tolist()) == {0 if split == "train" else 2}
        assert {e["split"] for e in root.attrs["episodes"]} == {split}
        np.testing.assert_array_equal(root["data/action"][:], np.array([x["action"] for x in mine], np.float32))
    bad = CliRunner().invoke(app, ["export", str(ds), "--format", "lerobot", "--out", str(tmp_path / "l"), "--split", "val"])
    assert bad.exit_code == 2 and "--split val" in bad.output and not (tmp_path / "l").exists()  # a split the dataset lacks
