"""Same seed -> bit-identical step records, in this process and in a fresh one."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from echo_data.recipe import CameraConfig, Recipe, load_recipe

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys
from echo_data.recipe import recipe_from_mapping
from echo_data.episode import EpisodeSpec
from echo_data.app.pipeline import simulate
from echo_data.records import records_digest
d = json.load(open(sys.argv[1]))
recipe = recipe_from_mapping(d["recipe"])
spec = EpisodeSpec.from_dict(d["spec"])
ro = simulate(spec, recipe)
print("DIGEST", records_digest(ro.steps), len(ro.steps), ro.success)
"""


def small_camera_recipe(path: Path) -> Recipe:
    r = load_recipe(path)
    cam = CameraConfig(width=32, height=32)
    return r.model_copy(update={"robot": r.robot.model_copy(update={"head_camera": cam, "wrist_camera": cam.model_copy(update={"rgb": False})})})


@pytest.mark.slow
def test_same_spec_gives_identical_records(tmp_path: Path) -> None:
    from echo_data.app.pipeline import simulate
    from echo_data.records import records_digest
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary

    recipe = small_camera_recipe(ROOT / "recipes" / "state_transition.yaml")
    spec, _ = sample_episode(recipe, "train", 0, SoundLibrary.builtin())
    first = simulate(spec, recipe)
    second = simulate(spec, recipe)
    assert len(first.steps) > 10
    assert records_digest(first.steps) == records_digest(second.steps)

    f = tmp_path / "job.json"
    f.write_text(json.dumps({"recipe": recipe.model_dump(mode="json"), "spec": spec.to_dict()}))
    env = {**os.environ, "LP_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", _CHILD, str(f)], capture_output=True, text=True, env=env, timeout=600)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("DIGEST")]
    assert line, out.stderr[-2000:]
    assert line[0].split()[1] == records_digest(first.steps)


def test_digest_sees_a_one_pixel_change() -> None:
    import numpy as np

    from echo_data.records import ACTION_DIM, STATE_DIM, StepRecord, records_digest

    img = np.zeros((4, 4, 3), np.uint8)
    rec = StepRecord(0, 0.0, "Navigate", 0, np.zeros(ACTION_DIM, np.float32), np.zeros(STATE_DIM, np.float32), img, None, None, (0.0, 0.0, 1.2), 0.0, (True,))
    d0 = records_digest([rec])
    img[1, 2, 0] = 1
    assert records_digest([rec]) != d0
