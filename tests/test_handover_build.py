"""The hand-over recorded in the data and `build --handover-from RUN` (docs/handover.md): each
chain entry's record holds the stance it hands over to and where it ended against that target's
interaction pose; a build taught from an `evaluate` run starts the next skill's demonstration
where the learner's drive ended."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from echo_data.agents.builtin import OraclePlanner, OracleSkills
from echo_data.cli import app
from echo_data.skill_table import SKILLS

ROOT = Path(__file__).resolve().parents[1]


def test_the_record_agrees_with_the_environments_hand_over() -> None:
    """The runtime's record of a Navigate: its stance from the skill table, the base pose and the
    offsets the success module computes on the world it ended in, and the env's `handed_over`."""
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv
    from echo_data.skills.success import stance_offset

    env = EchoDataEnv(str(ROOT / "recipes" / "quickstart.yaml"), split="test", images=False, audio=False)
    try:
        seen = set()
        for index, skills in ((0, 1), (1, 1), (0, 2)):
            obs, info = env.reset(options={"split": "test", "index": index})
            run = run_episode(env, obs, info, OraclePlanner(), OracleSkills(), skills=skills)
            chain, out = env.episode.chain, run.outcomes[-1]
            rec = out.handover
            if skills == 2:  # a Pick hands over to no stance
                assert rec is None and out.to_dict()["handover"] is None
                continue
            to = chain[1]
            stance = SKILLS[to.skill].stance
            assert rec is not None and stance is not None and (rec.skill, rec.index) == (to.skill, 1)
            assert (rec.distance, rec.heading) == (stance.distance, stance.heading)
            assert rec.end == env.world.robot.base_pose()
            off = stance_offset(env.world, to.target)
            assert off is not None and rec.goal_distance == pytest.approx(off[0], abs=1e-9) and rec.heading_error == pytest.approx(off[1], abs=1e-9)
            handed = bool(env.handover_flags[0])  # the env's `info["skills"][0]["handed_over"]` of the last step
            assert rec.inside == handed == run.navigate[0].handed_over
            assert rec.inside == (out.success and off[0] <= stance.distance and off[1] <= stance.heading)
            assert rec.learner_stop is None  # no learner pose was given
            seen.add(rec.inside)
        assert True in seen  # the experts hand over inside the stance
    finally:
        env.close()


BACK = 0.35  # m: where the stand-in learner stops, behind the interaction pose (outside the stance)


def _drive_short(world: Any, call: Any, spec: Any) -> Any:
    """A stand-in learned Navigate: the expert's drive to a pose BACK m behind the target's
    interaction pose, still facing the target (inside Navigate's success region), not to the
    pose itself: where a learner that stops early hands over."""
    from echo_data.scene.nav import target_point
    from echo_data.skills.navigate import current_grid, drive_to, goal_pose

    grid = current_grid(world)
    x, y, _ = goal_pose(world, call.target, grid)
    tx, ty = target_point(world.plan, call.target)
    yaw = math.atan2(ty - y, tx - x)
    result = yield from drive_to(world, (x - BACK * math.cos(yaw), y - BACK * math.sin(yaw), yaw), 600, grid=grid)
    return result


def _give_up(world: Any, call: Any, spec: Any) -> Any:
    """Every other skill ends at once (and fails): the evaluation stays short."""
    return None
    yield  # a generator, as the experts are


class _ShortDrive(OracleSkills):
    """The stand-in learner as a policy `evaluate` loads by name (privileged: it reads the world)."""

    def __init__(self) -> None:
        super().__init__({name: _drive_short if name == "Navigate" else _give_up for name in SKILLS})


def _recipe(tmp_path: Path) -> Path:
    """Quickstart's first train episode (object relocation: Navigate -> Pick -> Place), no cameras."""
    p = tmp_path / "r.yaml"
    off = "{rgb: false, depth: false}"
    p.write_text(f"extends: {ROOT / 'recipes' / 'quickstart.yaml'}\nrobot:\n  head_camera: {off}\n  wrist_camera: {off}\n")
    return p


def _one_line_exit_2(r: Any, says: str) -> None:
    err = [ln for ln in r.output.splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(err) == 1 and err[0].startswith("error: ") and says in err[0], r.output


@pytest.fixture(scope="module")
def learner_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, Any]]:
    """(recipe, RUN, RUN's document): the stand-in learner evaluated on train episode 0."""
    tmp = tmp_path_factory.mktemp("run")
    recipe, run = _recipe(tmp), tmp / "run.json"
    r = CliRunner().invoke(app, ["evaluate", str(recipe), "--split", "train", "-n", "1", "--policy", "test_handover_build:_ShortDrive", "--json", str(run)])
    assert r.exit_code == 0, r.output
    return recipe, run, json.loads(run.read_text())


