"""Place's carry done by the drive learner (docs/handover.md#places-carry): the split of a Place
segment at its first row inside Place's stance (`learn.carry`), the learners' options
(`--from-stance`, `--with-carries`), and the runtime that carries with the drive policy before a
Place run trained from the stance (`agents.runtime.carry_call`).

On a real build of one object-relocation episode (Navigate, Pick, Place; audio only, no pictures
stored) and two-step trainings: they check the contract, not what the models learn."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pytest
from support.torch_module import torch  # noqa: F401  (skips the module where the test extra leaves torch out)
from typer.testing import CliRunner

from echo_data.agents.builtin import OraclePlanner, OracleSkills
from echo_data.agents.compose import SkillDispatch
from echo_data.cli import app
from echo_data.episode import SkillCall
from echo_data.skill_table import STANCE, approach_skill

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


@pytest.fixture(scope="module")
def recipe(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Quickstart with tiny cameras and only the spectrogram stored (train episode 0 moves a furby to a table)."""
    path = tmp_path_factory.mktemp("carry_recipe") / "carry.yaml"
    path.write_text(f"extends: {ROOT / 'recipes' / 'quickstart.yaml'}\nname: carry\n"
                    "robot:\n  head_camera: {width: 16, height: 16}\n  wrist_camera: {width: 16, height: 16, rgb: false}\n"
                    "outputs:\n  observations: [spectrogram]\n  planner_export: false\n")
    return path


