"""`outputs.max_frames`: episodes cut after their first N control steps, in the same dataset format.

A cut build must hold exactly the first frames of the whole build of the same recipe and seed
(the experts act as in the whole episode), be a complete dataset (validate, manifest counts, card,
planner export, LeRobot export) and train the planner unchanged. Built for real, one episode per
split of quickstart (--limit 1), once whole and once cut.
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
import soundfile as sf
import yaml
from support.optional import needs_torch
from typer.testing import CliRunner

from echo_data.agents.runtime import run_episode
from echo_data.cli import app
from echo_data.dataset.validate import validate
from echo_data.envs.audio import pre_roll_steps
from echo_data.episode import SkillCall
from echo_data.recipe import load_recipe, recipe_from_mapping
from echo_data.records import ACTION_DIM

RECIPES = Path(__file__).resolve().parent.parent / "recipes"
N = 10  # quickstart's first Navigate takes longer than this: every episode is cut
runner = CliRunner()


def _build(recipe: Path, out: Path) -> Path:
    res = runner.invoke(app, ["build", str(recipe), "--out", str(out), "--limit", "1", "--workers", "2", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def builds(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("truncate")
    cut = tmp / "quickstart_cut.yaml"
    cut.write_text(yaml.safe_dump({"extends": str(RECIPES / "quickstart.yaml"), "outputs": {"max_frames": N}}))
    return _build(RECIPES / "quickstart.yaml", tmp / "whole"), _build(cut, tmp / "cut")


def _rows(ds: Path, split: str) -> list[dict[str, Any]]:
    return [r for f in sorted((ds / "data").glob(f"{split}-*.parquet")) for r in pq.read_table(f).to_pylist()]


def _episodes(ds: Path) -> dict[str, dict[str, Any]]:
    return {r["episode_id"]: r for r in pq.read_table(ds / "meta" / "episodes.parquet").to_pylist()}


def _wav(ds: Path, rel: str) -> np.ndarray:
    return sf.read(io.BytesIO((ds / rel).read_bytes()), dtype="int16", always_2d=True)[0]


def test_cut_frames_are_the_whole_build_first_frames(builds: tuple[Path, Path]) -> None:
    whole, cut = builds
    ew, ec = _episodes(whole), _episodes(cut)
    assert ew.keys() == ec.keys() and len(ec) == 2
    recipe = load_recipe(RECIPES / "quickstart.yaml")
    hop = recipe.acoustics.sample_rate // recipe.robot.control_hz
    for eid, c in ec.items():
        w = ew[eid]
        assert (c["seed"], c["attempt"], c["events"], c["chain"]) == (w["seed"], w["attempt"], w["events"], w["chain"])
        assert w["n_steps"] > N and w["success"] and w["truncated_at"] is None
        assert c["n_steps"] == N and c["truncated_at"] == N and not c["success"] and c["outcomes"] == []
        # audio: the WAV is bit for bit the whole episode's up to the end of step N (then the cut's fade and tail)
        played = (pre_roll_steps(recipe) + N) * hop
        a, b = _wav(cut, c["audio_path"]), _wav(whole, w["audio_path"])
        k = min(len(a), len(b))
        differ = np.flatnonzero(np.any(a[:k] != b[:k], axis=1))
        assert len(a) < len(b) and (differ[0] if len(differ) else k) >= played
    for split in ("train", "test"):
        rc = _rows(cut, split)
        rw = [r for r in _rows(whole, split) if r["frame_index"] < N]
        assert len(rc) == len(rw) == N
        for x, y in zip(rc, rw):
            for col in x:  # every column bit for bit: state, action, images (PNG bytes), audio features, poses
                if col in ("done", "skill_success", "index"):
                    continue
                assert x[col] == y[col], (split, x["frame_index"], col)
        # the last stored frame ends the episode; its chain flags are the outcomes so far (none finished)
        assert [r["done"] for r in rc] == [False] * (N - 1) + [True]
        assert not any(v for r in rc for v in r["skill_success"])


def test_cut_build_is_a_complete_dataset(builds: tuple[Path, Path], tmp_path: Path) -> None:
    _, cut = builds
    assert validate(cut) == []
    res = runner.invoke(app, ["validate", str(cut)])
    assert res.exit_code == 0, res.output
    m = json.loads((cut / "manifest.json").read_text())
    # cut episodes are complete: stored, counted, never retried as failures
    assert m["counts"]["truncated_episodes"] == {"train": 1, "test": 1}
    assert m["counts"]["episodes"] == {"train": 1, "test": 1} and m["failed_episodes"] == []
    assert m["recipe"]["outputs"]["max_frames"] == N
    assert "first 10 control steps" in (cut / "README.md").read_text()
    for eid, e in _episodes(cut).items():  # the planner export is written for every episode
        split = e["split"]
        assert (cut / "planner" / "audio" / split / f"{eid}.wav").is_file() and (cut / "planner" / "images" / split / f"{eid}.png").is_file()
    assert len(json.loads((cut / "planner" / "train.json").read_text())) == 1
    le = tmp_path / "le"
    res = runner.invoke(app, ["export", str(cut), "--format", "lerobot", "--out", str(le)])
    assert res.exit_code == 0, res.output
    eps = pq.read_table(le / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert [(e["length"], e["truncated"], e["split"]) for e in eps] == [(N, True, "train")]  # the train split (lerobot-train reads a whole folder)
    res = runner.invoke(app, ["info", str(cut)])
    assert res.exit_code == 0, res.output


def test_whole_build_counts_no_cut_episodes(builds: tuple[Path, Path]) -> None:
    whole, _ = builds
    m = json.loads((whole / "manifest.json").read_text())
    assert m["counts"]["truncated_episodes"] == {"train": 0, "test": 0}
    assert "control steps (`outputs.max_frames`)" not in (whole / "README.md").read_text()


@needs_torch
def test_planner_trains_on_a_cut_build(builds: tuple[Path, Path], tmp_path: Path) -> None:
    _, cut = builds
    run = tmp_path / "planner"
    res = runner.invoke(app, ["train", "planner", str(cut), "--inputs", "audio", "--epochs", "2", "--out", str(run), "--threads", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    report = json.loads((run / "eval.json").read_text())
    assert "test" not in report["episodes"] and report["train_rows"] + report["episodes"]["val"] >= 1
    res = runner.invoke(app, ["evaluate-planner", str(run)])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["episodes"]["test"] == 1


# ------------------------------------------------------------------ the cut in the episode loop


class _Env:
    """Just what run_episode reads: a chain, a step counter, success tests by step count."""

    def __init__(self, chain: list[SkillCall], done_at: dict[int, int]) -> None:
        self.episode = SimpleNamespace(episode_id="train-000000", setting="state_transition", seed=0, plan=None, chain=tuple(chain))
        self.recipe = recipe_from_mapping({"name": "x"})
        self.world = SimpleNamespace(robot=SimpleNamespace(base_pose=lambda: (0.0, 0.0, 0.0)))
        self.steps, self.done_at = 0, done_at

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        self.steps += 1
        return {}, 0.0, False, False, self.info()

    def info(self) -> dict:
        """The environment's info: each chain skill's success test at this step, and `done` (latched in chain order)."""
        ok = [self.steps >= self.done_at[k] for k in range(len(self.episode.chain))]
        return {"skills": [{"success": ok[k], "done": all(ok[: k + 1])} for k in range(len(ok))]}


class _Planner:
    privileged = True  # reads the true chain

    def reset(self, info: dict) -> None:
        self.chain = info["true_chain"]

    def plan(self, obs: dict) -> list:
        return self.chain


class _Policy:
    def reset(self, info: dict) -> None:
        pass

    def act(self, obs: dict) -> np.ndarray:
        return np.zeros(ACTION_DIM, np.float32)


CHAIN = [SkillCall("OpenDoor", "door:0", 0), SkillCall("CloseSink", "faucet:0", 1)]


@pytest.mark.parametrize(
    "max_steps, steps, outcomes, truncated_at",
    [
        (3, 3, [], 3),  # cut inside the first skill: it gets no outcome
        (5, 5, [True], 5),  # the first skill ends exactly at the cut: finished, the second never starts
        (7, 7, [True], 7),  # cut inside the second skill
        (9, 9, [True, True], None),  # the chain ends at the cut: a whole episode
        (None, 9, [True, True], None),
    ],
)
def test_run_episode_cuts_after_max_steps(max_steps: int | None, steps: int, outcomes: list[bool], truncated_at: int | None) -> None:
    env = _Env(CHAIN, {0: 5, 1: 9})
    seen: list[int] = []
    run = run_episode(env, {}, env.info(), _Planner(), _Policy(), on_step=lambda e, *a: seen.append(e.steps), max_steps=max_steps)
    assert (run.steps, [o.success for o in run.outcomes], run.truncated_at) == (steps, outcomes, truncated_at)
    assert seen == list(range(steps)) and run.failure == "" and run.success == (truncated_at is None)
