"""The skill learners of the registry (bc, bc-rnn, act, diffusion), the dataset reader's windows,
the training-input checks and the binary gripper head.

Training runs a few optimiser steps on the shared synthetic dataset (real shapes, seconds to
build); each run then loads through evaluate's loader and drives the robot closed loop for a few
steps of a real quickstart episode (no rendering: the learners read the state).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12); fails on 3.11
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.reader import StepReader
from echo_data.dataset.schema import ACTION, STATE
from echo_data.learn import runs
from echo_data.learn.algos import ALGORITHMS, algorithm, config_from_run
from echo_data.learn.algos.base import ACTION_COLUMNS, action_loss
from echo_data.learn.features import BC_INPUTS, feature_spec, parse_inputs
from echo_data.learn.policy import SkillPolicy
from echo_data.records import ACTION_DIM, BASE_FRAME_STATE, EE_ACTION_NAMES, PRIVILEGED_PREFIX, STATE_NAMES

ROOT = Path(__file__).resolve().parent.parent
QUICK = str(ROOT / "recipes" / "quickstart.yaml")
runner = CliRunner()
SMALL = {"bc": [], "bc_rnn": [], "act": ["--chunk", "4", "--d-model", "32", "--heads", "2", "--layers", "1"],
         "diffusion": ["--horizon", "8", "--execute", "4", "--width", "16", "--train-steps", "20", "--sample-steps", "4"]}


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 3, "test": 1})


def _train(ds: Path, out: Path, algo: str, *extra: str, code: int = 0) -> dict:
    args = ["train", algo.replace("_", "-"), str(ds), "--skill", "Navigate", "--inputs", "state", "--out", str(out), "--no-progress", *extra]
    res = runner.invoke(app, args)
    assert res.exit_code == code, res.output
    return json.loads(res.stdout) if code == 0 else {"output": res.output}


@pytest.fixture(scope="module")
def trained(ds: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("algos")
    for name in ALGORITHMS:
        _train(ds, root / name, name, "--max-steps", "2", *SMALL[name])
    return {name: root / name for name in ALGORITHMS}


def test_every_algorithm_names_itself_and_drives_the_robot_closed_loop(trained: dict[str, Path]) -> None:
    from echo_data.agents.builtin import OraclePlanner
    from echo_data.agents.loading import load_policy
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv

    env = EchoDataEnv(QUICK, split="test", images=False, audio=False)
    try:
        spec = env.sample_spec("test", 0)
        for name, run in trained.items():
            assert runs.read_json(run / runs.CONFIG)["algo"] == name and runs.read_json(run / runs.POLICY)["algo"] == name
            policy = load_policy(str(run))  # what `evaluate --policy RUN_DIR` constructs
            assert isinstance(policy, SkillPolicy) and policy.algo == name and policy.observations == (STATE,)
            obs, info = env.reset(options={"spec": spec})
            result = run_episode(env, obs, info, OraclePlanner(), policy, max_steps=3, skills=1)
            assert result.steps == 3, (name, result)
    finally:
        env.close()


def test_chunked_policies_queue_or_ensemble_their_predictions(ds: Path, trained: dict[str, Path]) -> None:
    obs = _observations(ds)
    # Diffusion, horizon 8, execute 4: one prediction per four steps, and reset empties the queue.
    policy = SkillPolicy.from_run(trained["diffusion"])
    calls = _count(policy)
    policy.reset({})
    first = [policy.act(o) for o in obs[:5]]
    assert len(calls) == 2 and all(a.shape == (ACTION_DIM,) and np.isfinite(a).all() for a in first)
    policy.reset({})
    assert np.array_equal(policy.act(obs[0]), first[0])  # sampling reseeded: the same first action
    # ACT with temporal ensembling: a prediction every step; the action at step 2 is the weighted
    # mean of what the chunks of steps 0, 1 and 2 said for step 2 (w_i = exp(-m i), oldest first).
    policy = SkillPolicy.from_run(trained["act"])
    chunks: list[np.ndarray] = []
    predict = policy._predict
    policy._predict = lambda o: chunks.append(predict(o)) or chunks[-1]  # type: ignore[method-assign]
    policy.reset({})
    acts = [policy.act(o) for o in obs[:3]]
    m = policy.ensemble
    assert m is not None and len(chunks) == 3
    w = np.exp(-m * np.arange(3))
    want = (w[:, None] * np.stack([chunks[0][2], chunks[1][1], chunks[2][0]])).sum(axis=0) / w.sum()
    np.testing.assert_allclose(acts[2], want, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(acts[0], chunks[0][0], rtol=1e-6)


def test_resumed_runs_equal_uninterrupted_ones_for_act_and_diffusion(ds: Path, tmp_path: Path) -> None:
    for name in ("act", "diffusion"):
        straight, split = tmp_path / f"{name}-a", tmp_path / f"{name}-b"
        _train(ds, straight, name, "--max-steps", "4", *SMALL[name])
        _train(ds, split, name, "--max-steps", "2", *SMALL[name])
        _train(ds, split, name, "--max-steps", "4", "--resume", *SMALL[name])
        a, b = (runs.load_torch(f / runs.CHECKPOINT)["model"] for f in (straight, split))
        assert all(torch.equal(a[k], b[k]) for k in a), name


def test_reader_windows_equal_the_rows_they_index(ds: Path) -> None:
    reader = StepReader(ds, "train")
    idx = reader.index
    rows = np.arange(len(idx))
    deltas = (-2, -1, 0, 1, 3)
    values, pads = reader.windows(rows, {ACTION: deltas, STATE: (-1, 0)})
    every = reader.read([ACTION, STATE])
    first, last = idx.bounds("segment")
    for i in rows:
        for j, d in enumerate(deltas):
            want = int(np.clip(i + d, first[i], last[i]))
            assert np.array_equal(values[ACTION][i, j], every[ACTION][want])
            assert pads[ACTION][i, j] == (not first[i] <= i + d <= last[i])
            assert idx.segment[want] == idx.segment[i]
        assert np.array_equal(values[STATE][i, 1], every[STATE][i])
    shuffled = np.array(rows[::-1])
    assert np.array_equal(reader.read([ACTION], shuffled)[ACTION], every[ACTION][shuffled])


def test_default_inputs_hold_no_world_pose_and_no_privileged_column(ds: Path) -> None:
    for algo in ALGORITHMS.values():
        default = algo.config.default_of(next(f for f in algo.config.options() if f.name == "inputs"))
        assert not any(n.startswith(PRIVILEGED_PREFIX) for n in default)
    spec = feature_spec(ds, ("state",))
    assert set(spec.state_names) <= set(BASE_FRAME_STATE) and not {"base_x", "base_y", "base_yaw"} & set(spec.state_names)
    assert parse_inputs(f"state,{PRIVILEGED_PREFIX}target_pose", BC_INPUTS) == ("state", f"{PRIVILEGED_PREFIX}target_pose")
    res = runner.invoke(app, ["train", "act", str(ds), "--skill", "Pick", "--inputs", f"state,{PRIVILEGED_PREFIX}nothing", "--out", str(ds.parent / "r")])
    assert res.exit_code == 2 and f"--inputs {PRIVILEGED_PREFIX}nothing: no such column" in res.output
    assert "base_x" in STATE_NAMES  # (the raw state still holds it: only the default input leaves it out)


def test_binary_gripper_is_classified() -> None:
    names, binary = ACTION_COLUMNS["action.ee"]
    assert names[-1] == "gripper_close" and binary == ("gripper_close",)
    cfg = algorithm("bc").config(skill="Pick", action_column="action.ee")
    assert cfg.binary == (len(names) - 1,) and algorithm("bc").config(skill="Pick").binary == ()
    pred = torch.zeros(2, 1, len(names))
    pred[0, 0, -1], pred[1, 0, -1] = 3.0, -3.0
    target = torch.zeros(2, 1, len(names))
    target[0, 0, -1] = 1.0
    got = action_loss(pred, target, torch.ones(2, 1), cfg.binary)
    bce = torch.nn.functional.binary_cross_entropy_with_logits(torch.tensor([3.0, -3.0]), torch.tensor([1.0, 0.0]), reduction="sum") / 2
    assert float(got) == pytest.approx(float(bce) / len(names), rel=1e-6)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--lr", "inf"], "--lr inf: must be a finite number > 0"),
        (["--lr", "0"], "--lr 0.0: must be a finite number > 0"),
        (["--seed", str(2**64)], "--seed 18446744073709551616: must be within [0, 2**64)"),
        (["--inputs", "depth", "--image-size", "0", "--encoder", "spatial_softmax", "--shift", "16"], "--shift 16: must be below the image side (16 px)"),
        (["--device", "tpu"], "--device 'tpu': choose from cpu, cuda, auto"),
        # a closed-loop choice whose episodes act in the other form: refused before 10 epochs are spent
        (["--select-every", "1", "--action-column", "action.ee"], "acts in robot.action_space joint, whose policies clone action "),
    ],
)
def test_training_inputs_are_checked_before_anything_is_written(ds: Path, tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "run"
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Navigate", "--out", str(out), "--no-progress", *args])
    assert res.exit_code == 2 and message in res.output and len(res.output.strip().splitlines()) == 1, res.output
    assert not (out / runs.BEST).exists() and not (out / runs.CHECKPOINT).exists()


def test_a_diverging_run_names_the_step_and_saves_no_weights(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "nan"
    got = _train(ds, out, "bc", "--lr", "1e30", "--max-steps", "4", code=2)
    assert "diverged at optimiser step" in got["output"] or "is not finite at optimiser step" in got["output"], got
    for name in (runs.BEST, runs.CHECKPOINT):
        if (out / name).exists():
            assert all(torch.isfinite(v).all() for v in runs.load_torch(out / name)["model"].values())


def test_config_file_and_overrides(ds: Path, tmp_path: Path) -> None:
    conf = tmp_path / "act.yaml"
    conf.write_text("chunk: 3\nd-model: 16\nheads: 2\nlayers: 1\nmax_steps: 1\nensemble: -1\nexecute: 2\n")
    _train(ds, tmp_path / "run", "act", "--config", str(conf), "--execute", "3")
    cfg = config_from_run(runs.read_json(tmp_path / "run" / runs.CONFIG))
    assert (cfg.chunk, cfg.d_model, cfg.execute, cfg.ensemble_weight()) == (3, 16, 3, None)
    conf.write_text("chunk: 3\nflavour: mint\n")
    got = _train(ds, tmp_path / "bad", "act", "--config", str(conf), code=2)
    assert "unknown option 'flavour'" in got["output"]


def _observations(ds: Path) -> list[dict]:
    reader = StepReader(ds, "train")
    rows = np.flatnonzero(reader.index.skill == "Navigate")[:5]
    return [{STATE: s} for s in reader.read([STATE], rows)[STATE]]


def _count(policy: SkillPolicy) -> list[int]:
    calls: list[int] = []
    predict = policy.model.predict
    policy.model.predict = lambda *a: calls.append(1) or predict(*a)  # type: ignore[method-assign]
    return calls


def test_every_algorithm_clones_the_end_effector_form_with_a_binary_gripper(ds: Path, tmp_path: Path) -> None:
    """The dataset's `action.ee` column (11 floats, `gripper_close` 0/1): every algorithm trains on
    it and acts in its form."""
    import pyarrow.parquet as pq

    from echo_data.learn.fit import train_skill

    copy = ds  # the build records the end-effector form of every step (docs/action_spaces.md)
    table = pq.read_table(sorted((ds / "data").glob("train-*.parquet"))[0], columns=["action.ee"])
    grip = np.asarray(table.column("action.ee").to_pylist(), np.float32)[:, -1]
    assert set(np.unique(grip)) <= {0.0, 1.0}
    obs = _observations(copy)
    for name in ALGORITHMS:
        cfg = algorithm(name).config(dataset=str(copy), skill="Navigate", inputs=("state",), action_column="action.ee", max_steps=2,
                                     **{k.lstrip("-").replace("-", "_"): float(v) if "." in v else int(v) for k, v in zip(SMALL[name][::2], SMALL[name][1::2], strict=True)})
        train_skill(cfg, tmp_path / name, progress=False)
        policy = SkillPolicy.from_run(tmp_path / name)
        assert policy.config.binary == (len(EE_ACTION_NAMES) - 1,) and policy.std[-1] == 1.0 and policy.mean[-1] == 0.0
        policy.reset({})
        for o in obs[:3]:
            a = policy.act(o)
            assert a.shape == (len(EE_ACTION_NAMES),) and a[-1] in (0.0, 1.0) and np.isfinite(a).all(), name


def test_spatial_softmax_finds_the_peak_and_trains_at_stored_resolution(ds: Path, tmp_path: Path) -> None:
    from echo_data.learn.models import SpatialSoftmaxEncoder

    enc = SpatialSoftmaxEncoder(1, (16, 24), keypoints=2)  # feature maps of 8 x 12 after the stride-2 convolution
    f = torch.zeros(1, 2, 8, 12)
    f[0, 0, 0, 11] = f[0, 1, 7, 0] = 60.0  # top right, bottom left
    np.testing.assert_allclose(enc.keypoints(f)[0].numpy(), [[1.0, -1.0], [-1.0, 1.0]], atol=1e-4)
    run = tmp_path / "ss"
    _train(ds, run, "act", "--inputs", "depth,wrist_depth,state", "--image-size", "0", "--encoder", "spatial_softmax", "--shift", "2", "--max-steps", "1", *SMALL["act"])
    policy = SkillPolicy.from_run(run)
    assert policy.spec.side("depth") == (16, 24) and policy.spec.side("wrist_depth") == (16, 16)
    reader = StepReader(ds, "train")
    row = reader.read(list(policy.observations), np.array([0]))
    policy.reset({})
    assert policy.act({k: v[0] for k, v in row.items()}).shape == (ACTION_DIM,)


def test_planner_seed_is_bounded_too(ds: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["train", "planner", str(ds), "--seed", "-1", "--out", str(tmp_path / "p")])
    assert res.exit_code == 2 and "--seed -1: must be within [0, 2**64)" in res.output and not (tmp_path / "p").exists(), res.output


def test_diffusion_reads_the_last_two_observations_as_it_trained(ds: Path, trained: dict[str, Path]) -> None:
    """obs_steps 2: training conditions row t on rows (t-1, t) clamped to the segment's first row;
    acting on the observations (t-1, t), the first one repeated right after a reset."""
    from echo_data.learn.data import SkillRows
    from echo_data.learn.fit import Units

    seg = np.array([0, 0, 0, 1, 1])
    rows = SkillRows({}, np.zeros((5, 1, 12)), np.zeros((5, 1), bool), np.zeros((5, 3)), np.zeros(5), seg)
    assert Units(rows, False, "cpu", history=2).history.tolist() == [[0, 0], [0, 1], [1, 2], [3, 3], [3, 4]]
    obs = _observations(ds)
    policy = SkillPolicy.from_run(trained["diffusion"])
    assert policy.config.history() == 2
    policy.reset({})
    acts = [policy.act(o) for o in obs[:5]]  # predicts at steps 0 and 4 (execute 4)
    x = [policy.inputs(o) for o in obs[:5]]
    gen = torch.Generator().manual_seed(policy.config.seed)
    with torch.no_grad():
        first, _ = policy.model.predict({k: torch.stack([x[0][k], x[0][k]], dim=1) for k in x[0]}, None, gen)
        later, _ = policy.model.predict({k: torch.stack([x[3][k], x[4][k]], dim=1) for k in x[0]}, None, gen)
    np.testing.assert_allclose(acts[0], first[0, 0].numpy() * policy.std + policy.mean, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(acts[4], later[0, 0].numpy() * policy.std + policy.mean, rtol=1e-5, atol=1e-6)


def test_a_binary_entry_switches_when_the_chunk_switches_it_within_switch_ahead(ds: Path, tmp_path: Path) -> None:
    """`--switch-ahead h`: the gripper command follows the newest chunk's look-ahead (see
    `echo_data.learn.policy.switched`), it changes as soon as one of the next h predicted steps
    changes it, and only from what was commanded last; h = 1 is the plain threshold."""
    from echo_data.learn.fit import train_skill
    from echo_data.learn.policy import switched

    open_, close = np.array([0.0], np.float32), np.array([1.0], np.float32)
    ahead = np.array([[0.1], [0.2], [0.9], [0.8]], np.float32)  # the expert closes two steps from now
    assert switched(ahead, None)[0] == 0.0  # a segment's start: this step's prediction
    assert switched(ahead, open_)[0] == 1.0 and switched(ahead[:2], open_)[0] == 0.0
    assert switched(ahead[2:], close)[0] == 1.0  # closed stays closed while every step says so ...
    assert switched(np.array([[0.9], [0.3]], np.float32), close)[0] == 0.0  # ... and opens on a predicted release

    with pytest.raises(Exception, match="--switch-ahead 5"):  # at most the chunk
        algorithm("bc").config(skill="Navigate", chunk=4, switch_ahead=5).check()
    cfg = algorithm("bc").config(dataset=str(ds), skill="Navigate", inputs=("state",), action_column="action.ee", max_steps=2, chunk=4, switch_ahead=3)
    train_skill(cfg, tmp_path / "bc", progress=False)
    policy = SkillPolicy.from_run(tmp_path / "bc")
    assert policy.switch_ahead == 3
    chunks: list[np.ndarray] = []
    grip = len(EE_ACTION_NAMES) - 1
    for step, value in enumerate((0.2, 0.2, 0.7)):  # the chunk predicts the close at its third step
        c = np.zeros((4, len(EE_ACTION_NAMES)), np.float32)
        c[:, grip] = 0.1
        c[2:, grip] = value if step == 0 else 0.1
        chunks.append(c)
    feed = iter(chunks)
    policy._predict = lambda o: next(feed)  # type: ignore[method-assign]
    policy.reset({})
    obs = _observations(ds)
    assert policy.act(obs[0])[-1] == 0.0  # 0.2 three steps ahead: no switch predicted
    policy.reset({})
    chunks[0][2:, grip] = 0.7
    feed = iter(chunks)
    assert policy.act(obs[0])[-1] == 0.0  # the segment's first step: its own prediction (0.1)
    assert policy.act(obs[1])[-1] == 0.0  # the next chunk says open throughout
    policy.reset({})
    policy._last_binary = open_
    feed = iter([chunks[0]])
    policy._rest = None
    assert policy.act(obs[0])[-1] == 1.0  # commanded open, a close predicted within 3 steps: close now


def test_a_stop_run_learns_each_segments_last_row_and_ends_its_skill_there(ds: Path, tmp_path: Path) -> None:
    """`--stop`: the target carries the dataset's `skill_stop` (1 exactly on a segment's last row)
    as one more binary entry, weighted to balance its one last row against the others; the policy
    says STOP (None) when it predicts it and gives the environment the action alone otherwise."""
    from echo_data.dataset.schema import SKILL_STOP
    from echo_data.learn.data import load_skill_rows
    from echo_data.learn.features import FeatureSpec
    from echo_data.learn.fit import train_skill

    with pytest.raises(Exception, match="--stop"):
        algorithm("bc").config(skill="Navigate", stop=True, action_form="delta").check()
    cfg = algorithm("bc_rnn").config(dataset=str(ds), skill="Navigate", inputs=("state",), action_column="action.ee", max_steps=2, stop=True)
    train_skill(cfg, tmp_path / "stop", progress=False)
    policy = SkillPolicy.from_run(tmp_path / "stop")
    reader = StepReader(ds, "train")
    nav = np.flatnonzero(reader.index.skill == "Navigate")
    _, last = reader.index.bounds("segment")
    is_last = nav == last[nav]
    assert np.array_equal(reader.read([SKILL_STOP], nav)[SKILL_STOP].astype(bool), is_last)
    rows = load_skill_rows(ds, "train", "Navigate", FeatureSpec.from_dict(policy.config.features), action_column="action.ee", stop=True)
    assert rows.actions.shape[-1] == len(EE_ACTION_NAMES) + 1 and np.array_equal(rows.actions[:, 0, -1], is_last.astype(np.float32))
    kept = ~np.isin(rows.episodes, policy.config.val_episodes)
    assert policy.config.stop_weight == pytest.approx((kept.sum() - is_last[kept].sum()) / is_last[kept].sum())  # (the synthetic segments are short)
    assert policy.ends_itself and policy.config.binary == (len(EE_ACTION_NAMES) - 1, len(EE_ACTION_NAMES))
    assert algorithm("bc_rnn").config(action_column="action.ee").binary_weights() == (1.0,) and policy.config.binary_weights() == (1.0, policy.config.stop_weight)
    head = policy.model.head[-1] if isinstance(policy.model.head, torch.nn.Sequential) else policy.model.head
    obs = _observations(ds)
    assert policy.config.stop_threshold == 0.5  # chosen on validation only with --select-every
    for bias, threshold, stops in ((-50.0, 0.5, False), (50.0, 0.5, True), (2.0, 0.5, True), (2.0, 0.95, False)):  # logit 2: p 0.88
        with torch.no_grad():
            head.weight[-1] = 0.0
            head.bias[-1] = bias
        policy.config.stop_threshold = threshold
        policy.reset({})
        a = policy.act(obs[0])
        assert (a is None) == stops, (bias, threshold)
        if a is not None:
            assert a.shape == (len(EE_ACTION_NAMES),) and np.isfinite(a).all()


def test_a_stop_runs_threshold_is_the_best_on_validation_the_latest_of_ties(monkeypatch: pytest.MonkeyPatch) -> None:
    """`select.closed_loop_scores`: every threshold of STOP_THRESHOLDS scored closed loop; the best
    success wins, a tie goes to the higher threshold (the later stop); a run without --stop is
    scored once."""
    from echo_data.learn import select

    scored: list[float] = []
    for table, want in (({0.5: 0.2, 0.95: 0.6, 0.995: 0.4}, (0.6, 0.95)), ({0.5: 0.3, 0.95: 0.3, 0.995: 0.1}, (0.3, 0.95)),
                        ({0.5: float("nan"), 0.95: 0.0, 0.995: 0.0}, (0.0, 0.995))):
        def fake(cfg, model, out, table=table):  # the closed-loop score at the threshold the policy would act with
            scored.append(cfg.stop_threshold)
            return table[cfg.stop_threshold]
        monkeypatch.setattr(select, "closed_loop_success", fake)
        cfg = algorithm("bc_rnn").config(skill="Navigate", action_column="action.ee", stop=True)
        got = select.closed_loop_scores(cfg, None, Path("."))
        assert (got["val_success"], got["stop_threshold"]) == want and cfg.stop_threshold == want[1]
    assert scored == list(select.STOP_THRESHOLDS) * 3
    monkeypatch.setattr(select, "closed_loop_success", lambda cfg, model, out: 0.7)
    assert select.closed_loop_scores(algorithm("bc").config(skill="Pick"), None, Path(".")) == {"val_success": 0.7}


def test_losses_csv_keeps_a_column_only_some_epochs_carry(tmp_path: Path) -> None:
    """A --stop run's selection epochs add `stop_threshold` to their row; losses.csv keeps it (a
    run once died writing it)."""
    import csv

    runs.write_losses(tmp_path, [{"epoch": 1, "step": 8, "train_loss": 0.6, "val_loss": 0.5, "val_success": float("nan")},
                                 {"epoch": 2, "step": 16, "train_loss": 0.5, "val_loss": 0.4, "val_success": 0.3, "stop_threshold": 0.95}])
    rows = list(csv.DictReader((tmp_path / runs.LOSSES).open()))
    assert rows[0]["stop_threshold"] == "" and rows[1]["stop_threshold"] == "0.95" and rows[1]["val_success"] == "0.3"


def test_entries_the_demonstrations_never_vary_are_acted_exactly(ds: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`held_entries`: an entry constant over the skill's training rows (Navigate's TCP change:
    the experts hold the arm while driving) is emitted exactly, not as the network's
    approximation of a normalised constant; a non-zero TCP change would re-solve the arm's IK and
    its null-space pull would refold the arm (docs/learners.md)."""
    from echo_data.learn.algos.base import held_entries

    rows = np.array([[0.3, 0.0, 1.0, 0.5], [0.1, 0.0, 1.0, 0.5], [0.2, 0.0, 0.0, 0.5]], dtype=np.float32)
    assert held_entries(rows) == [[1, 0.0], [3, 0.5]] and held_entries(rows[:0]) == []

    import echo_data.learn.fit as fit

    seen: list[np.ndarray] = []
    monkeypatch.setattr(fit, "held_entries", lambda a: (seen.append(np.asarray(a)), [[0, 7.0]])[1])
    summary = _train(ds, tmp_path / "run", "bc", "--max-steps", "2", "--action-column", "action.ee")
    cfg = config_from_run(runs.read_json(Path(summary["run"]) / runs.CONFIG))
    reader = StepReader(ds, "train")
    own = np.flatnonzero((reader.index.skill == "Navigate") & ~np.isin(reader.index.episode, cfg.val_episodes))
    assert cfg.held_entries == [[0, 7.0]]  # written to config.json
    np.testing.assert_array_equal(seen[0], reader.read(["action.ee"], own)["action.ee"])  # from the skill's training rows, in order

    conf = json.loads((Path(summary["run"]) / runs.CONFIG).read_text())
    conf["held_entries"] = [[4, 0.0], [9, 0.0], [10, 1.0]]  # ee_dx, ee_drz, gripper_close
    (Path(summary["run"]) / runs.CONFIG).write_text(json.dumps(conf))
    policy = SkillPolicy.from_run(Path(summary["run"]))
    policy.reset({})
    obs = {STATE: np.full(len(STATE_NAMES), 0.3, np.float32), "observation.kind": np.zeros(1, np.float32)}
    a = policy.act(obs)
    assert a is not None and a[4] == 0.0 and a[9] == 0.0 and a[10] == 1.0 and a.shape == (len(EE_ACTION_NAMES),)
