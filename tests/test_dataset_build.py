"""Build orchestration and the on-disk contract, with the synthetic generator injected."""

from __future__ import annotations

import hashlib
import io
import json
import os
from pathlib import Path

import numpy as np
import pyarrow.dataset as pds
import pyarrow.parquet as pq
import pytest
import soundfile as sf
import typer
import yaml
from support.synth import null_library, synth_generate, synth_recipe
from typer.testing import CliRunner

from echo_data.app.build import BuildError, OutputError, build
from echo_data.app.commands import register
from echo_data.dataset.validate import validate

RECIPE_PATH = Path(__file__)  # only its directory matters to the synthetic generator


def _build(out: Path, **kw: object):
    kw.setdefault("generate", synth_generate)
    kw.setdefault("make_library", null_library)
    kw.setdefault("progress", False)
    recipe = kw.pop("recipe", None) or synth_recipe()
    return build(recipe, RECIPE_PATH, out, **kw)  # type: ignore[arg-type]


def _digests(root: Path) -> dict[str, str]:
    """sha256 of every file but the manifest (which holds timestamps and the worker count)."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != "manifest.json"
    }


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "synth"
    _build(out)
    return out


def test_layout_and_names(built: Path) -> None:
    m = json.loads((built / "manifest.json").read_text())
    assert sorted(p.name for p in (built / "data").iterdir()) == [
        "test-00000-of-00002.parquet",
        "test-00001-of-00002.parquet",
        "train-00000-of-00003.parquet",
        "train-00001-of-00003.parquet",
        "train-00002-of-00003.parquet",
    ]
    assert m["complete"] and m["recipe_hash"] == synth_recipe().content_hash() and m["limit"] is None
    assert m["counts"]["episodes"] == {"train": 5, "test": 3}
    assert {"numpy", "pyarrow", "sapien", "pyroomacoustics", "echo-data"} <= set(m["versions"])
    for e in m["shards"]:
        assert hashlib.sha256((built / e["file"]).read_bytes()).hexdigest() == e["sha256"]
        md = pq.ParquetFile(built / e["file"]).metadata
        assert md.num_rows == e["rows"]
        mel = next(md.row_group(0).column(i) for i in range(md.num_columns) if md.row_group(0).column(i).path_in_schema.startswith("observation.audio.mel"))
        assert "BYTE_STREAM_SPLIT" in mel.encodings  # float features are not dictionary-encoded
    for name in ("meta/episodes.parquet", "meta/stats.json", "meta/info.json", "planner/train.json", "planner/dataset_info.json"):
        assert (built / name).is_file(), name
    assert not (built / ".work").exists()
    info = sf.info(str(built / "audio" / "train" / "train-000003.wav"))
    assert (info.samplerate, info.channels, info.subtype) == (16000, 2, "PCM_16")
    stats = json.loads((built / "meta" / "stats.json").read_text())
    assert len(stats["action"]["mean"]) == 12 and len(stats["observation.state"]["std"]) == 25
    assert len(stats["observation.audio.spectrogram"]["q50"]) == 2 and len(stats["observation.images.head_rgb"]["max"]) == 3
    assert 0.0 <= stats["observation.images.head_rgb"]["min"][0] <= stats["observation.images.head_rgb"]["max"][0] <= 1.0


def test_rows_match_the_generated_episode(built: Path) -> None:
    """What comes back from the shard is exactly what the generator produced (attempt 1 here:
    train-1 failed its first attempt, so the retry with the same index is stored)."""
    r = synth_recipe()
    ep = synth_generate(r, "train", 1, None, RECIPE_PATH, attempt=1)
    t = pq.read_table(built / "data" / "train-00000-of-00003.parquet")
    rows = t.filter(t.column("episode_index").to_numpy() == 1)
    assert rows.column("frame_index").to_pylist() == list(range(len(ep.steps)))
    np.testing.assert_array_equal(np.array(rows.column("action").to_pylist(), np.float32), np.stack([s.action for s in ep.steps]))
    assert rows.column("audio_offset").to_pylist() == ep.audio_offsets.tolist()
    from PIL import Image

    depth = np.asarray(Image.open(io.BytesIO(rows.column("observation.images.head_depth")[2].as_py()["bytes"])))
    np.testing.assert_array_equal(depth, ep.steps[2].head_depth)
    episodes = pq.read_table(built / "meta" / "episodes.parquet").to_pylist()
    row = next(e for e in episodes if e["episode_id"] == "train-000001")
    assert row["attempt"] == 1 and row["seed"] == ep.spec.seed and row["n_steps"] == len(ep.steps)
    assert [c["target_kind"] for c in row["chain"]] == ["phone", "phone", "counter", "counter"]
    audio, sr = sf.read(str(built / row["audio_path"]), dtype="float32")
    assert sr == 16000 and audio.shape == ep.audio.shape and np.abs(audio - ep.audio.clip(-1, 1)).max() < 1e-4


def test_hf_datasets_decodes_images_and_arrays(built: Path) -> None:
    import datasets  # the test extra installs it: a missing one fails, never skips
    files = sorted(str(p) for p in (built / "data").glob("train-*.parquet"))
    ds = datasets.load_dataset("parquet", data_files=files, split="train", cache_dir=str(built.parent / "hf_cache"))
    assert ds.num_rows == 25
    assert type(ds.features["observation.audio.mel"]).__name__ == "Array3D"
    row = ds[4]
    rgb, depth = row["observation.images.head_rgb"], row["observation.images.head_depth"]
    assert rgb.mode == "RGB" and rgb.size == (24, 16)
    assert np.asarray(depth).dtype == np.uint16 and np.asarray(depth).shape == (16, 24)
    assert np.asarray(row["observation.audio.spectrogram"]).shape == (65, 26, 2)
    assert np.asarray(row["observation.audio.mel"]).shape == (64, 101, 2)
    assert len(row["action"]) == 12 and len(row["observation.state"]) == 25 and row["index"] == 4
    assert ds.with_format("numpy")[0:3]["observation.audio.spectrogram"].shape == (3, 65, 26, 2)


def test_pyarrow_dataset_scans(built: Path) -> None:
    d = pds.dataset(built / "data", format="parquet")
    m = json.loads((built / "manifest.json").read_text())
    assert d.count_rows() == sum(m["counts"]["steps"].values())
    picks = d.to_table(columns=["skill", "episode_index"], filter=pds.field("skill") == "Pick")
    assert picks.num_rows > 0 and set(picks.column("skill").to_pylist()) == {"Pick"}


def test_planner_export(built: Path) -> None:
    records = json.loads((built / "planner" / "train.json").read_text())
    assert len(records) == 5
    rec = records[0]
    user, assistant = rec["messages"]
    assert user["role"] == "user" and user["content"].startswith("<audio><image>") and "CloseSink" in user["content"]
    assert assistant["role"] == "assistant"
    assert json.loads(assistant["content"])[0] == {"skill": "Navigate", "target": "phone"}
    assert rec["audios"] == ["audio/train/train-000000.wav"] and rec["images"] == ["images/train/train-000000.png"]
    info = sf.info(str(built / "planner" / rec["audios"][0]))
    heard = pq.read_table(built / "meta" / "episodes.parquet").column("audio_samples")[0].as_py()
    assert (info.samplerate, info.channels, info.frames) == (16000, 1, min(3 * 16000, heard))
    # alongside: the first second with both ears, whose channel mean is the mono clip's first second
    binaural, sr = sf.read(str(built / "planner" / "audio_binaural" / "train" / "train-000000.wav"), always_2d=True)
    mono, _ = sf.read(str(built / "planner" / rec["audios"][0]), always_2d=True)
    assert (sr, binaural.shape) == (16000, (min(16000, heard), 2))
    assert np.abs(binaural.mean(axis=1) - mono[: len(binaural), 0]).max() <= 1.5 / 32768  # 16-bit rounding of each file
    assert np.abs(binaural[:, 0] - binaural[:, 1]).max() > 0  # two ears, not one copied
    assert (built / "planner" / rec["images"][0]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    di = json.loads((built / "planner" / "dataset_info.json").read_text())["synth_train"]
    assert di["formatting"] == "sharegpt" and di["file_name"] == "train.json"
    assert di["columns"] == {"messages": "messages", "audios": "audios", "images": "images"}
    assert di["tags"] == {"role_tag": "role", "content_tag": "content", "user_tag": "user", "assistant_tag": "assistant"}


def test_manifest_records_failures_and_rejections(built: Path) -> None:
    m = json.loads((built / "manifest.json").read_text())
    reasons = {(f["split"], f["index"]): f["reason"] for f in m["failed_episodes"]}
    assert reasons[("train", 1)] == "Pick(phone_0): no IK solution"
    assert reasons[("train", 2)].startswith("sampling: no solvable layout")
    assert m["rejected"]["path_blocked"] == 4  # two SamplingErrors carrying 2 each
    assert m["skills"]["Pick"]["attempts"] == m["skills"]["Pick"]["successes"] + 3
    assert m["counts"]["episode_attempts"] == 8 + len(m["failed_episodes"])


def test_workers_and_resume_give_identical_bytes(built: Path, tmp_path: Path) -> None:
    summary = _build(tmp_path / "synth", workers=2, progress=True)  # the bar's shared step slots travel to the workers
    assert summary.episodes == {"train": 5, "test": 3}
    assert _digests(tmp_path / "synth") == _digests(built)
    again = _build(tmp_path / "synth", mode="resume")
    assert again.generated == 0 and _digests(tmp_path / "synth") == _digests(built)


def test_refuses_existing_output_without_resume_or_overwrite(built: Path, tmp_path: Path) -> None:
    before = _digests(built)
    with pytest.raises(OutputError, match="--resume.*--overwrite"):
        _build(built)
    assert _digests(built) == before
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="not an echo-data dataset"):
        _build(tmp_path / "x", mode="overwrite")
    assert (tmp_path / "x" / "notes.txt").read_text() == "mine"


def test_resume_with_other_recipe_or_limit_is_refused(built: Path) -> None:
    with pytest.raises(OutputError, match="different recipe"):
        _build(built, mode="resume", recipe=synth_recipe(seed=8))
    with pytest.raises(OutputError, match="--limit"):
        _build(built, mode="resume", limit=2)


def test_limit_is_recorded_and_overwrite_replaces(tmp_path: Path) -> None:
    out = tmp_path / "synth"
    _build(out, limit=1)
    m = json.loads((out / "manifest.json").read_text())
    assert m["limit"] == 1 and m["counts"]["episodes"] == {"train": 1, "test": 1}
    assert sorted(p.name for p in (out / "data").iterdir()) == ["test-00000-of-00001.parquet", "train-00000-of-00001.parquet"]
    _build(out, limit=2, mode="overwrite")
    assert json.loads((out / "manifest.json").read_text())["counts"]["episodes"] == {"train": 2, "test": 2}
    assert validate(out) == []


def test_split_builds_only_the_named_split_and_is_recorded(tmp_path: Path) -> None:
    out = tmp_path / "synth"
    _build(out, only=["train"])
    m = json.loads((out / "manifest.json").read_text())
    assert m["only_splits"] == ["train"] and m["counts"]["episodes"] == {"train": synth_recipe().splits["train"]}
    assert all(p.name.startswith("train-") for p in (out / "data").iterdir())
    assert validate(out) == []
    with pytest.raises(OutputError, match="--split"):
        _build(out, mode="resume", only=["test"])
    with pytest.raises(OutputError, match="--split"):
        _build(out, mode="resume")  # all splits is another dataset
    with pytest.raises(OutputError, match="--split val"):
        _build(tmp_path / "other", only=["val"])
    assert not (tmp_path / "other").exists()
    full = tmp_path / "full"
    _build(full)  # the train split's bytes do not depend on whether the test split was built
    assert {k: v for k, v in _digests(full).items() if "train-" in k} == {k: v for k, v in _digests(out).items() if "train-" in k}


def always_fails(recipe, split, index, library, recipe_dir, attempt=0):  # noqa: ANN001, ANN201
    ep = synth_generate(recipe, split, 0, library, recipe_dir, attempt=1)
    ep.success = False
    ep.outcomes[-1].success, ep.outcomes[-1].reason = False, "door jammed"
    return ep


def test_episode_that_never_succeeds_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(BuildError, match=r"train episode 0: no success in 3 attempts.*door jammed"):
        _build(tmp_path / "synth", generate=always_fails)


def _cli(args: list[str]) -> object:
    app = typer.Typer()
    register(app)
    return CliRunner().invoke(app, args)


def test_bad_output_path_exit_2_nothing_written(tmp_path: Path) -> None:
    recipe = tmp_path / "r.yaml"
    recipe.write_text(yaml.safe_dump(synth_recipe().model_dump(mode="json")))
    blocker = tmp_path / "blocker"
    blocker.write_text("a file")
    before = sorted(os.listdir(tmp_path))
    for out in (blocker, blocker / "sub"):
        res = _cli(["build", str(recipe), "--out", str(out)])
        assert res.exit_code == 2, res.output
        assert "not a directory" in res.output and len(res.output.strip().splitlines()) == 1
    with pytest.raises(OutputError, match="not a directory"):
        _build(blocker)
    res = _cli(["build", str(recipe), "--out", "/sys/echo-data-test"])  # EPERM even for root
    assert res.exit_code == 2 and "not writable" in res.output
    assert not Path("/sys/echo-data-test").exists()
    assert sorted(os.listdir(tmp_path)) == before and blocker.read_text() == "a file"


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_read_only_directory_exit_2(tmp_path: Path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o555)
    with pytest.raises(OutputError, match="not writable"):
        _build(ro / "synth")
    assert list(ro.iterdir()) == []


@pytest.mark.parametrize(
    "text, key",
    [
        ("name: x\nscene: [1, 2\n", "malformed YAML"),
        ("name: x\nscene:\n  roomz: [2, 3]\n", "scene.roomz: unknown key"),
        ("name: x\nacoustics:\n  sample_rate: fast\n", "acoustics.sample_rate"),
        ("name: x\nsplits: {train: -1}\n", "splits"),
        ("name: x\nscene:\n  rooms: [4, 2]\n", "scene.rooms"),
        ("name: x\nsounds:\n  folders: {phone: no_such_folder}\n", "sounds.folders.phone"),
    ],
)
def test_cli_bad_recipe_exit_2(tmp_path: Path, text: str, key: str) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    res = _cli(["build", str(bad), "--out", str(tmp_path / "o")])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2 and len(lines) == 1 and key in lines[0] and "bad.yaml" in lines[0]
    assert not (tmp_path / "o").exists()


def test_cli_unreadable_sound_file_exit_2_nothing_written(tmp_path: Path) -> None:
    folder = tmp_path / "my_phones"
    folder.mkdir()
    (folder / "ring.wav").write_bytes(b"RIFF not really a wav")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nsounds:\n  folders: {phone: my_phones}\n")
    res = _cli(["build", str(bad), "--out", str(tmp_path / "o")])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and "ring.wav" in lines[0]
    assert not (tmp_path / "o").exists()


def wrong_shapes(recipe, split, index, library, recipe_dir, attempt=0):  # noqa: ANN001, ANN201
    ep = synth_generate(recipe, split, index, library, recipe_dir, attempt=1)
    ep.mel = ep.mel[:, :10]
    return ep


def test_result_that_breaks_the_contract_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(BuildError, match=r"train episode 0: cannot be stored: observation.audio.mel has shape"):
        _build(tmp_path / "synth", generate=wrong_shapes)


def test_ray_executor_missing_is_a_clear_input_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without Ray (simulated: a None entry in sys.modules makes `import ray` raise ImportError),
    `--executor ray` is refused with the install hint before anything is written."""
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(OutputError, match=r"pip install 'echo-data\[ray\]'"):
        _build(tmp_path / "synth", executor="ray")
    assert not (tmp_path / "synth").exists()


def test_ray_executor_gives_the_same_bytes(built: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`--executor ray` (when Ray is installed: `pip install .[ray]`) writes what the local pool writes."""
    import os

    import ray  # the test extra installs it

    # Ray workers unpickle the synthetic generator by module name: let them import it.
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]))
    try:
        summary = _build(tmp_path / "ray", workers=2, executor="ray")
    finally:
        ray.shutdown()
    assert summary.episodes == {"train": 5, "test": 3}
    assert _digests(tmp_path / "ray") == _digests(built)
