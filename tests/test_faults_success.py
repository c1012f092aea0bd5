"""One meaning of success: a dataset episode replayed in the environment ends on the step the
recorded episode ends (the env terminates when the last skill's test first holds, and the build
records no step after it), and every row's `skill_success` equals the env's success flags after
that row's action. Rows of a skill after its flag turned true are the expert finishing it (letting
go, backing off, tucking): they stay, and the flags say which they are."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
from support.recipes import ROOT, tiny_recipe

from echo_data.dataset.schema import STATE
from echo_data.envs import EchoDataEnv


@pytest.mark.slow
def test_replay_ends_on_the_recorded_step_with_the_recorded_flags(tmp_path: Path) -> None:
    from echo_data.app.build import build

    recipe = tiny_recipe()
    out = tmp_path / "ds"
    build(recipe, ROOT / "recipes" / "quickstart.yaml", out, progress=False)
    episodes = pq.read_table(out / "meta" / "episodes.parquet").to_pylist()
    table = pq.read_table(sorted((out / "data").glob("test-*.parquet")))
    env = EchoDataEnv(recipe, split="test", images=False, audio=False)
    wrapping_up = 0
    for ep in episodes:
        rows = table.filter(pc.equal(table["episode_index"], ep["episode_index"])).sort_by("frame_index").to_pylist()
        obs, info = env.reset(options={"split": "test", "index": ep["episode_index"], "attempt": ep["attempt"] // recipe.max_attempts_per_episode})
        chain = len(info["skills"])
        before = [s["done"] for s in info["skills"]]
        for t, row in enumerate(rows):
            assert np.array_equal(obs[STATE], np.asarray(row[STATE], np.float32)), f"{ep['episode_id']} frame {t}: another state"
            obs, _, terminated, truncated, info = env.step(np.asarray(row["action"], np.float32))
            flags = [s["done"] for s in info["skills"]]
            assert row["skill_success"][:chain] == flags, f"{ep['episode_id']} frame {t}: flags {row['skill_success']} vs env {flags}"
            assert not any(row["skill_success"][chain:])
            assert terminated == (t == len(rows) - 1) == row["done"], f"{ep['episode_id']}: env ended at frame {t} of {len(rows)}"
            wrapping_up += int(before[row["skill_index"]])  # the skill's test held before this row: the expert finishing it
            before = flags
        assert info["success"] and ep["success"]
    assert wrapping_up > 0  # intermediate skills keep their experts' last motions (the next skill starts from them)
    env.close()
