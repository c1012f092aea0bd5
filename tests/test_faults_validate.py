"""`validate` against the damage it used to miss: each kind applied to a copy of one freshly
built dataset, and the problem it reports named exactly. Also: a writer that clips (as the old
one did) leaves a dataset validate refuses, and the new writer refuses to clip at all."""

from __future__ import annotations

import io
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from support.synth import build_synth, damageable_copy, null_library, synth_generate, synth_recipe

import echo_data.dataset.encode as encode_mod
from echo_data.app.build import BuildError, build
from echo_data.dataset.validate import validate

TESTS = Path(__file__).resolve().parent


@pytest.fixture(scope="session")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = build_synth(tmp_path_factory.mktemp("faults-validate") / "synth", dict(synth_recipe().splits))
    assert validate(out) == []
    return out


@pytest.fixture
def ds(pristine: Path, tmp_path: Path) -> Path:
    return damageable_copy(pristine, tmp_path)


def _edit_json(path: Path, edit: Callable[[dict], None]) -> None:
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data, indent=1))


def _manifest_counts(d: Path) -> None:
    _edit_json(d / "manifest.json", lambda m: m["counts"]["episodes"].update(train=m["counts"]["episodes"]["train"] + 1))


def _manifest_success_rate(d: Path) -> None:
    _edit_json(d / "manifest.json", lambda m: m["counts"].update(episode_success_rate=1.0))


def _stray_shard(d: Path) -> None:
    shutil.copy(d / "data" / "train-00000-of-00003.parquet", d / "data" / "train-00003-of-00004.parquet")


def _stray_wav(d: Path) -> None:
    shutil.copy(d / "audio" / "train" / "train-000000.wav", d / "audio" / "train" / "train-000099.wav")


def _missing_info(d: Path) -> None:
    (d / "meta" / "info.json").unlink()


def _edited_stats(d: Path) -> None:
    _edit_json(d / "meta" / "stats.json", lambda s: s["action"].update(mean=[0.0] * len(s["action"]["mean"])))


def _edited_planner_json(d: Path) -> None:
    _edit_json(d / "planner" / "train.json", lambda recs: recs[0]["messages"][1].update(content="[]"))  # type: ignore[arg-type, index]


def _truncated_planner_wav(d: Path) -> None:
    wav = d / "planner" / "audio" / "test" / "test-000001.wav"
    wav.write_bytes(wav.read_bytes()[:-800])


def _truncated_binaural_wav(d: Path) -> None:
    wav = d / "planner" / "audio_binaural" / "test" / "test-000001.wav"
    wav.write_bytes(wav.read_bytes()[:-800])


def _manifest_skills(d: Path) -> None:
    _edit_json(d / "manifest.json", lambda m: m["skills"]["Pick"].update(successes=m["skills"]["Pick"]["attempts"]))


DAMAGE = {
    "manifest counts": (_manifest_counts, "manifest.json: counts.episodes is"),
    "manifest success rate": (_manifest_success_rate, "manifest.json: counts.episode_success_rate is 1.0"),
    "manifest skills": (_manifest_skills, "manifest.json: skills differs"),
    "stray shard": (_stray_shard, "data/train-00003-of-00004.parquet: stray file"),
    "stray wav": (_stray_wav, "audio/train/train-000099.wav: stray file"),
    "missing meta/info.json": (_missing_info, "meta/info.json: missing"),
    "edited meta/stats.json": (_edited_stats, "meta/stats.json: differs from what the shards give"),
    "edited planner json": (_edited_planner_json, "planner/train.json: differs from what the shards give"),
    "truncated planner wav": (_truncated_planner_wav, "planner/audio/test/test-000001.wav: differs from the clip of audio/test/test-000001.wav"),
    "truncated binaural planner wav": (
        _truncated_binaural_wav,
        "planner/audio_binaural/test/test-000001.wav: differs from the clip of audio/test/test-000001.wav",
    ),
}


@pytest.mark.parametrize("kind", sorted(DAMAGE))
def test_damage_is_found_and_named(kind: str, ds: Path) -> None:
    damage, expected = DAMAGE[kind]
    damage(ds)
    problems = validate(ds)
    assert any(p.startswith(expected) for p in problems), (expected, problems)


