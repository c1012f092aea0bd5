"""DAgger for every learner (`echo_data.learn.dagger`): each rollout joins training as a segment
of its own, so a recurrent learner (BC-RNN) trains on it from a zero state like the dataset's
segments and a chunking one (ACT) takes its windows like the dataset's chunks; with `--stop` each
labelled state says whether the expert would stop there.

Training runs a few optimiser steps on the shared synthetic dataset; rollouts run in the real
environment of its recipe without cameras or audio (the learners read the state).
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12); fails on 3.11
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.schema import ACTION, STATE
from echo_data.learn import runs
from echo_data.learn.dagger import Rollouts, _Labels, collect
from echo_data.learn.data import append_rows, load_skill_rows
from echo_data.learn.features import feature_spec
from echo_data.learn.fit import Units
from echo_data.learn.policy import SkillPolicy
from echo_data.records import ACTION_DIM

runner = CliRunner()
QUICK = Path(__file__).resolve().parent.parent / "recipes" / "quickstart.yaml"
SINK_EPISODE = 1  # train episode 1 of quickstart: Navigate, CloseSink
ROLL = ["--dagger", "1", "--dagger-episodes", "1", "--dagger-steps", "6"]
SMALL = {"bc_rnn": ["--batch-size", "2"], "act": ["--chunk", "4", "--d-model", "32", "--heads", "2", "--layers", "1"]}


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 3, "test": 1})


def _train(ds: Path, out: Path, algo: str, *extra: str, code: int = 0) -> dict:
    args = ["train", algo.replace("_", "-"), str(ds), "--skill", "Navigate", "--inputs", "state", "--out", str(out), "--no-progress",
            "--max-steps", "2", *SMALL.get(algo, []), *extra]
    res = runner.invoke(app, args)
    assert res.exit_code == code, res.output
    return json.loads(res.stdout) if code == 0 else {"output": res.output}


def _rows(ds: Path, chunk: int, stop: bool = False) -> object:
    return load_skill_rows(ds, "train", "Navigate", feature_spec(ds, ("state",)), chunk=chunk, stop=stop)


def test_rollout_windows_are_the_datasets_chunks(ds: Path) -> None:
    """The dataset's own segments, given as rollouts, window into exactly the targets training
    reads from the dataset (chunks clamped at the segment's end, padding masked, a padded STOP 0)."""
    from echo_data.dataset.reader import StepReader
    from echo_data.dataset.schema import SKILL_STOP

    reader = StepReader(ds, "train")
    keep = np.flatnonzero(reader.index.skill == "Navigate")
    got = reader.read([ACTION, SKILL_STOP], keep)
    _, segments = np.unique(reader.index.segment[keep], return_inverse=True)
    rollouts = Rollouts({}, got[ACTION].astype(np.float32), got[SKILL_STOP].astype(np.float32), segments, [], math.nan)
    assert rollouts.rollouts == len(np.unique(segments)) > 1
    for chunk in (1, 4):
        rows = _rows(ds, chunk, stop=True)
        acts, pad = rollouts.windows(chunk, stop=True)
        assert pad.any() == (chunk > 1)
        np.testing.assert_array_equal(pad, rows.action_pad)
        np.testing.assert_array_equal(acts, rows.actions)


def test_first_only_chunks_supervise_a_rows_own_label_alone(ds: Path, tmp_path: Path) -> None:
    """`--dagger-chunk first`: a DAgger row's chunk target is the expert's label of that row's state,
    the rest masked (the learner's later states are not the expert's path); "path" as before;
    the choice is recorded, a bad one or one without --dagger refused (one line, exit 2)."""
    labels = np.arange(12, dtype=np.float32).reshape(6, 2)
    ro = Rollouts({}, labels, np.zeros(6, np.float32), np.array([0, 0, 0, 1, 1, 1]), [], math.nan)
    path_acts, path_pad = ro.windows(3, stop=False)
    ro.first_only = True
    acts, pad = ro.windows(3, stop=False)
    np.testing.assert_array_equal(acts[:, 0], labels)
    assert pad[:, 1:].all() and not pad[:, 0].any()
    assert not path_pad[0].any() and path_pad[2, 1:].all()  # "path": a rollout's chunk runs on to its end
    np.testing.assert_array_equal(path_acts, acts)  # the same windows, only the mask differs
    summary = _train(ds, tmp_path / "first", "act", *ROLL, "--dagger-chunk", "first")
    assert summary["dagger"]["chunk"] == "first"
    for bad in (["--dagger-chunk", "first"], [*ROLL, "--dagger-chunk", "ahead"]):
        out = _train(ds, tmp_path / "bad", "act", *bad, code=2)["output"]
        assert "--dagger-chunk" in out and len([ln for ln in out.splitlines() if ln.startswith("error:")]) == 1, out
    assert not (tmp_path / "bad").exists()  # refused before anything was written


@pytest.mark.parametrize("algo", ["bc_rnn", "act"])
def test_dagger_round_adds_each_rollout_as_a_segment(ds: Path, tmp_path: Path, algo: str) -> None:
    """bc-rnn (a GRU over segments) and act (chunks of 4) DAgger end to end; each rollout is one
    training segment shaped like the dataset's, its windows the rollout's own labels."""
    run = tmp_path / algo
    summary = _train(ds, run, algo, *ROLL)
    assert summary["rows"]["dagger"] == 6 and summary["dagger"]["segments_aggregated"] == 1
    log = (run / runs.DAGGER_LOG).read_text().splitlines()
    head, row = log[0].split(","), dict(zip(log[0].split(","), log[1].split(","), strict=True))
    assert head[:4] == ["round", "episodes", "rows_added", "rows_aggregated"]
    assert (row["rows_added"], row["segments_added"], row["segments_aggregated"], row["stop_rows_added"]) == ("6", "1", "1", "0")
    new = collect(run, ds, [1], max_steps=5)  # another round's rollout: one segment of five rows
    assert len(new) == 5 and new.rollouts == 1 and (new.segments == 0).all() and not new.stops.any()
    chunk = SkillPolicy.from_run(run).config.window()
    rows = _rows(ds, chunk)
    acts, pad = new.windows(chunk, stop=False)
    assert acts.shape == (5, chunk, rows.actions.shape[2])
    np.testing.assert_array_equal(acts[:, 0], new.labels)  # each row's own label first, then the labels the rollout went on to
    if chunk > 1:
        np.testing.assert_array_equal(acts[0, 1:], new.labels[1:chunk])
        assert pad[-1, 1:].all() and not pad[0].any()
    both = append_rows(rows, new.inputs, acts, pad, new.segments)
    units = Units(both, sequence=True, device="cpu")
    seg = int(rows.segments.max()) + 1
    assert units.spans[seg] == (len(rows), 5) and both.episodes[-1] == -1  # a segment of its own, never validation
    x, at, real, _ = units.inputs(np.array([seg, int(rows.segments[0])]))
    first = units.spans[int(rows.segments[0])][1]
    assert x["state"].shape == (2, max(5, first), *rows.inputs["state"].shape[1:]) and real.reshape(2, -1)[0, :5].all()
    np.testing.assert_array_equal(at.reshape(2, -1)[0, :5], np.arange(len(rows), len(rows) + 5))


@pytest.fixture(scope="module")
def stop_run(ds: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A BC-RNN with the STOP, DAgger'd one round (six rows)."""
    run = tmp_path_factory.mktemp("stop") / "rnn"
    _train(ds, run, "bc_rnn", "--stop", *ROLL)
    return run


def test_the_stop_weight_balances_every_training_row_dagger_rows_too(ds: Path, stop_run: Path) -> None:
    from echo_data.learn.data import split_episodes

    rows = _rows(ds, 1, stop=True)
    kept = ~np.isin(rows.episodes, split_episodes(rows.episodes, 0.15, 0))  # the default validation share and seed
    log = (stop_run / runs.DAGGER_LOG).read_text().splitlines()
    added = dict(zip(log[0].split(","), log[1].split(","), strict=True))
    n, last = int(kept.sum()) + int(added["rows_added"]), float(rows.actions[kept, 0, -1].sum()) + float(added["stop_rows_added"])
    assert int(added["rows_added"]) == 6 and runs.read_json(stop_run / runs.CONFIG)["stop_weight"] == pytest.approx((n - last) / last)


def test_stop_labels_hold_exactly_where_the_drive_hands_over(ds: Path, stop_run: Path) -> None:
    """A STOP learner's rows say stop exactly where the environment's hand-over test holds (not
    at the edge of the paper's 1.5 m region): the Navigate expert drives, every state labelled."""
    from echo_data.dataset.reader import dataset_recipe
    from echo_data.envs.env import EchoDataEnv
    from echo_data.skill_table import handover_call
    from echo_data.skills import EXPERTS

    policy = SkillPolicy.from_run(stop_run)
    recipe, n_train = dataset_recipe(ds)
    env = EchoDataEnv(recipe, split="train", images=False, audio=False)
    hook = _Labels(policy, ACTION, None, stop=True)
    held: list[float] = []
    region: list[bool] = []  # the paper's success test (the 1.5 m region), which holds before the hand-over does
    try:
        spec = next(s for s in (env.sample_spec("train", i) for i in range(n_train)) if handover_call(s.chain, 0) is not None)
        obs, _ = env.reset(options={"spec": spec})
        policy.reset({})
        hook.start(0)
        drive = EXPERTS["Navigate"](env.world, spec.chain[0], spec)
        for ee in drive:
            a = env.world.robot.ee.to_joint(np.asarray(ee, np.float32))
            held.append(float(env.handover_flags[0]))
            region.append(bool(env.success_flags[0]))
            hook(env, obs, a, 0, spec.chain[0], ())
            obs, *_ = env.step(a)
    finally:
        env.close()
    done = hook.rollouts(len(policy.config.action_names), [])
    assert len(done) == len(held) > 10 and done.rollouts == 1
    np.testing.assert_array_equal(done.stops, held)
    assert done.stops[0] == 0 and done.stops[-1] == 1  # the drive ends in the next skill's stance ...
    assert sum(region) > sum(held)  # ... entered after the success region: the STOP is not the paper's 1.5 m test
    assert torch.is_tensor(done.inputs["state"]) and len(done.inputs["state"]) == len(held)


def test_a_manipulation_stop_is_labelled_where_the_expert_has_nothing_left_to_do(stop_run: Path) -> None:
    """CloseSink from where the experts' drive hands over, the labeller's own answers executed:
    every state is stop 0 until the lever is closed and a fresh expert has nothing left to do; that
    state is the one STOP row (the expert's last command as its action) and the rollout ends."""
    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.runtime import StopEpisode, run_episode
    from echo_data.envs.env import EchoDataEnv

    env = EchoDataEnv(QUICK, split="train", images=False, audio=False)
    hook = _Labels(SkillPolicy.from_run(stop_run), ACTION, None, stop=True)  # its policy only prepares the state
    closed: list[bool] = []
    try:
        spec = env.sample_spec("train", SINK_EPISODE)
        k = next(j for j, c in enumerate(spec.chain) if c.skill == "CloseSink")
        obs, info = env.reset(options={"spec": spec})
        assert all(o.success for o in run_episode(env, obs, info, OraclePlanner(), OracleSkills(), skills=k).outcomes)
        obs = {STATE: env.world.robot.state().astype(np.float32)}  # what the policy reads
        env.agent_stops = True  # as the runtime sets it for a learner that STOPs: the skill ends only at its STOP
        hook.start(k)
        with pytest.raises(StopEpisode):
            for _ in range(400):
                closed.append(bool(env.success_flags[k]))
                hook.record(env, obs, None, spec.chain[k])
                obs, *_ = env.step(hook.labels[-1])
    finally:
        env.close()
    done = hook.rollouts(ACTION_DIM, [])
    assert len(done) == len(closed) > 10 and done.stops[:-1].sum() == 0 and done.stops[-1] == 1 and closed[-1]
    np.testing.assert_array_equal(done.labels[-1], done.labels[-2])
    assert sum(closed) > 1  # the lever was closed before the expert was done (it withdraws): success alone is no STOP


def test_a_learner_that_stops_where_the_expert_goes_on_is_labelled_there(ds: Path, stop_run: Path, tmp_path: Path) -> None:
    """A STOP never reaches the step hook (`act` returns None): the state is labelled anyway, with
    the expert's action and stop 0 (the drive starts far from the hand-over), and the rollout ends."""
    run = tmp_path / "eager"
    shutil.copytree(stop_run, run)
    config = runs.read_json(run / runs.CONFIG)
    (run / runs.CONFIG).write_text(json.dumps({**config, "stop_threshold": -1.0}))  # every probability passes: STOP at once
    new = collect(run, ds, [0, 1], max_steps=5)
    assert len(new) == 2 and new.rollouts == 2 and new.segments.tolist() == [0, 1] and new.stops.tolist() == [0.0, 0.0]
    assert new.success == [False, False] and math.isnan(new.agreement)  # no action was taken to compare


def test_dagger_refuses_the_delta_action_form_in_one_line(ds: Path, tmp_path: Path) -> None:
    out = _train(ds, tmp_path / "delta", "bc", "--action-form", "delta", *ROLL, code=2)["output"]
    assert "--dagger: --action-form delta" in out and len(out.strip().splitlines()) == 1
    assert not (tmp_path / "delta").exists()


@pytest.mark.parametrize("horizon", [1, 4])
def test_the_experts_take_over_executes_its_labels_and_keeps_only_its_rows(ds: Path, tmp_path: Path, horizon: int,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """`--dagger-chunk takeover`: the learner acts until the rollout's drawn step, then every
    action executed is the expert's label of that state, and only those states are added (so a
    chunk of the rollout is what the expert executed). Horizon 1: the expert from the first step."""
    import echo_data.learn.dagger as dagger
    from echo_data.envs.env import EchoDataEnv

    run = tmp_path / "bc"
    _train(ds, run, "bc")
    monkeypatch.setattr(dagger, "demonstration_length", lambda dataset, skill: horizon)
    executed: list[np.ndarray] = []
    step = EchoDataEnv.step

    def spy(self: EchoDataEnv, action: np.ndarray) -> object:
        executed.append(np.asarray(action, dtype=np.float32).copy())
        return step(self, action)

    monkeypatch.setattr(EchoDataEnv, "step", spy)
    new = collect(run, ds, [0], max_steps=5, takeover_seed=7)
    at = int(np.random.default_rng(7).integers(0, horizon))
    assert new.takeovers == 1 and len(new) == 5 and new.rollouts == 1
    assert len(executed) == at + 5  # the learner's `at` steps, then the expert's five (the sixth state ends the rollout)
    np.testing.assert_array_equal(np.stack(executed[at:]), new.labels)
    [(mine, theirs)] = new.switches  # where it took over: the learner's would-be action beside the expert's, which was executed
    np.testing.assert_array_equal(theirs, new.labels[0])
    assert mine.shape == theirs.shape
    assert new.success == []  # a rollout the expert took over says nothing of the learner's success
    if at == 0:
        assert math.isnan(new.agreement)  # no learner action to compare
    summary = _train(ds, tmp_path / "cli", "act", *ROLL, "--dagger-chunk", "takeover")
    log = (tmp_path / "cli" / runs.DAGGER_LOG).read_text().splitlines()
    assert summary["dagger"]["chunk"] == "takeover" and log[0].split(",")[-1] == "takeovers"