@pytest.fixture(scope="module")
def ds(recipe: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("carry") / "ds"
    res = runner.invoke(app, ["build", str(recipe), "--out", str(out), "--split", "train", "--limit", "1", "--workers", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


def _place_segment(ds: Path) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float], str]:
    """(the Place segment's split rows, their base poses, its receptacle's interaction pose, the target)."""
    from echo_data.dataset.reader import StepReader, dataset_recipe, episode_records
    from echo_data.dataset.schema import STATE
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.scene.nav import interaction_pose

    reader = StepReader(ds, "train")
    idx = reader.index
    rows = np.flatnonzero(idx.skill == "Place")
    ep = episode_records(ds)[0]
    k = int(idx.skill_index[rows[0]])
    target = ep["chain"][k]["target"]
    plan = generate_floorplan_from_seed(dataset_recipe(ds)[0], int(ep["scene_seed"]))
    return rows, reader.read([STATE], rows)[STATE][:, :3], interaction_pose(plan, target), target


def test_a_place_segment_splits_at_its_first_row_inside_places_stance(ds: Path) -> None:
    from echo_data.dataset.reader import StepReader
    from echo_data.learn.carry import CARRY, OUTSIDE, PLACING, carry_parts
    from echo_data.skills.navigate import GOAL_TOL, YAW_TOL

    rows, base, pose, _ = _place_segment(ds)
    # the regenerated interaction pose is where the Place expert's drive stopped (within its tolerances)
    assert math.hypot(*(base[-1, :2] - pose[:2])) <= GOAL_TOL and abs(math.remainder(base[-1, 2] - pose[2], 2 * math.pi)) <= YAW_TOL
    dist = np.hypot(base[:, 0] - pose[0], base[:, 1] - pose[1])
    heading = np.abs(np.remainder(base[:, 2] - pose[2] + np.pi, 2 * np.pi) - np.pi)
    first = int(np.argmax((dist <= STANCE.distance) & (heading <= STANCE.heading)))
    assert 0 < first < len(rows) - 1  # a carry and a placing
    part = carry_parts(StepReader(ds, "train"))
    assert (part[rows[:first]] == CARRY).all() and (part[rows[first:]] == PLACING).all()
    assert (np.delete(part, rows) == OUTSIDE).all()  # Navigate's and Pick's rows are no carry


def test_a_dataset_built_before_the_hand_over_record_splits_on_the_regenerated_pose(ds: Path, tmp_path: Path,
                                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Without `outcomes[k].handover` (a dataset built before it was recorded) the receptacle's
    interaction pose comes from the regenerated apartment, and the split falls on the same row."""
    import echo_data.learn.carry as carry
    from echo_data.dataset.reader import StepReader

    recorded = carry.carry_parts(StepReader(ds, "train"))
    real = carry.episodes_table

    def without_record(root: Path, columns: list[str]) -> Any:
        t = real(root, columns)
        old = [[{k: v for k, v in o.items() if k != "handover"} for o in outs] for outs in t.column("outcomes").to_pylist()]
        return t.set_column(t.column_names.index("outcomes"), "outcomes", pa.array(old))

    asked: list[str] = []
    regenerate = carry._Regenerated.pose

    def counted(self: Any, seed: int, target: str) -> Any:
        asked.append(target)
        return regenerate(self, seed, target)

    monkeypatch.setattr(carry, "episodes_table", without_record)
    monkeypatch.setattr(carry._Regenerated, "pose", counted)
    assert np.array_equal(carry.carry_parts(StepReader(ds, "train")), recorded)
    assert asked  # the poses were regenerated, not read


def test_place_from_stance_trains_on_the_stance_rows_only(ds: Path, tmp_path: Path) -> None:
    from echo_data.dataset.reader import StepReader
    from echo_data.learn import runs
    from echo_data.learn.carry import PLACING, carry_parts

    rows, _, _, _ = _place_segment(ds)
    stance = int((carry_parts(StepReader(ds, "train"))[rows] == PLACING).sum())
    counts = {}
    for flag in ("--no-from-stance", "--from-stance"):
        out = tmp_path / flag
        res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Place", "--inputs", "state", flag, "--max-steps", "1", "--out", str(out), "--no-progress"])
        assert res.exit_code == 0, res.output
        counts[flag] = json.loads(res.output)["rows"]["train"]
        assert runs.read_json(out / runs.CONFIG)["from_stance"] is (flag == "--from-stance")
    assert counts["--from-stance"] == stance < counts["--no-from-stance"] == len(rows)


def test_the_options_belong_to_their_skills(ds: Path, tmp_path: Path) -> None:
    for skill, flag in (("Pick", "--from-stance"), ("Navigate", "--from-stance"), ("Place", "--with-carries")):
        res = runner.invoke(app, ["train", "bc", str(ds), "--skill", skill, "--inputs", "state", flag, "--out", str(tmp_path / skill), "--no-progress"])
        assert res.exit_code == 2 and flag in res.output, res.output
        assert not (tmp_path / skill).exists()


def test_a_drive_learner_with_carries_learns_them_as_drives_to_the_receptacle(ds: Path) -> None:
    from echo_data.dataset.reader import StepReader
    from echo_data.learn.carry import CARRY, carry_parts
    from echo_data.learn.data import chain_kinds, load_skill_rows
    from echo_data.learn.features import feature_spec

    reader = StepReader(ds, "train")
    idx = reader.index
    carry = np.flatnonzero(carry_parts(reader) == CARRY)
    nav = np.flatnonzero(idx.skill == "Navigate")
    receptacle = chain_kinds(ds, "train")[(int(idx.episode[carry[0]]), int(idx.skill_index[carry[0]]))]
    spec = feature_spec(ds, ("state", "kind"), kinds=("furby", receptacle))
    rows = load_skill_rows(ds, "train", "Navigate", spec, chunk=2, stop=True, with_carries=True)
    assert len(rows) == len(nav) + len(carry)
    at = np.isin(np.sort(np.concatenate([nav, carry])), carry)  # the carry's rows among the loaded ones (split order)
    assert len(np.unique(rows.segments[at])) == 1 and not np.isin(rows.segments[at], rows.segments[~at]).any()  # a segment of its own
    stop = rows.actions[..., -1]
    assert stop[at][-1, 0] == 1 and stop[at][:-1, 0].sum() == 0  # its STOP on its last row, never on a placing row
    assert rows.action_pad[at][-1, 1]  # its window ends with it
    kinds = rows.inputs["kind"][at].argmax(-1).numpy()
    assert (kinds == 1).all()  # the receptacle's kind


def _train(ds: Path, out: Path, *args: str) -> Path:
    res = runner.invoke(app, ["train", *args, str(ds), "--max-steps", "1", "--out", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


def test_carry_call_is_the_drive_before_a_place_trained_from_its_stance(ds: Path, tmp_path: Path) -> None:
    from echo_data.agents.runtime import carry_call
    from echo_data.learn.policy import SkillPolicy

    place = SkillPolicy.from_run(_train(ds, tmp_path / "place", "bc", "--skill", "Place", "--inputs", "state", "--from-stance"))
    call, pick = SkillCall("Place", "furniture:1", 0), SkillCall("Pick", "furby_0", 0)
    assert carry_call(SkillDispatch({"Place": place}, OracleSkills()), call) == SkillCall(approach_skill().name, "furniture:1", 0)
    assert carry_call(SkillDispatch({"Pick": place}, OracleSkills()), call) is None  # the expert Place carries itself
    assert carry_call(SkillDispatch({"Place": place}, OracleSkills()), pick) is None
    assert carry_call(place, call) is None  # no drive policy to carry with


class _Steps:
    """`run_episode`'s hook: the call each step of chain entry `k` acts in and the base's offset
    from the entry's interaction pose before it; ends the episode `after` steps into the skill itself."""

    def __init__(self, k: int, after: int) -> None:
        self.k, self.after, self.seen = k, after, []

    def __call__(self, env: Any, obs: dict, a: np.ndarray, k: int, call: SkillCall, flags: tuple) -> None:
        from echo_data.agents.runtime import StopEpisode
        from echo_data.skills.success import stance_offset

        if k != self.k:
            return
        if sum(c.skill == "Place" for c, _ in self.seen) >= self.after:
            raise StopEpisode
        self.seen.append((call, stance_offset(env.world, call.target)))


@pytest.fixture(scope="module")
def env(recipe: Path) -> Any:
    from echo_data.envs.env import EchoDataEnv

    e = EchoDataEnv(str(recipe), split="train", images=False, audio=False)
    yield e
    e.close()


def test_the_drive_carries_to_places_stance_and_place_starts_there(ds: Path, env: Any, tmp_path: Path) -> None:
    """The expert's drive as the drive policy (a two-step learner would not arrive): the same path
    as a learned one's, through the composition's Navigate member."""
    from echo_data.agents.runtime import run_episode
    from echo_data.learn.policy import SkillPolicy

    place = SkillPolicy.from_run(_train(ds, tmp_path / "place", "bc", "--skill", "Place", "--inputs", "state", "--from-stance"))
    obs, info = env.reset(options={"split": "train", "index": 0})
    k = next(i for i, c in enumerate(env.episode.chain) if c.skill == "Place")
    hook = _Steps(k, after=2)
    run = run_episode(env, obs, info, OraclePlanner(), SkillDispatch({"Place": place}, OracleSkills()), on_step=hook)
    assert run.plan_correct and len(run.true_chain) == 3  # the chain is still one Place entry
    carry = [off for c, off in hook.seen if c.skill == approach_skill().name]
    placing = [off for c, off in hook.seen if c.skill == "Place"]
    assert len(carry) > 20 and len(placing) == 2 and [c.skill for c, _ in hook.seen] == ["Navigate"] * len(carry) + ["Place"] * 2
    outside = carry[-1][0] > STANCE.distance or carry[-1][1] > STANCE.heading
    assert outside and placing[0][0] <= STANCE.distance and placing[0][1] <= STANCE.heading  # it ended at the hand-over, Place starts there
    (rec,) = run.carries
    assert rec.skill_index == k and rec.handed_over and rec.success
    assert rec.goal_distance == pytest.approx(placing[0][0], abs=1e-6) and rec.heading_error == pytest.approx(placing[0][1], abs=1e-6)


class _ExpertFirst:
    """The Navigate member for the plumbing check: the expert for the chain's own Navigate (so the
    episode reaches its Place), the learned drive `learned` for the carry."""

    privileged = True

    def __init__(self, learned: Any) -> None:
        self.learned, self.expert, self.active = learned, OracleSkills(), None
        self.infos: list[dict] = []
        self.observed: list[dict] = []
        self.observations = learned.observations  # its goal observation (GOAL_POSE) among them

    @property
    def ends_itself(self) -> bool:
        return self.active is self.expert

    def reset(self, info: dict) -> None:
        self.active = self.expert if info["skill_index"] == 0 else self.learned
        self.infos.append(info)
        self.active.reset(info if self.active is self.expert else {k: v for k, v in info.items() if k not in ("world", "call", "spec_object")})

    def act(self, obs: dict) -> Any:
        if self.active is self.learned:
            self.observed.append(obs)
        return self.active.act(obs)


def test_a_learned_drive_carries_with_the_receptacles_kind_and_goal(ds: Path, env: Any, tmp_path: Path) -> None:
    from echo_data.agents.runtime import StopEpisode, run_episode
    from echo_data.dataset.reader import episode_records
    from echo_data.learn.policy import SkillPolicy
    from echo_data.records import GOAL_POSE
    from echo_data.skills.navigate import goal_pose

    nav_run = _train(ds, tmp_path / "nav", "bc-rnn", "--skill", "Navigate", "--inputs", "state,kind,target", "--with-carries")
    nav = SkillPolicy.from_run(nav_run)
    receptacle = next(c["target_kind"] for c in episode_records(ds)[0]["chain"] if c["skill"] == "Place")
    assert receptacle in nav.spec.kinds  # the carries' kinds join the drive's vocabulary
    place = SkillPolicy.from_run(_train(ds, tmp_path / "place", "bc", "--skill", "Place", "--inputs", "state", "--from-stance"))
    member = _ExpertFirst(nav)
    obs, info = env.reset(options={"split": "train", "index": 0})
    k = next(i for i, c in enumerate(env.episode.chain) if c.skill == "Place")

    def stop_early(e: Any, o: dict, a: np.ndarray, kk: int, call: SkillCall, flags: tuple) -> None:
        if kk == k and len(member.observed) >= 4:  # a few learned steps are the plumbing; a two-step learner would not arrive
            raise StopEpisode

    run = run_episode(env, obs, info, OraclePlanner(), SkillDispatch({"Navigate": member, "Place": place}, OracleSkills()), on_step=stop_early)
    carry_info = member.infos[-1]
    assert carry_info["skill"] == approach_skill().name and carry_info["skill_index"] == k and carry_info["target_kind"] == receptacle
    assert nav._kind == nav.spec.kinds.index(receptacle)
    want = goal_pose(env.world, env.episode.chain[k].target)
    assert all(np.allclose(o[GOAL_POSE], want, atol=1e-5) for o in member.observed)
    assert run.truncated_at is not None and not run.carries  # cut during the carry: no record


def test_dagger_leaves_the_carry_to_the_drive() -> None:
    """DAgger's labeller for a Place trained from the stance sees only Place's own states: the
    carry before them (the drive call at the same chain entry) is not labelled."""
    from echo_data.learn.dagger import _Labels

    class _Place:
        skill = "Place"

    hook = _Labels(_Place(), "action", None)
    hook.start(2)
    hook(None, {}, np.zeros(12), 2, SkillCall(approach_skill().name, "furniture:1", 0), (True, True, False))
    assert hook.label is None and not hook.labels
