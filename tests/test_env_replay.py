"""Same world as the dataset: reset the environment to a built episode, replay its actions, get its rows back.

One episode of each setting is built with the real pipeline (tiny cameras), then replayed in a
fresh `EchoDataEnv`: every state, image, spectrogram, log-mel and audio sample must be
identical to the dataset's rows and WAV (bit for bit: SAPIEN's CPU physics, the renderer and
the streaming acoustics are deterministic for the same inputs in one process).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import soundfile as sf
from PIL import Image

from echo_data.dataset.encode import encode_wav
from echo_data.dataset.schema import STATE, StepLayout, column_to_numpy
from echo_data.envs import EchoDataEnv, observation_space
from echo_data.envs.env import BINAURAL
from echo_data.recipe import CameraConfig, load_recipe

ROOT = Path(__file__).resolve().parents[1]


def tiny_recipe(setting: str = "quickstart"):
    r = load_recipe(ROOT / "recipes" / f"{setting}.yaml")
    cam = CameraConfig(width=32, height=32)
    robot = r.robot.model_copy(update={"head_camera": cam, "wrist_camera": cam.model_copy(update={"rgb": False})})
    comp = {"object_relocation": {"test": 1}, "state_transition": {"test": 1}, "multi_event": {"test": 1}}
    return r.model_copy(update={"robot": robot, "composition": comp, "splits": {"test": 3}})


def test_observation_space_is_the_dataset_schema() -> None:
    recipe = tiny_recipe()
    layout = StepLayout.from_recipe(recipe)
    schema = layout.schema()
    space = observation_space(recipe)
    dataset_obs = {f.name for f in schema if f.name.startswith("observation.")}
    assert set(space.spaces) - {BINAURAL} == dataset_obs
    for col, (kind, h, w) in layout.images.items():
        assert space[col].shape == ((h, w, 3) if kind == "rgb" else (h, w))
        assert space[col].dtype == (np.uint8 if kind == "rgb" else np.uint16)
    for col, shape in layout.arrays.items():
        assert space[col].shape == shape and space[col].dtype == np.float32
        assert schema.field(col).type.value_type == "float32"
    assert space[STATE].shape == (schema.field(STATE).type.list_size,) and space[STATE].dtype == np.float32
    hop = recipe.acoustics.sample_rate // recipe.robot.control_hz
    assert space[BINAURAL].shape == (hop, 2)


def _decode(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)))


@pytest.mark.slow
def test_replaying_a_dataset_episode_reproduces_its_rows(tmp_path: Path) -> None:
    import pyarrow.compute as pc

    from echo_data.app.build import build

    recipe = tiny_recipe()
    out = tmp_path / "ds"
    build(recipe, ROOT / "recipes" / "quickstart.yaml", out, progress=False)
    episodes = pq.read_table(out / "meta" / "episodes.parquet").to_pylist()
    table = pq.read_table(sorted((out / "data").glob("test-*.parquet")))
    assert {e["setting"] for e in episodes} == {"object_relocation", "state_transition", "multi_event"}
    layout = StepLayout.from_recipe(recipe)
    env = EchoDataEnv(recipe, split="test")
    for ep in episodes:
        rows = table.filter(pc.equal(table["episode_index"], ep["episode_index"])).sort_by("frame_index")
        retry = ep["attempt"] // recipe.max_attempts_per_episode
        obs, info = env.reset(options={"split": "test", "index": ep["episode_index"], "attempt": retry})
        assert info["episode_id"] == ep["episode_id"]
        actions = np.array(rows["action"].to_pylist(), np.float32)
        states = np.array(rows[STATE].to_pylist(), np.float32)
        arrays = {col: column_to_numpy(rows[col], shape) for col, shape in layout.arrays.items()}
        images = {col: [_decode(v["bytes"]) for v in rows[col].to_pylist()] for col in layout.images}
        blocks = []
        for t, a in enumerate(actions):
            where = f"{ep['episode_id']} frame {t}"
            assert np.array_equal(obs[STATE], states[t]), f"state differs at {where}"
            for col, pics in images.items():
                assert np.array_equal(obs[col], pics[t]), f"{col} differs at {where}"
            for col, values in arrays.items():
                assert np.array_equal(obs[col], values[t]), f"{col} differs at {where}"
            obs, _, terminated, truncated, info = env.step(a)
            blocks.append(obs[BINAURAL])
        track, offsets = env.episode_audio()
        wav, fs = sf.read(out / ep["audio_path"], dtype="int16")
        ours, _ = sf.read(io.BytesIO(encode_wav(track, fs)), dtype="int16")
        assert np.array_equal(ours, wav), f"{ep['episode_id']}: audio differs from the WAV"
        # the per-step blocks are the track itself, control period by control period
        start = int(offsets[0])
        assert np.array_equal(np.concatenate(blocks), track[start : start + sum(len(b) for b in blocks)])
        assert np.array_equal(np.asarray(rows["audio_offset"].to_pylist()), offsets)
        assert info["success"] and all(s["done"] for s in info["skills"])
    env.close()
