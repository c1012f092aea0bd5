"""Learners for every skill: wrist depth, the target kind, the GRU and its per-skill reset, on a
real quickstart build of three train episodes (object relocation, a sink, a door and an object:
all five skills). The paper-table driver's test: tests/test_table.py.

Training runs are two optimiser steps: they check the contract (inputs, loading, acting, the
recurrent state), not what the models learn.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12); fails on 3.11
from typer.testing import CliRunner

from echo_data.agents.loading import load_policy
from echo_data.cli import app
from echo_data.dataset.schema import STATE
from echo_data.dataset.torch import StepDataset
from echo_data.learn import runs
from echo_data.learn.algos import config_from_run
from echo_data.learn.data import chain_kinds
from echo_data.learn.features import DELTA_ACTION, DELTA_STATE, WRIST_DEPTH, FeatureSpec, from_action_form, prepare, to_action_form
from echo_data.learn.policy import BCPolicy
from echo_data.records import ACTION_DIM

ROOT = Path(__file__).resolve().parent.parent
QUICK = str(ROOT / "recipes" / "quickstart.yaml")
SKILLS = ("Navigate", "Pick", "Place", "OpenDoor", "CloseSink")
runner = CliRunner()


@pytest.fixture(scope="module")
def ds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("skills") / "qs"
    res = runner.invoke(app, ["build", QUICK, "--out", str(out), "--split", "train", "--limit", "3", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def trained(ds: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One GRU learner per skill, two steps each: head and wrist depth, state, target kind (+ audio and RGB for Navigate)."""
    root = tmp_path_factory.mktemp("runs")
    out = {}
    for skill in SKILLS:
        inputs = "audio,depth,rgb,state,kind" if skill == "Navigate" else "depth,wrist_depth,state,kind"
        args = ["train", "bc-rnn", str(ds), "--skill", skill, "--inputs", inputs, "--max-steps", "2", "--out", str(root / skill), "--no-progress"]
        res = runner.invoke(app, args)
        assert res.exit_code == 0, res.output
        out[skill] = root / skill
    return out


def _segment(ds: Path, skill: str) -> tuple[list[dict], str]:
    """The observations of the first segment of `skill` in the train split, and its target kind."""
    data = StepDataset(ds, "train", skill=skill)
    first = data[0]
    ep, k = int(first["episode_index"]), int(first["skill_index"])
    obs = []
    for i in range(len(data)):
        item = data[i]
        if int(item["episode_index"]) != ep or int(item["skill_index"]) != k:
            break
        obs.append({c: v for c, v in item.items() if c.startswith("observation.")})
    return obs, chain_kinds(ds, "train")[(ep, k)]


@pytest.mark.parametrize("skill", SKILLS)
def test_every_skill_learns_from_wrist_depth_and_its_target_kind(ds: Path, trained: dict[str, Path], skill: str) -> None:
    cfg = config_from_run(runs.read_json(trained[skill] / runs.CONFIG))
    spec = FeatureSpec.from_dict(cfg.features)
    obs, kind = _segment(ds, skill)
    assert cfg.ALGO == "bc_rnn" and cfg.SEQUENCE and kind in spec.kinds
    if skill != "Navigate":
        assert WRIST_DEPTH in spec.columns and spec.wrist_std > 0
    policy = BCPolicy.from_run(trained[skill])
    policy.reset({"skill": skill, "target_kind": kind})
    x = policy.inputs(obs[0])
    assert x["kind"][0, spec.kinds.index(kind)] == 1.0 and x["kind"].sum() == 1.0
    a = policy.act(obs[0])
    assert a.shape == (ACTION_DIM,) and a.dtype == np.float32 and np.isfinite(a).all()
    policy.reset({"skill": skill, "target_kind": "a kind never trained on"})
    assert float(policy.inputs(obs[0])["kind"].abs().sum()) == 0.0  # unknown kind: no one-hot, no error


def test_gru_state_resets_at_each_skill_and_acting_replays_training(ds: Path, trained: dict[str, Path]) -> None:
    obs, kind = _segment(ds, "Pick")
    policy = BCPolicy.from_run(trained["Pick"])
    policy.reset({"skill": "Pick", "target_kind": kind})
    stepped = np.stack([policy.act(o) for o in obs[:6]])
    assert policy.hidden is not None
    # Training runs the GRU over the whole segment from a zero state: acting step by step after
    # reset must give the same actions (same path, same history length).
    xs = [policy.inputs(o) for o in obs[:6]]
    with torch.no_grad():
        y, _ = policy.model({k: torch.cat([x[k] for x in xs])[None] for k in xs[0]})
    whole = y[0, :, 0].numpy() * policy.std + policy.mean
    for i, v in policy.config.held_entries:  # entries the demonstrations never vary are acted exactly (the torso's here)
        whole[:, int(i)] = v
    np.testing.assert_allclose(stepped, whole, rtol=1e-5, atol=1e-5)
    # Mid-segment the history matters; after reset (a new skill) the state is zero again.
    later = policy.act(obs[0])
    policy.reset({"skill": "Pick", "target_kind": kind})
    assert policy.hidden is None
    assert np.array_equal(policy.act(obs[0]), stepped[0]) and not np.array_equal(later, stepped[0])
    # evaluate's per-skill composition resets the learner at the start of its skill
    dispatch = load_policy([f"Pick={trained['Pick']}", "oracle"])
    member = dispatch.policy_for("Pick")
    member.reset({"skill": "Pick", "target_kind": kind})
    member.act(obs[0])
    dispatch.reset({"skill": "Pick", "target": "furby_0", "target_kind": kind, "skill_index": 1})
    assert member.hidden is None