# ------------------------------------------------------------ clipping and audio features


def _loud(recipe, split, index, library, recipe_dir, attempt=0):  # noqa: ANN001, ANN201
    """Episodes whose track goes past full scale (as today's uncalibrated tracks can)."""
    ep = synth_generate(recipe, split, index, library, recipe_dir, attempt=attempt)
    if ep.audio is not None:
        ep.audio = (ep.audio * 6.0).astype(np.float32)  # peaks near 1.8: clips; features stay those of the quiet track
    return ep


def _old_encode_wav(audio: np.ndarray, sample_rate: int, what: str = "audio") -> bytes:
    """The writer before: clip to [-1, 1] without a word."""
    buf = io.BytesIO()
    sf.write(buf, np.clip(np.asarray(audio, dtype=np.float32), -1.0, 1.0), sample_rate, subtype="PCM_16", format="WAV")
    return buf.getvalue()


def test_clipped_audio_and_features_of_other_audio_are_found(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A dataset written the old way (clipping silently, features of the unclipped track)."""
    monkeypatch.setattr(encode_mod, "encode_wav", _old_encode_wav)
    monkeypatch.setattr(encode_mod, "as_written", lambda audio, what="": np.asarray(audio, dtype=np.float32))
    out = tmp_path / "loud"
    build(synth_recipe(splits={"train": 2}), TESTS, out, generate=_loud, make_library=null_library, progress=False)
    monkeypatch.undo()
    problems = validate(out)
    clipped = [p for p in problems if "clipped samples (at 16-bit full scale)" in p]
    spec = [p for p in problems if "observation.audio.spectrogram does not match the WAV's samples" in p]
    mel = [p for p in problems if "observation.audio.mel does not match the WAV's samples" in p]
    assert len(clipped) == 2 and len(spec) == 2 and len(mel) == 2, problems
    assert clipped[0].startswith("train-000000: audio/train/train-000000.wav has ")


def test_features_of_different_audio_are_found_without_clipping(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def quiet_features(recipe, split, index, library, recipe_dir, attempt=0):  # noqa: ANN001, ANN202
        ep = synth_generate(recipe, split, index, library, recipe_dir, attempt=attempt)
        if ep.audio is not None:
            ep.audio = (ep.audio * 0.5).astype(np.float32)  # quieter WAV than the features describe
        return ep

    out = tmp_path / "quiet"
    build(synth_recipe(splits={"train": 1}), TESTS, out, generate=quiet_features, make_library=null_library, progress=False)
    problems = validate(out)
    assert any(p.startswith("train-000000: observation.audio.spectrogram does not match") for p in problems), problems
    assert not any("clipped" in p for p in problems)


def test_writer_refuses_to_clip(tmp_path: Path) -> None:
    with pytest.raises(BuildError, match=r"train episode 0: cannot be stored: train-000000 audio: \d+ of \d+ samples .* reach 16-bit full scale .*refusing to clip"):
        build(synth_recipe(splits={"train": 1}), TESTS, tmp_path / "loud", generate=_loud, make_library=null_library, progress=False)


def test_wrong_stop_labels_and_a_continuous_gripper_are_found(tmp_path: Path) -> None:
    def bad_labels(recipe, split, index, library, recipe_dir, attempt=0):  # noqa: ANN001, ANN202
        ep = synth_generate(recipe, split, index, library, recipe_dir, attempt=attempt)
        ep.steps[0].skill_stop = not ep.steps[0].skill_stop  # a stop where the skill goes on (or none where it ends)
        ee = np.array(ep.steps[1].action_ee, np.float32)
        ee[-1] = 0.4  # a gripper command that is neither open nor close
        ep.steps[1].action_ee = ee
        return ep

    out = tmp_path / "labels"
    build(synth_recipe(splits={"train": 1}), TESTS, out, generate=bad_labels, make_library=null_library, progress=False)
    problems = validate(out)
    stem = "data/train-00000-of-00001.parquet: episode train-000000"
    assert f"{stem} skill_stop is not 1 exactly on each skill segment's last row" in problems, problems
    assert f"{stem} action.ee gripper_close is not 0 or 1" in problems, problems
    assert f"{stem} action.ee.executed gripper_close is not 0 or 1" in problems, problems  # executed = the label here
