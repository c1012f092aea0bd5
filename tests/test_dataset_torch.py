"""PyTorch loaders: per-step and windowed datasets, filters, DataLoader workers."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from support.synth import synth_generate, synth_recipe
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12); fails on 3.11

from echo_data.dataset.torch import SequenceDataset, StepDataset


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 4, "test": 1})


def _all_rows(ds: Path, split: str) -> dict:
    files = sorted((ds / "data").glob(f"{split}-*.parquet"))
    t = pq.ParquetDataset(files).read(columns=["episode_index", "frame_index", "skill", "setting", "action"])
    return {c: t.column(c).to_pylist() for c in t.column_names}


def test_step_dataset_items_and_filters(ds: Path) -> None:
    rows = _all_rows(ds, "train")
    d = StepDataset(ds, "train")
    assert len(d) == len(rows["episode_index"])
    item = d[5]
    assert item["observation.images.head_rgb"].shape == (3, 16, 24) and item["observation.images.head_rgb"].dtype == torch.float32
    assert item["observation.images.wrist_depth"].shape == (1, 16, 16)
    assert item["observation.audio.spectrogram"].shape == (65, 26, 2)
    assert item["observation.audio.mel"].shape == (64, 101, 2)
    np.testing.assert_allclose(item["action"].numpy(), np.array(rows["action"][5], np.float32))
    episodes = pq.read_table(ds / "meta" / "episodes.parquet").to_pylist()
    row = next(e for e in episodes if e["split"] == "train" and e["attempt"] == 1)  # a retried episode
    ep = synth_generate(synth_recipe(splits={"train": 4, "test": 1}), "train", row["episode_index"], None, Path("."), attempt=1)
    item = d[row["dataset_from_index"] + 2]
    assert int(item["episode_index"]) == row["episode_index"] and int(item["frame_index"]) == 2
    np.testing.assert_allclose(item["observation.images.head_depth"][0].numpy(), ep.steps[2].head_depth / 1000.0, rtol=1e-6)
    np.testing.assert_allclose(item["observation.images.head_rgb"].numpy(), ep.steps[2].head_rgb.transpose(2, 0, 1) / 255.0, rtol=1e-6)
    np.testing.assert_array_equal(item["observation.audio.mel"].numpy(), ep.mel[2])
    picks = StepDataset(ds, "train", skill="Pick", columns=["skill", "action"])
    assert len(picks) == rows["skill"].count("Pick") > 0 and {picks[i]["skill"] for i in range(len(picks))} == {"Pick"}
    assert set(picks[0]) == {"skill", "action"}
    st = StepDataset(ds, "train", setting="state_transition")
    assert len(st) == rows["setting"].count("state_transition") > 0
    with pytest.raises(ValueError, match="unknown columns"):
        StepDataset(ds, "train", columns=["nope"])


def test_dataloader_with_two_workers(ds: Path) -> None:
    d = StepDataset(ds, "train", columns=["index", "action", "observation.images.head_rgb", "observation.audio.spectrogram"])
    loader = torch.utils.data.DataLoader(d, batch_size=4, shuffle=False, num_workers=2)
    batches = list(loader)
    index = torch.cat([b["index"] for b in batches])
    assert index.tolist() == list(range(len(d)))
    assert batches[0]["observation.images.head_rgb"].shape == (4, 3, 16, 24)
    assert batches[0]["observation.audio.spectrogram"].shape == (4, 65, 26, 2)


def test_sequence_windows_pad_at_episode_edges(ds: Path) -> None:
    rows = _all_rows(ds, "train")
    s = SequenceDataset(ds, "train", history=3, action_chunk=4)
    assert len(s) == len(rows["episode_index"])
    first = s[0]
    assert first["observation.state"].shape == (3, 25) and first["action"].shape == (4, 12)
    assert first["observation_is_pad"].tolist() == [True, True, False]
    np.testing.assert_allclose(first["action"][0].numpy(), np.array(rows["action"][0], np.float32))
    n0 = rows["episode_index"].count(0)
    last = s[n0 - 1]  # last step of episode 0: the chunk runs past the end and is padded
    assert int(last["frame_index"]) == n0 - 1 and int(last["episode_index"]) == 0
    assert last["action_is_pad"].tolist() == [False, True, True, True]
    np.testing.assert_allclose(last["action"][3].numpy(), np.array(rows["action"][n0 - 1], np.float32))
    nxt = s[n0]  # first step of episode 1 never sees episode 0
    assert int(nxt["episode_index"]) == 1 and nxt["observation_is_pad"].tolist() == [True, True, False]
    loader = torch.utils.data.DataLoader(s, batch_size=3, num_workers=2)
    batch = next(iter(loader))
    assert batch["observation.images.head_rgb"].shape == (3, 3, 3, 16, 24) and batch["action_is_pad"].shape == (3, 4)


def test_take_equals_collated_items(ds: Path) -> None:
    d = StepDataset(ds, "train")
    idx = [7, 0, 15, 3, 7]  # across shards, out of order, repeated
    got = d.take(idx)
    want = torch.utils.data.default_collate([d[i] for i in idx])
    assert set(got) == set(want)
    for k, v in want.items():
        if isinstance(v, torch.Tensor):
            assert got[k].dtype == v.dtype and torch.equal(got[k], v), k
        else:
            assert got[k] == v, k


def test_default_collate_batches_every_column(ds: Path) -> None:
    d = StepDataset(ds, "train")
    assert set(d.columns) == {f.name for f in pq.read_schema(next((ds / "data").glob("train-*.parquet")))}
    batch = next(iter(torch.utils.data.DataLoader(d, batch_size=3)))  # torch's default collate
    assert batch["skill_success"].shape == (3, 5) and batch["skill_success"].dtype == torch.bool
    assert batch["camera_pose.head"].shape == (3, 16) and batch["audio_sample_rate"].tolist() == [16000] * 3
    assert batch["audio_path"][0] == "audio/train/train-000000.wav"


def test_binaural_window_is_what_the_step_heard(ds: Path) -> None:
    import soundfile as sf

    from echo_data.acoustics.features import last_second
    from echo_data.dataset.audio import binaural_window

    d = StepDataset(ds, "train", columns=["audio_path", "audio_sample_rate", "audio_offset", "observation.audio.spectrogram"])
    row = d[3]
    track, sr = sf.read(ds / row["audio_path"], dtype="float32", always_2d=True)
    np.testing.assert_array_equal(binaural_window(ds, row, 1.0), last_second(track, int(row["audio_offset"]), sr))
    np.testing.assert_array_equal(binaural_window(ds, row, 0.25), last_second(track, int(row["audio_offset"]), sr)[-sr // 4 :])
    long = binaural_window(ds, row, 30.0)  # longer than the episode: zeros before its start
    assert long.shape == (30 * sr, 2) and not long[: 30 * sr - int(row["audio_offset"])].any()
    arrow_row = pq.read_table(sorted((ds / "data").glob("train-*.parquet"))[0]).slice(0, 1).to_pylist()[0]
    assert binaural_window(ds, arrow_row, 0.1).shape == (sr // 10, 2)


def test_shuffled_epochs_cover_every_step_once_per_epoch(ds: Path) -> None:
    d = StepDataset(ds, "train", columns=["index", "action"])
    s = d.shuffled(seed=3, buffer_groups=1)  # one row group per shard here: windows of one group
    loader = torch.utils.data.DataLoader(s, batch_size=4, num_workers=2, persistent_workers=True)
    epochs = [torch.cat([b["index"] for b in loader]).tolist() for _ in range(2)]
    assert sorted(epochs[0]) == sorted(epochs[1]) == list(range(len(d)))
    assert epochs[0] != list(range(len(d))) and epochs[0] != epochs[1]
    one = [int(x["index"]) for x in d.shuffled(seed=3)]
    assert sorted(one) == list(range(len(d)))
    batched = torch.utils.data.DataLoader(d.shuffled(seed=3, batch_size=5), batch_size=None, num_workers=2)
    assert sorted(torch.cat([b["index"] for b in batched]).tolist()) == list(range(len(d)))
    with pytest.raises(ValueError, match="buffer_groups"):
        d.shuffled(buffer_groups=99)


def test_normalize_uses_meta_stats(ds: Path) -> None:
    import json

    from echo_data.dataset.torch import Normalize

    stats = json.loads((ds / "meta" / "stats.json").read_text())
    d = StepDataset(ds, "train")
    batch = next(iter(torch.utils.data.DataLoader(d, batch_size=len(d))))
    norm = Normalize(ds)
    out = norm(batch)
    a = out["action"].numpy()
    np.testing.assert_allclose(a.mean(axis=0), 0, atol=1e-5)  # train stats over the train rows
    np.testing.assert_allclose(a.std(axis=0), 1, atol=1e-4)
    rgb = out["observation.images.head_rgb"]
    want = (batch["observation.images.head_rgb"][:, 1] - stats["observation.images.head_rgb"]["mean"][1]) / stats["observation.images.head_rgb"]["std"][1]
    np.testing.assert_allclose(rgb[:, 1].numpy(), want.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(norm.inverse("action", out["action"]).numpy(), batch["action"].numpy(), rtol=1e-5, atol=1e-5)
    mm = Normalize(ds, mode="min_max", columns=["observation.state"])(batch)["observation.state"].numpy()
    assert mm.min() >= -1 - 1e-5 and mm.max() <= 1 + 1e-5 and set(Normalize(ds, columns=["action"]).params) == {"action"}