def test_build_starts_the_next_skill_where_the_learner_handed_over(learner_run: tuple[Path, Path, dict[str, Any]], tmp_path: Path) -> None:
    from echo_data.dataset.reader import episode_records
    from echo_data.dataset.validate import validate
    from echo_data.skills.navigate import GOAL_TOL, YAW_TOL, wrap

    recipe, run, doc = learner_run
    nav = doc["episodes"][0]["skills"][0]
    assert nav["skill"] == "Navigate" and nav["success"] and not nav["handover"]["inside"]
    end = nav["handover"]["end"]
    assert nav["handover"]["goal_distance"] > 3 * GOAL_TOL  # it stopped short of the interaction pose
    out = tmp_path / "ds"
    r = CliRunner().invoke(app, ["build", str(recipe), "--out", str(out), "--split", "train", "--limit", "1", "--workers", "1",
                                 "--no-progress", "--handover-from", str(run)])
    assert r.exit_code == 0, r.output
    ep = episode_records(out)[0]
    built = ep["outcomes"][0]["handover"]
    assert built["learner_stop"] is True and ep["seed"] == doc["episodes"][0]["seed"]
    # the expert stopped at the learner's pose (within its own tolerances), not at the interaction pose
    assert math.dist(built["end"][:2], end[:2]) <= GOAL_TOL and abs(wrap(built["end"][2] - end[2])) <= YAW_TOL
    assert built["goal_distance"] > 2 * GOAL_TOL  # the expert's own stop is within GOAL_TOL of the interaction pose
    # and Pick's first row starts there
    import pyarrow.parquet as pq

    rows = pq.read_table(out / "data" / "train-00000-of-00001.parquet", columns=["skill_index", "observation.state"]).to_pylist()
    first = next(row["observation.state"] for row in rows if row["skill_index"] == 1)
    assert np.allclose(first[:3], built["end"], atol=1e-5)
    manifest = json.loads((out / "manifest.json").read_text())
    block = manifest["handover_from"]
    assert block["sha256"] and block["file"] == "run.json" and block["episodes"] == [ep["episode_id"]] and block["fallbacks"] == 0
    assert "run.json" in (out / "README.md").read_text()
    assert validate(out) == []


def test_a_pose_that_is_no_usable_cell_keeps_the_exact_pose_and_is_counted(learner_run: tuple[Path, Path, dict[str, Any]], tmp_path: Path) -> None:
    """RUN given as evaluate's journal (header line, one line per episode), its pose moved off the
    floor plan: the expert stops at the interaction pose, the record and the manifest say so."""
    from echo_data.dataset.reader import episode_records
    from echo_data.skills.navigate import GOAL_TOL

    recipe, _, doc = learner_run
    rec = json.loads(json.dumps(doc["episodes"][0]))
    rec["skills"][0]["handover"]["end"] = [-50.0, -50.0, 0.0]
    journal = tmp_path / "run.episodes.jsonl"
    head = {"evaluation": {"recipe": doc["recipe"]["content_hash"], "split": "train", "policy": doc["policy"]}}
    journal.write_text(json.dumps(head) + "\n" + json.dumps(rec) + "\n" + '{"torn')
    out = tmp_path / "ds"
    r = CliRunner().invoke(app, ["build", str(recipe), "--out", str(out), "--split", "train", "--limit", "1", "--workers", "1",
                                 "--no-progress", "--handover-from", str(journal)])
    assert r.exit_code == 0, r.output
    built = episode_records(out)[0]["outcomes"][0]["handover"]
    assert built["learner_stop"] is False and built["goal_distance"] <= GOAL_TOL
    block = json.loads((out / "manifest.json").read_text())["handover_from"]
    assert (block["file"], block["episodes"], block["fallbacks"]) == (journal.name, [], 1)


@pytest.mark.parametrize("bad, says", [
    ("recipe", "recipe.content_hash"),
    ("test", "split: 'test'"),
    ("garbage", "not what `echo-data evaluate --json` writes"),
    ("end", "episodes[0].skills[0].handover.end"),
])
def test_bad_runs_are_one_line_exit_2_and_write_nothing(learner_run: tuple[Path, Path, dict[str, Any]], tmp_path: Path, bad: str, says: str) -> None:
    recipe, _, doc = learner_run
    doc = json.loads(json.dumps(doc))
    if bad == "recipe":
        doc["recipe"]["content_hash"] = "0" * 64
    elif bad == "test":
        doc["split"] = "test"
    elif bad == "end":
        doc["episodes"][0]["skills"][0]["handover"]["end"] = [0.0, "x"]
    run = tmp_path / "run.json"
    run.write_text("{not json" if bad == "garbage" else json.dumps(doc))
    out = tmp_path / "ds"
    r = CliRunner().invoke(app, ["build", str(recipe), "--out", str(out), "--limit", "1", "--no-progress", "--handover-from", str(run)])
    _one_line_exit_2(r, says)
    assert str(run) in r.output and not out.exists()