def test_runs_from_before_the_new_inputs_still_load(ds: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Pick", "--inputs", "depth,state", "--max-steps", "1", "--out", str(tmp_path / "old"), "--no-progress"])
    assert res.exit_code == 0, res.output
    cfg = runs.read_json(tmp_path / "old" / runs.CONFIG)
    for key in ("algo", "action_column", "select_every", "select_episodes", "device", "encoder", "hidden"):  # a run from before the registry
        del cfg[key]
    cfg["recurrent"], cfg["seq_batch"] = False, 4
    for key in ("wrist_mean", "wrist_std", "kinds", "sides", "privileged"):
        del cfg["features"][key]
    (tmp_path / "old" / runs.CONFIG).write_text(json.dumps(cfg))
    obs, _ = _segment(ds, "Pick")
    policy = BCPolicy.from_run(tmp_path / "old")
    policy.reset({})
    assert not policy.recurrent and policy.act(obs[0]).shape == (ACTION_DIM,)


def test_kind_one_hot_follows_the_vocabulary() -> None:
    spec = FeatureSpec(inputs=("kind",), kinds=("alarm", "furby", "phone"))
    x = prepare({}, spec, kind=np.array([2, -1, 0]))["kind"]
    assert x.tolist() == [[0, 0, 1], [0, 0, 0], [1, 0, 0]]


def test_delta_actions_are_changes_from_the_measured_joints(ds: Path, tmp_path: Path) -> None:
    """--action-form delta: the network's target is (joint target - measured joint) for the torso
    and arm, normalised with the skill's own rows; acting adds the measured joints back, so the
    env gets the dataset's kind of action (absolute targets)."""
    out = tmp_path / "delta"
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Pick", "--inputs", "depth,wrist_depth,state,kind", "--action-form", "delta",
                              "--max-steps", "2", "--out", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    cfg = config_from_run(runs.read_json(out / runs.CONFIG))
    data = StepDataset(ds, "train", skill="Pick")
    rows = [data[i] for i in range(len(data))]
    actions = np.stack([np.asarray(r["action"], dtype=np.float32) for r in rows])[:, None]
    states = np.stack([np.asarray(r[STATE], dtype=np.float32) for r in rows])
    delta = to_action_form(actions, states, "delta")[:, 0]
    arm = list(DELTA_ACTION)
    assert np.allclose(delta[:, arm], actions[:, 0, arm] - states[:, list(DELTA_STATE)])
    assert np.array_equal(delta[:, :3], actions[:, 0, :3]) and np.array_equal(delta[:, 11], actions[:, 0, 11])  # base, gripper as stored
    # the scale is the skill's own: the arm's changes are far smaller than its targets' spread (a joint
    # whose change never varies in these rows, e.g. the torso at its target, keeps the unit scale)
    stds = np.array(cfg.action_std)[arm]
    moving = stds != 1.0
    assert moving.any() and stds[moving].max() < 0.5 * np.asarray(actions[:, 0, arm]).std(axis=0).max()
    policy = BCPolicy.from_run(out)
    obs, kind = _segment(ds, "Pick")
    policy.reset({"skill": "Pick", "target_kind": kind})
    with torch.no_grad():
        pred = policy.model(policy.inputs(obs[5]))[0, 0].numpy() * policy.std + policy.mean
    a = policy.act(obs[5])
    measured = np.asarray(obs[5][STATE], dtype=np.float32)
    np.testing.assert_allclose(a[arm], pred[arm] + measured[list(DELTA_STATE)], atol=1e-6)
    np.testing.assert_allclose(from_action_form(delta[7], states[7], "delta"), actions[7, 0], atol=1e-6)
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Pick", "--inputs", "depth", "--action-form", "delta", "--out", str(tmp_path / "r")])
    assert res.exit_code == 2 and "needs state" in res.output and not (tmp_path / "r").exists()


def test_gru_with_chunks_is_refused(ds: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["train", "bc-rnn", str(ds), "--skill", "Pick", "--inputs", "state", "--chunk", "2", "--out", str(tmp_path / "r")])
    assert res.exit_code == 2 and "--chunk" in res.output and not (tmp_path / "r").exists()
