"""`echo-data train`: BC per skill and the planner, on a real (tiny) quickstart build.

One dataset is built per module with the real pipeline (quickstart, one episode per split).
Training runs are a few optimiser steps: they check the contract (files, loading, resume,
determinism, preprocessing shared with acting), not what the models learn.
"""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12); fails on 3.11
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.schema import ACTION, STATE, column_to_numpy
from echo_data.dataset.torch import StepDataset
from echo_data.learn import runs
from echo_data.learn.features import HEAD_DEPTH, LEAKING_STATE, feature_spec, prepare, single
from echo_data.learn.models import AudioEncoder, PooledAudioEncoder
from echo_data.learn.policy import BCPolicy, PlannerModel
from echo_data.records import ACTION_DIM, STATE_DIM, STATE_NAMES

RECIPES = Path(__file__).resolve().parent.parent / "recipes"
runner = CliRunner()


@pytest.fixture(scope="module")
def ds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("learn") / "qs"
    res = runner.invoke(app, ["build", str(RECIPES / "quickstart.yaml"), "--out", str(out), "--limit", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


def _train(ds: Path, out: Path, *extra: str) -> dict:
    args = ["train", "bc", str(ds), "--skill", "Navigate", "--out", str(out), "--threads", "1", "--no-progress", "--batch-size", "32",
            "--select-every", "0", *extra]  # the lowest validation loss unless a test chooses closed loop (the last option given wins)
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def _weights(folder: Path, name: str = runs.CHECKPOINT) -> dict:
    return runs.load_torch(folder / name)["model"]


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _obs(ds: Path, split: str = "train", i: int = 5) -> tuple[dict, np.ndarray]:
    item = StepDataset(ds, split, skill="Navigate")[i]
    return {k: v for k, v in item.items() if k.startswith("observation.")}, item[ACTION].numpy()


def test_bc_run_loads_as_a_policy_and_acts(ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "nav"
    summary = _train(ds, run, "--inputs", "audio,depth,state", "--max-steps", "3")
    assert summary["step"] == 3
    for name in (runs.CONFIG, runs.POLICY, runs.AGENT, runs.CHECKPOINT, runs.BEST):
        assert (run / name).is_file()
    meta = json.loads((run / runs.POLICY).read_text())
    assert meta["kind"] == "policy" and meta["class"] == "echo_data.learn.policy:SkillPolicy" and meta["algo"] == "bc"
    agent = json.loads((run / runs.AGENT).read_text())  # evaluate's checkpoint folder: Class(checkpoint=folder)
    assert agent == {"class": meta["class"], "kwargs": {}}
    module, cls = agent["class"].split(":")
    policy = getattr(__import__(module, fromlist=[cls]), cls)(checkpoint=run)
    policy.reset({"skill": "Navigate", "target": "x"})
    obs, _ = _obs(ds, "test")
    a = policy.act(obs)
    assert a.shape == (ACTION_DIM,) and a.dtype == np.float32 and np.isfinite(a).all()


def test_epochs_write_losses_and_curves(ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "nav"
    summary = _train(ds, run, "--inputs", "audio,state", "--epochs", "2")
    lines = (run / runs.LOSSES).read_text().splitlines()
    assert lines[0].startswith("epoch,step,train_loss,val_loss") and len(lines) == 3
    assert (run / runs.CURVES).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert summary["epoch"] == 2 and np.isfinite(summary["last"]["train_loss"])


def test_resume_continues_from_the_saved_step(ds: Path, tmp_path: Path) -> None:
    """A run stopped at step 2 and resumed to step 7 holds the same weights as one run
    straight to step 7 (the batch order of an epoch depends on the seed and epoch alone)."""
    straight, split = tmp_path / "straight", tmp_path / "split"
    _train(ds, straight, "--inputs", "audio,state", "--max-steps", "7")
    _train(ds, split, "--inputs", "audio,state", "--max-steps", "2")
    assert runs.load_torch(split / runs.CHECKPOINT)["state"]["step"] == 2
    assert not _same(_weights(split), _weights(straight))
    summary = _train(ds, split, "--inputs", "audio,state", "--max-steps", "7", "--resume")
    assert summary["step"] == 7
    assert _same(_weights(split), _weights(straight))


def test_same_seed_same_weights_other_seed_differs(ds: Path, tmp_path: Path) -> None:
    a, b, c = (tmp_path / n for n in "abc")
    for folder, seed in ((a, "3"), (b, "3"), (c, "4")):
        _train(ds, folder, "--inputs", "audio,depth,state", "--max-steps", "4", "--seed", seed)
    assert _same(_weights(a), _weights(b))
    assert not _same(_weights(a), _weights(c))


def test_audio_encoder_hears_left_from_right(ds: Path) -> None:
    obs, _ = _obs(ds)
    spec = feature_spec(ds, ("audio",))
    x = prepare(single(obs, spec), spec)["audio"]
    assert x.shape == (1, 2, 65, 26) and not torch.equal(x[:, 0], x[:, 1])
    torch.manual_seed(0)
    enc = AudioEncoder(65, 26).eval()
    with torch.no_grad():
        y, y_swapped = enc(x), enc(x.flip(1))
    assert (y - y_swapped).abs().max() > 1e-4


def test_level_ild_form_is_the_ears_level_difference_in_db(ds: Path, tmp_path: Path) -> None:
    """level_ild: channel 2 is 20 log10(|L| / |R|) (the level ratio of the ears in dB), so an ear
    ten times louder reads +20 dB and swapping the ears flips its sign; a run trains and acts on it."""
    from echo_data.learn.features import ILD_SCALE_DB, SPECTROGRAM

    spec = feature_spec(ds, ("audio",), audio_form="level_ild")
    mag = np.full((1, 65, 26, 2), 1e-3, np.float32)
    mag[..., 0] *= 10.0  # the left ear 20 dB louder
    x = prepare({SPECTROGRAM: np.log1p(mag)}, spec)["audio"]
    assert x.shape == (1, 3, 65, 26)
    np.testing.assert_allclose(x[:, 2].numpy() * ILD_SCALE_DB, 20.0, atol=1e-3)
    swapped = prepare({SPECTROGRAM: np.log1p(mag[..., ::-1].copy())}, spec)["audio"]
    np.testing.assert_allclose(swapped[:, 2].numpy(), -x[:, 2].numpy(), atol=1e-5)
    obs, _ = _obs(ds)
    real = prepare(single(obs, spec), spec)["audio"]
    torch.manual_seed(0)
    enc = AudioEncoder(65, 26, channels=3).eval()
    with torch.no_grad():
        assert (enc(real) - enc(torch.cat([real[:, [1, 0]], -real[:, 2:]], dim=1))).abs().max() > 1e-4
    summary = _train(ds, tmp_path / "ild", "--inputs", "audio,state", "--audio-form", "level_ild", "--max-steps", "2")
    assert summary["step"] == 2
    policy = BCPolicy.from_run(tmp_path / "ild")
    assert policy.act(obs).shape == (ACTION_DIM,)
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Navigate", "--out", str(tmp_path / "bad"), "--audio-form", "db", "--no-progress"])
    assert res.exit_code == 2 and "--audio-form: unknown form 'db'" in res.output, res.output


def test_acting_preprocesses_raw_world_observations_like_training(ds: Path) -> None:
    """The world gives depth as uint16 millimetres (H, W); the loaders give float metres
    (1, H, W). Both go through the same `prepare` and must give the same model input."""
    from PIL import Image

    spec = feature_spec(ds, ("audio", "depth", "state"))
    obs, _ = _obs(ds)
    f = sorted((ds / "data").glob("train-*.parquet"))[0]
    t = pq.read_table(f, columns=["skill", HEAD_DEPTH])
    row = [i for i, s in enumerate(t.column("skill").to_pylist()) if s == "Navigate"][5]
    raw = dict(obs)
    raw[HEAD_DEPTH] = np.asarray(Image.open(io.BytesIO(t.column(HEAD_DEPTH)[row].as_py()["bytes"])))
    assert raw[HEAD_DEPTH].dtype == np.uint16 and raw[HEAD_DEPTH].ndim == 2
    a, b = prepare(single(obs, spec), spec), prepare(single(raw, spec), spec)
    for k in a:
        torch.testing.assert_close(a[k], b[k])


def test_state_velocities_echo_the_previous_action(ds: Path) -> None:
    """The leak the `state` input removes: base velocities at t equal the action at t-1."""
    f = sorted((ds / "data").glob("train-*.parquet"))[0]
    t = pq.read_table(f, columns=["episode_index", "skill", ACTION, STATE])
    a = column_to_numpy(t.column(ACTION), (ACTION_DIM,))
    s = column_to_numpy(t.column(STATE), (STATE_DIM,))
    nav = np.asarray(t.column("skill").to_pylist()) == "Navigate"
    same_ep = t.column("episode_index").to_numpy()
    m = nav[1:] & nav[:-1] & (same_ep[1:] == same_ep[:-1])
    v = [STATE_NAMES.index(n) for n in ("base_vx", "base_vy", "base_wz")]
    assert m.sum() > 50 and np.abs(s[1:][m][:, v] - a[:-1][m][:, :3]).max() < 1e-2
    fed = feature_spec(ds, ("state",)).state_names
    assert not set(fed) & set(LEAKING_STATE) and {"base_vx", "base_wz", "arm_0_vel"} <= set(LEAKING_STATE)
    assert set(feature_spec(ds, ("state_raw",)).state_names) == set(STATE_NAMES)


def test_planner_trains_scores_and_plans(ds: Path, tmp_path: Path) -> None:
    from echo_data.learn.planner_data import episode_rows, export_chain

    run = tmp_path / "planner"
    res = runner.invoke(app, ["train", "planner", str(ds), "--inputs", "audio,image", "--epochs", "2", "--out", str(run), "--threads", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    assert report == json.loads((run / "eval.json").read_text())
    assert "test" not in report["episodes"] and not any(k.startswith("test") for k in report)  # training never reads the test split
    assert json.loads((run / runs.POLICY).read_text())["kind"] == "planner"
    # asked for, the test split is scored (test.json) by the kept checkpoint with the decoder chosen on validation
    res = runner.invoke(app, ["evaluate-planner", str(run)])
    assert res.exit_code == 0, res.output
    scored = json.loads(res.stdout)
    assert scored == json.loads((run / runs.TEST).read_text())
    assert scored["episodes"]["test"] == 1 and scored["test_sounds_heard_in_training"] == []
    acc = scored["test"]["all"]["events_in_order"]
    assert acc["n"] == 1 and 0.0 <= acc["ci95"][0] <= acc["ci95"][1] <= 1.0
    # the decoder is chosen on validation and stored where PlannerModel reads it
    config = json.loads((run / runs.CONFIG).read_text())
    assert report["decode"] == config["decode"] == scored["decode"] and set(scored["test_events_in_order_by_decoder"]) == {"threshold", "sets"}
    assert config["event_sets"] and all(s == sorted(s) for s in config["event_sets"])
    item = StepDataset(ds, "test", columns=["frame_index", "observation.audio.mel", "observation.images.head_rgb"])[0]
    assert int(item["frame_index"]) == 0
    chain = PlannerModel.from_run(run).plan({k: v for k, v in item.items() if k != "frame_index"})
    assert chain and all(set(c) == {"skill", "target"} for c in chain)
    # the score is the acting planner's: its chain for the one test episode is right exactly when test.json counts it right
    (truth,) = [export_chain(r) for r in episode_rows(ds, "test")]
    assert scored["test"]["all"]["chain_exact"]["correct"] == int(chain == truth)
    # resuming is continuing the same run: other inputs are refused, one line, exit 2
    res = runner.invoke(app, ["train", "planner", str(ds), "--inputs", "audio", "--epochs", "3", "--out", str(run), "--resume", "--no-progress"])
    assert res.exit_code == 2 and "inputs is ['audio', 'image'], not ['audio']" in res.output, res.output


def test_planner_learning_curve_subsets_are_seeded_and_nested(ds: Path, tmp_path: Path) -> None:
    """`--train-episodes N` trains on N train episodes drawn from the seed, nested across sizes."""
    from echo_data.learn.planner_data import subset

    assert subset(list(range(40)), 10, 0) < subset(list(range(40)), 20, 0)
    assert subset(list(range(40)), 10, 0) != subset(list(range(40)), 10, 1) and subset([3, 4], None, 0) == {3, 4}
    assert len(subset(list(range(40)), 10, 0)) == 10 and subset(list(range(5)), 9, 0) == set(range(5))
    run = tmp_path / "small"
    res = runner.invoke(app, ["train", "planner", str(ds), "--train-episodes", "1", "--max-steps", "1", "--out", str(run), "--no-progress"])
    assert res.exit_code == 0, res.output
    assert json.loads((run / runs.CONFIG).read_text())["train_episodes"] == 1
    assert sum(json.loads(res.stdout)["episodes"][k] for k in ("train", "val")) == 1


def test_planner_validation_by_sounds_holds_out_instances_never_trained_on() -> None:
    """--val-by sounds: validation episodes play only held-out train instances, training episodes
    none, so validation hears unheard sounds as the test split does."""
    from echo_data.learn.planner_data import split_by_sounds

    rows = [{"episode_index": i, "events": [{"category": c, "sound_id": f"{c}{i % n}"} for c, n in evs]}
            for i, evs in enumerate([[("phone", 6)], [("sink", 3)], [("phone", 6), ("sink", 3)], [("alarm", 1)]] * 10)]
    train, val, held = split_by_sounds(rows, 0.34, 0)
    assert held and not train & val and train and val
    assert not any(h.startswith("alarm") for h in held)  # a category with one instance keeps it for training
    for r in rows:
        sounds = {e["sound_id"] for e in r["events"]}
        if r["episode_index"] in val:
            assert sounds <= set(held)
        if r["episode_index"] in train:
            assert not sounds & set(held)
    assert split_by_sounds(rows, 0.34, 0) == (train, val, held) and split_by_sounds(rows, 0.34, 1)[2] != held


def test_planner_set_decoder_answers_only_event_sets_of_the_training_episodes() -> None:
    """"threshold" names every category with a positive logit; "sets" the most probable set the
    training episodes hold (independent sigmoid probabilities), ordered by the priority scores."""
    from echo_data.learn.planner import decode, event_sets

    cats = ["alarm", "doorbell", "furby", "phone", "sink"]
    rows = [{"events": [{"category": c} for c in evs]} for evs in (["phone"], ["sink"], ["sink", "phone"], ["doorbell", "alarm"], ["doorbell"])]
    sets = event_sets(rows)
    assert sets == [["alarm", "doorbell"], ["doorbell"], ["phone"], ["phone", "sink"], ["sink"]]
    scores = np.array([0.0, 2.0, 0.0, 1.0, 3.0])
    logits = np.array([-5.0, 0.5, -5.0, 2.0, 1.0])  # doorbell, phone and sink above 0: no such episode
    assert decode(logits, scores, cats) == ["sink", "doorbell", "phone"]
    assert decode(logits, scores, cats, sets) == ["sink", "phone"]  # 1.0 + 2.0 beats doorbell's 0.5 with anything
    assert decode(logits, scores, cats, [["sink"]]) == ["sink"]
    # at least one event either way: all logits negative -> the likeliest single set
    assert decode(np.array([-4.0, -1.0, -4.0, -2.0, -3.0]), scores, cats, sets) == ["doorbell"]


def test_planner_augmentation_shifts_pitch_and_gain_alike_in_both_ears() -> None:
    from echo_data.learn.planner import AUG_GAIN_DB, augment_audio

    x = torch.randn(4, 2, 64, 101)
    x[:, 1] = x[:, 0]  # equal ears: augmentation must keep them equal (the interaural cue untouched)
    std = torch.tensor([10.0, 10.0]).view(1, 2, 1, 1)
    a = augment_audio(x, std, np.random.default_rng(0))
    assert a.shape == x.shape and not torch.equal(a, x) and torch.equal(a[:, 0], a[:, 1])
    assert torch.equal(a, augment_audio(x, std, np.random.default_rng(0)))  # seeded
    y = torch.zeros(1, 2, 64, 101)
    gains = [float(augment_audio(y, std, np.random.default_rng(k)).max()) for k in range(20)]
    assert max(gains) <= AUG_GAIN_DB / 10.0 + 1e-6  # a gain of at most 6 dB, in per-ear std units


def test_planner_options_select_by_accuracy_with_augmentation(ds: Path, tmp_path: Path) -> None:
    run = tmp_path / "aug"
    res = runner.invoke(app, ["train", "planner", str(ds), "--epochs", "2", "--augment", "--select", "accuracy", "--val-by", "sounds",
                              "--encoder", "pooled", "--order", "priority", "--mix", "0.5", "--out", str(run), "--no-progress"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    assert report["augment"] and report["select"] == "accuracy" and report["val_by"] == "sounds"
    assert (report["encoder"], report["order"], report["mix"]) == ("pooled", "priority", 0.5)
    res = runner.invoke(app, ["evaluate-planner", str(run), str(ds)])  # the recipe's priority order on the test split too
    assert res.exit_code == 0, res.output
    scored = json.loads(res.stdout)
    assert scored["test_errors"]["of"] == scored["episodes"]["test"] == scored["test"]["all"]["events_in_order"]["n"]
    cfg = json.loads((run / runs.CONFIG).read_text())
    assert cfg["priority"] == ["sink", "doorbell", "alarm", "phone", "furby"]  # the quickstart recipe's rule
    plan = PlannerModel.from_run(run)
    assert plan.priority == cfg["priority"] and isinstance(plan.model.enc.parts["audio"], PooledAudioEncoder)
    res = runner.invoke(app, ["train", "planner", str(ds), "--encoder", "wide", "--out", str(tmp_path / "bad"), "--no-progress"])
    assert res.exit_code == 2 and "--encoder: unknown 'wide'" in res.output, res.output
    res = runner.invoke(app, ["train", "planner", str(ds), "--select", "luck", "--out", str(tmp_path / "bad"), "--no-progress"])
    assert res.exit_code == 2 and "--select: unknown 'luck'" in res.output, res.output
    res = runner.invoke(app, ["train", "planner", str(ds), "--audio", "spectrogram", "--mix", "0.5", "--out", str(tmp_path / "bad"), "--no-progress"])
    assert res.exit_code == 2 and "--mix 0.5 needs --audio mel" in res.output, res.output  # log1p magnitudes do not sum as powers


@pytest.mark.parametrize(
    "args, message",
    [
        (["--skill", "Fly"], "--skill 'Fly': no such rows"),
        (["--skill", "Navigate", "--inputs", "audio,smell"], "--inputs: unknown ['smell']"),
        (["--skill", "Navigate", "--chunk", "2", "--execute", "3"], "need 1 <= execute <= chunk"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(ds: Path, tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "run"
    res = runner.invoke(app, ["train", "bc", str(ds), "--out", str(out), "--no-progress", *args])
    assert res.exit_code == 2 and message in res.output and len(res.output.strip().splitlines()) == 1, res.output
    assert not out.exists()


def test_not_a_dataset_and_busy_out_folder(ds: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["train", "bc", str(tmp_path), "--skill", "Navigate", "--out", str(tmp_path / "r")])
    assert res.exit_code == 2 and "not an echo-data dataset (no manifest.json)" in res.output
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("mine")
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Navigate", "--out", str(busy)])
    assert res.exit_code == 2 and "not empty" in res.output and (busy / "notes.txt").read_text() == "mine"
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Navigate", "--out", str(tmp_path / "none"), "--resume"])
    assert res.exit_code == 2 and "nothing to resume" in res.output


def test_wilson_interval_matches_closed_forms() -> None:
    """0 of n: the upper bound is z^2 / (n + z^2); k of n is symmetric to n-k of n; the
    interval holds the observed rate and stays inside [0, 1]."""
    from echo_data.evaluation.metrics import Z95
    from echo_data.learn.metrics import rate, wilson

    z2 = Z95**2
    lo, hi = wilson(0, 10)
    assert lo == 0.0 and hi == pytest.approx(z2 / (10 + z2), rel=1e-9)
    lo8, hi8 = wilson(8, 10)
    lo2, hi2 = wilson(2, 10)
    assert lo8 == pytest.approx(1 - hi2) and hi8 == pytest.approx(1 - lo2) and lo8 < 0.8 < hi8
    assert hi8 == pytest.approx(0.9433, abs=1e-4) and lo8 == pytest.approx(0.4902, abs=1e-4)
    assert rate(0, 0)["accuracy"] is None


def test_action_chunks_and_target_input(ds: Path, tmp_path: Path) -> None:
    """--chunk 4 --execute 2: the policy predicts once per two steps; a target policy reads its
    goal from the observation GOAL_POSE (which it asks for) and refuses to act without one."""
    from echo_data.learn.features import FeatureError
    from echo_data.records import GOAL_POSE

    run = tmp_path / "chunk"
    _train(ds, run, "--inputs", "state,target", "--chunk", "4", "--execute", "2", "--max-steps", "2")
    policy = BCPolicy.from_run(run)
    calls = []
    forward = policy.model.forward
    policy.model.forward = lambda x: calls.append(1) or forward(x)  # type: ignore[method-assign]
    obs, _ = _obs(ds)
    assert GOAL_POSE in policy.observations
    policy.reset({"skill": "Navigate"})
    with pytest.raises(FeatureError, match="goal_pose"):
        policy.act(obs)
    policy.reset({"skill": "Navigate"})
    obs = {**obs, GOAL_POSE: np.array([1.0, 2.0, 0.5], np.float32)}
    actions = [policy.act(obs) for _ in range(5)]
    assert len(calls) == 3 and all(a.shape == (ACTION_DIM,) and np.isfinite(a).all() for a in actions)
    assert not np.array_equal(actions[0], actions[1])  # two different steps of one chunk


QUICK = str(RECIPES / "quickstart.yaml")


def test_evaluate_runs_a_trained_planner_and_a_per_skill_bc_run(ds: Path, tmp_path: Path) -> None:
    planner, bc = tmp_path / "planner", tmp_path / "bc"
    res = runner.invoke(app, ["train", "planner", str(ds), "--inputs", "audio", "--epochs", "1", "--out", str(planner), "--threads", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    _train(ds, bc, "--inputs", "state", "--max-steps", "2")
    out = tmp_path / "p.json"
    # the planner reads audio although the policy reads only the state: evaluate renders both
    res = runner.invoke(app, ["evaluate", QUICK, "-n", "1", "--planner", str(planner), "--policy", "still", "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    ep = doc["episodes"][0]
    assert doc["planner"]["class"] == "echo_data.learn.policy:PlannerModel" and not ep["failure"].startswith("agent error"), ep
    assert isinstance(ep["planned_chain"], list)
    res = runner.invoke(app, ["evaluate", QUICK, "-n", "1", "--policy", f"Navigate={bc}", "--policy", "oracle", "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    nav = doc["episodes"][0]["skills"][0]
    assert nav["skill"] == "Navigate" and nav["steps"] > 0
    assert doc["policy"]["skills"]["Navigate"]["class"] == "echo_data.learn.policy:SkillPolicy"


def test_dagger_labeller_answers_as_the_expert_from_its_start(ds: Path) -> None:
    from echo_data.dataset.reader import dataset_recipe
    from echo_data.envs.env import EchoDataEnv
    from echo_data.skills import EXPERTS
    from echo_data.skills.navigate import Relabeller

    recipe, n_train = dataset_recipe(ds)
    env = EchoDataEnv(recipe, split="train", images=False, audio=False)
    try:
        spec = env.sample_spec("train", 0)
        env.reset(options={"spec": spec})
        call = spec.chain[0]
        label = Relabeller(env.world, call.target, env.nav_grid())(np.zeros(3, np.float32))
        expert = EXPERTS["Navigate"](env.world, call, spec)
        first = env.world.robot.ee.to_joint(np.asarray(next(expert), np.float32))  # the expert speaks action.ee
        expert.close()
    finally:
        env.close()
    assert n_train >= 1 and label is not None
    np.testing.assert_allclose(label, first, atol=1e-6)


def test_dagger_round_adds_expert_labelled_rows_and_retrains(ds: Path, tmp_path: Path) -> None:
    base = _train(ds, tmp_path / "bc", "--inputs", "state", "--epochs", "1")
    run = tmp_path / "dagger"
    summary = _train(ds, run, "--inputs", "state", "--epochs", "1", "--dagger", "1", "--dagger-episodes", "1", "--dagger-steps", "5")
    assert summary["rows"]["dagger"] == 5 and summary["rows"]["train"] == base["rows"]["train"] + 5
    assert summary["rows"]["val"] == base["rows"]["val"]  # DAgger rows never validate
    log = (run / "dagger.csv").read_text().splitlines()
    assert log[0].startswith("round,") and log[1].split(",")[:4] == ["1", "0", "5", "5"]
    assert BCPolicy.from_run(run).act(_obs(ds, "test")[0]).shape == (ACTION_DIM,)
    # --resume: the rounds start from the finished BC run already in the folder (not trained again)
    shutil.copytree(tmp_path / "bc", tmp_path / "from_bc")
    again = _train(ds, tmp_path / "from_bc", "--inputs", "state", "--epochs", "1", "--dagger", "1", "--dagger-episodes", "1", "--dagger-steps", "5", "--resume")
    assert (tmp_path / "from_bc" / "dagger.csv").read_text().splitlines()[1].split(",")[:4] == ["1", "0", "5", "5"]
    assert again["rows"] == summary["rows"] and again["best_val_loss"] == summary["best_val_loss"]


@pytest.mark.parametrize("column", ["action", "action.ee"])
def test_dagger_round_on_pick_labels_the_learner_after_the_experts_hand_over(ds: Path, tmp_path: Path, column: str) -> None:
    """A manipulation skill: the experts run the chain up to Pick, the learner acts from there and
    the Pick expert labels each state it visits (in the run's action column); the rows train."""
    run = tmp_path / "pick"
    res = runner.invoke(app, ["train", "bc", str(ds), "--skill", "Pick", "--out", str(run), "--threads", "1", "--no-progress", "--batch-size", "32",
                              "--inputs", "state", "--epochs", "1", "--action-column", column, "--dagger", "1", "--dagger-episodes", "1", "--dagger-steps", "6"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["rows"]["dagger"] == 6 and summary["dagger"]["rows_aggregated"] == 6
    log = (run / runs.DAGGER_LOG).read_text().splitlines()
    row = log[1].split(",")
    assert row[:4] == ["1", "0", "6", "6"] and np.isfinite(float(row[5]))  # the learner-expert gap was measured


def test_checkpoint_chosen_closed_loop_on_validation_episodes(ds: Path, tmp_path: Path) -> None:
    """--select-every 1: after each epoch the policy runs on validation-split episodes (the
    dataset's recipe, split "val", never "test"); best.pt carries the success that chose it."""
    from echo_data.learn.select import SELECT_DIR, validation_recipe

    run = tmp_path / "sel"
    summary = _train(ds, run, "--inputs", "state", "--epochs", "2", "--select-every", "1", "--select-episodes", "1", "--skill", "Pick")
    import csv

    scores = [float(r["val_success"]) for r in csv.DictReader((run / runs.LOSSES).read_text().splitlines())]
    assert len(scores) == 2 and set(scores) <= {0.0, 1.0} and summary["last"]["val_success"] == scores[-1]  # one Pick attempt per epoch
    assert runs.load_torch(run / runs.BEST)["val_success"] == max(scores)
    first, second = (run / SELECT_DIR / f"scored-00{i}" for i in (1, 2))  # each epoch's weights scored as they were
    assert json.loads((first / runs.CONFIG).read_text())["skill"] == "Pick"
    assert not _same(_weights(first, runs.BEST), _weights(second, runs.BEST))
    recipe = validation_recipe(ds, "Pick", 2)
    assert recipe.splits["val"] == 2 and recipe.splits["test"] == json.loads((ds / "manifest.json").read_text())["recipe"]["splits"]["test"]
