"""The dataset card: README.md with Hugging Face front matter that matches the manifest."""

from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml
from support.synth import build_synth
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.manifest import load_manifest


@pytest.fixture(scope="module")
def ds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("card") / "synth", {"train": 4, "test": 2})


def _front(text: str) -> dict:
    assert text.startswith("---\n")
    return yaml.safe_load(text.split("---\n")[1])


def test_card_front_matter_matches_the_manifest(ds: Path) -> None:
    text = (ds / "README.md").read_text()
    front = _front(text)
    m = load_manifest(ds)
    assert front["license"] == "mit" and front["task_categories"] == ["robotics"] and front["size_categories"] == ["n<1K"]
    files = {d["split"]: d["path"] for d in front["configs"][0]["data_files"]}
    assert set(files) == {"train", "test"}
    for split, pattern in files.items():
        assert sorted(p.relative_to(ds).as_posix() for p in ds.glob(pattern)) == [e["file"] for e in m["shards"] if e["split"] == split]
    assert {s["name"]: s["num_examples"] for s in front["dataset_info"]["splits"]} == m["counts"]["steps"]
    for split, n in m["counts"]["episodes"].items():
        assert f"| {split} | {n} | {m['counts']['steps'][split]} |" in text
    assert m["recipe_hash"] in text and "`camera_pose.head`" in text and "| `skill_success` | bool[5] |" in text


def test_hf_datasets_reads_the_card_configs(ds: Path, caplog: pytest.LogCaptureFixture) -> None:
    import datasets  # the test extra installs it: a missing one fails, never skips
    with caplog.at_level("WARNING"):
        d = datasets.load_dataset(str(ds))
    m = load_manifest(ds)
    assert {k: len(v) for k, v in d.items()} == m["counts"]["steps"]
    assert not [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]  # e.g. "splits field in YAML is malformed"
    front = _front((ds / "README.md").read_text())
    sizes = {s["name"]: s["num_bytes"] for s in front["dataset_info"]["splits"]}
    assert sizes == {s: sum(e["bytes"] for e in m["shards"] if e["split"] == s) for s in sizes} and all(sizes.values())


def test_card_cites_and_links(ds: Path) -> None:
    text = (ds / "README.md").read_text()
    assert "## Citation" in text and "@inproceedings{" in text and "Sound-Triggered Mobile Manipulation" in text
    assert "## Links" in text and "`synth`" in text and "--format lerobot|robomimic|zarr" in text
    # the KEMAR HRTF's licence asks for its authors to be cited; echo-data itself has a BibTeX entry
    assert "@article{gardner1995kemar" in text and "3907--3908" in text and "@software{echo_data" in text
    assert _front(text)["annotations_creators"] == ["machine-generated"]
    assert "## Uses" in text and "## Out of scope" in text
    assert "restarts at 0 in every split" in text  # episode_index is per split


def test_info_refreshes_the_card(ds: Path) -> None:
    (ds / "README.md").unlink()
    assert CliRunner().invoke(app, ["info", str(ds)]).exit_code == 0
    assert _front((ds / "README.md").read_text())["pretty_name"] == "echo-data synth"


def test_card_states_the_audio_calibration(ds: Path) -> None:
    """The card says what a WAV sample means in sound pressure, as the manifest records it."""
    audio = load_manifest(ds)["audio"]
    text = (ds / "README.md").read_text()
    assert "## Audio calibration" in text
    assert f"a sample of 1.0 is {audio['full_scale_db_spl']:g} dB SPL" in text
    for cat, (lo, hi) in audio["source_levels_db_spl_at_1m"].items():
        assert f"| {cat} | {lo:g}–{hi:g} |" in text


def test_audio_config_plays_the_episode_wavs(ds: Path, tmp_path: Path) -> None:
    """The card's `audio` config loads with `datasets` as an Audio feature holding each episode's
    WAV bytes (what the Hub's viewer plays), and validate notices a table that drifts from them."""
    import datasets
    import pyarrow as pa
    from support.synth import damageable_copy

    from echo_data.dataset.validate import validate

    front = _front((ds / "README.md").read_text())
    assert [c["config_name"] for c in front["configs"]] == ["default", "audio"]
    d = datasets.load_dataset(str(ds), "audio", split="test")
    assert isinstance(d.features["audio"], datasets.Audio)
    rows = [r for r in pq.read_table(ds / "meta" / "episodes.parquet").to_pylist() if r["split"] == "test"]
    raw = d.cast_column("audio", datasets.Audio(decode=False))
    assert [x["episode_id"] for x in raw] == [r["episode_id"] for r in rows]
    assert all(x["audio"]["bytes"] == (ds / r["audio_path"]).read_bytes() for x, r in zip(raw, rows))
    bad = damageable_copy(ds, tmp_path)
    table = pq.read_table(bad / "meta" / "audio" / "test.parquet")
    cells = table.column("audio").to_pylist()
    cells[0]["bytes"] = cells[0]["bytes"][:-2]
    pq.write_table(table.set_column(2, "audio", pa.array(cells, table.schema.field("audio").type)), bad / "meta" / "audio" / "test.parquet")
    assert any("meta/audio/test.parquet" in p and "differs" in p for p in validate(bad))


def test_audio_config_decodes_a_row(ds: Path) -> None:
    """A row of the `audio` config decodes through `datasets` itself (its Audio feature decodes
    with torchcodec and FFmpeg, which scripts/setup.sh and setup_system.sh install), to the
    episode WAV's samples at its rate."""
    import importlib.util
    import os

    import datasets
    import numpy as np
    import soundfile

    if importlib.util.find_spec("torchcodec") is None and not os.environ.get("CI"):
        pytest.skip("torchcodec not installed (bash scripts/setup.sh)")
    d = datasets.load_dataset(str(ds), "audio", split="train")
    row = d[0]
    samples = row["audio"].get_all_samples()  # what datasets hands a user: a decoder, read whole
    wav, rate = soundfile.read(ds / f"audio/train/{row['episode_id']}.wav", dtype="float32", always_2d=True)
    assert samples.sample_rate == rate and tuple(samples.data.shape) == (2, len(wav))
    np.testing.assert_allclose(samples.data.numpy().T, wav, atol=1e-6)
