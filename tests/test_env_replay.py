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
from support.recipes import tiny_recipe

from echo_data.dataset.encode import encode_wav
from echo_data.dataset.schema import (
    ACTION,
    ACTION_EE,
    ACTION_EE_EXECUTED,
    ACTION_EXECUTED,
    SKILL_STOP,
    STATE,
    StepLayout,
    column_to_numpy,
    is_privileged,
)
from echo_data.envs import EchoDataEnv, observation_space
from echo_data.envs.env import BINAURAL
from echo_data.envs.privileged import TCP_TO_TARGET, PrivilegedProbe
from echo_data.recipe import Perturbation
from echo_data.records import PRIVILEGED_COLUMNS

ROOT = Path(__file__).resolve().parents[1]


def test_observation_space_is_the_dataset_schema() -> None:
    recipe = tiny_recipe()
    layout = StepLayout.from_recipe(recipe)
    schema = layout.schema()
    space = observation_space(recipe)
    # every observation column but the simulator-only ones, which no policy is handed
    dataset_obs = {f.name for f in schema if f.name.startswith("observation.") and not is_privileged(f.name)}
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
@pytest.mark.parametrize("perturbed", [False, True])
def test_replaying_a_dataset_episode_reproduces_its_rows(tmp_path: Path, perturbed: bool) -> None:
    """Replaying `action.executed` reproduces the episode, with and without the experts' end-effector
    perturbation; at every replayed step the joint columns are exactly the ee columns through the
    robot's one map (so a replay of `action.ee.executed` in ee mode applies the same targets)."""
    import pyarrow.compute as pc

    from echo_data.app.build import build

    recipe = tiny_recipe()
    level = Perturbation(position_cm=0.1, rotation_deg=0.2) if perturbed else Perturbation()
    recipe = recipe.model_copy(update={"experts": recipe.experts.model_copy(update={"perturbation": level})})
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
        actions = np.array(rows[ACTION_EXECUTED].to_pylist(), np.float32)
        labels = np.array(rows[ACTION].to_pylist(), np.float32)
        noisy = np.any(labels != actions, axis=1)
        # without noise the robot executed its labels; with noise most steps were perturbed
        assert (noisy.mean() > 0.2) if perturbed else not noisy.any(), f"{ep['episode_id']}: {noisy.mean():.2f} perturbed"
        states = np.array(rows[STATE].to_pylist(), np.float32)
        arrays = {col: column_to_numpy(rows[col], shape) for col, shape in layout.arrays.items()}
        images = {col: [_decode(v["bytes"]) for v in rows[col].to_pylist()] for col in layout.images}
        labels_ee = np.array(rows[ACTION_EE].to_pylist(), np.float32)
        executed_ee = np.array(rows[ACTION_EE_EXECUTED].to_pylist(), np.float32)
        privileged = {col: np.array(rows[col].to_pylist(), np.float32) for col in PRIVILEGED_COLUMNS}
        skill_index = np.asarray(rows["skill_index"].to_pylist())
        # skill_stop: 1 exactly on each skill segment's last row
        stops = np.append(skill_index[1:] != skill_index[:-1], True).astype(np.int8)
        assert np.array_equal(np.asarray(rows[SKILL_STOP].to_pylist(), np.int8), stops)
        # at the row where Pick's success first holds, the object is in the hand: the TCP is at it
        slot = np.array(rows["skill_success"].to_pylist())
        spec = env.episode
        probe = PrivilegedProbe()
        for k, call in enumerate(spec.chain):
            if call.skill == "Pick":
                first = int(np.argmax(slot[:, k]))
                assert slot[first, k] and np.linalg.norm(privileged[TCP_TO_TARGET][min(first + 1, len(slot) - 1)]) < 0.05
                assert np.linalg.norm(privileged[TCP_TO_TARGET][int(np.argmax(skill_index == k))]) > 0.3  # far at its start
        blocks = []
        for t, a in enumerate(actions):
            where = f"{ep['episode_id']} frame {t}"
            assert np.array_equal(obs[STATE], states[t]), f"state differs at {where}"
            robot = env.world.robot
            # the experts command action.ee: both joint columns are its image through the one map from this commanded state
            assert np.array_equal(robot.ee.to_joint(labels_ee[t]), labels[t]) and np.array_equal(robot.ee.to_joint(executed_ee[t]), a), where
            seen = probe(env.world, spec, spec.chain[int(skill_index[t])])  # recomputed from the replayed world
            assert all(np.array_equal(seen[col], privileged[col][t]) for col in PRIVILEGED_COLUMNS), where
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
