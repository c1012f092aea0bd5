"""`echo-data evaluate`: metrics against published values, bad input, determinism across workers, video."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.evaluation.metrics import summarise, wilson

ROOT = Path(__file__).resolve().parents[1]
QUICK = str(ROOT / "recipes" / "quickstart.yaml")


def test_wilson_matches_published_intervals() -> None:
    # Newcombe (1998), Statistics in Medicine 17:857, Table I: 81/263 -> score interval 0.2553-0.3662
    lo, hi = wilson(81, 263)
    assert lo == pytest.approx(0.2553, abs=5e-5) and hi == pytest.approx(0.3662, abs=5e-5)
    # closed form at k = 0: upper bound z^2 / (n + z^2)
    z2 = 1.959963984540054**2
    assert wilson(0, 30) == (0.0, pytest.approx(z2 / (30 + z2)))
    assert wilson(30, 30)[1] == 1.0 and wilson(30, 30)[0] == pytest.approx(30 / (30 + z2))


def _ep(setting: str, chain: int, plan: bool, done: int, spl: list[float | None]) -> dict:
    return {
        "setting": setting, "true_chain": [{}] * chain, "plan_correct": plan, "skills_completed": done if plan else 0,
        "success": plan and done == chain, "steps": 10, "navigate": [{"spl": s, "success": bool(s)} for s in spl],
    }


def test_progressive_success_counts_latched_stages() -> None:
    eps = [_ep("x", 3, True, 3, [0.8]), _ep("x", 3, True, 1, [1.0]), _ep("x", 2, False, 0, []), _ep("x", 5, True, 4, [0.5, None])]
    m = summarise(eps)
    assert m["task_planning"]["k"] == 3 and m["skill_completion"]["k"] == 1
    through = [(p["k"], p["n"]) for p in m["progressive"]]
    assert through == [(3, 4), (2, 4), (2, 3), (1, 1), (0, 1)]  # through p: over chains of >= p skills
    assert m["navigate_spl"]["n"] == 3 and m["navigate_spl"]["value"] == pytest.approx((0.8 + 1.0 + 0.5) / 3)
    assert (m["navigate_success"]["k"], m["navigate_success"]["n"]) == (3, 4)  # every attempted Navigate


class _BadShape:
    observations = ("observation.state",)

    def reset(self, info):  # noqa: ANN001
        pass

    def act(self, obs):  # noqa: ANN001
        return [0.0, 0.0, 0.0]


class _NaN(_BadShape):
    def act(self, obs):  # noqa: ANN001
        return [math.nan] * 12


def _run(*args: str):
    return CliRunner().invoke(app, ["evaluate", QUICK, "-n", "1", *args])  # a later -n wins


@pytest.mark.parametrize(
    "args, says",
    [
        (["--policy", "clever"], "policy 'clever': not a built-in"),
        (["--policy", "no_such_module:Policy"], "cannot import"),
        (["--planner", "tests:Nope"], "planner 'tests:Nope'"),
        (["-n", "4"], "index 3 is past the test split"),
        (["--split", "val"], "--split val"),
        (["--policy", "test_evaluate:_BadShape", "-n", "1"], "expected shape (12,), got (3,)"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(args: list[str], says: str) -> None:
    r = _run(*args)
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and says in err[0], r.output


def test_checkpoint_folder_that_does_not_load(tmp_path: Path) -> None:
    r = _run("--policy", str(tmp_path))
    assert r.exit_code == 2 and "has no agent.json" in r.output
    (tmp_path / "agent.json").write_text(json.dumps({"class": "test_evaluate:_Missing"}))
    r = _run("--policy", str(tmp_path))
    assert r.exit_code == 2 and "cannot import" in r.output


class _FromCheckpoint(_BadShape):
    def __init__(self, checkpoint: Path, gain: float = 1.0) -> None:
        self.checkpoint, self.gain = checkpoint, gain

    def act(self, obs):  # noqa: ANN001
        a = [0.0] * 12
        a[3:12] = list(obs["observation.state"][3:12])
        return a


def test_checkpoint_folder_loads_with_its_kwargs(tmp_path: Path) -> None:
    (tmp_path / "agent.json").write_text(json.dumps({"class": "test_evaluate:_FromCheckpoint", "kwargs": {"gain": 2.0}}))
    (tmp_path / "weights.bin").write_bytes(b"0123")
    out = tmp_path / "r.json"
    r = _run("--policy", str(tmp_path), "--json", str(out))
    assert r.exit_code == 0, r.output
    ident = json.loads(out.read_text())["policy"]
    assert ident["class"] == "test_evaluate:_FromCheckpoint" and ident["checkpoint"] == str(tmp_path)
    assert len(ident["checkpoint_sha256"]) == 64


class _Spinning(_FromCheckpoint):
    """A learner that asks torch for more threads than acting needs, and notes what it acts with."""

    threads: list[int] = []

    def __init__(self, checkpoint: Path, gain: float = 1.0) -> None:
        import torch

        super().__init__(checkpoint, gain)
        torch.set_num_threads(3)

    def act(self, obs):  # noqa: ANN001
        import torch

        _Spinning.threads.append(torch.get_num_threads())
        return super().act(obs)


def test_learners_act_on_one_torch_thread(tmp_path: Path) -> None:
    """A learner acts on `ACTING_THREADS` torch threads whatever it asked for: the episodes must not
    depend on the machine's core count (evaluation/run.py), and the results say so."""
    pytest.importorskip("torch")
    from echo_data.evaluation.run import ACTING_THREADS

    (tmp_path / "agent.json").write_text(json.dumps({"class": "test_evaluate:_Spinning"}))
    out = tmp_path / "r.json"
    _Spinning.threads.clear()
    r = _run("--policy", str(tmp_path), "--json", str(out))
    assert r.exit_code == 0, r.output
    assert _Spinning.threads and set(_Spinning.threads) == {ACTING_THREADS} == {1}
    assert json.loads(out.read_text())["acting_threads"] == ACTING_THREADS


def test_nan_action_fails_that_episode_with_its_reason(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    r = _run("--policy", "test_evaluate:_NaN", "-n", "1", "--json", str(out))
    assert r.exit_code == 0, r.output
    ep = json.loads(out.read_text())["episodes"][0]
    assert not ep["success"] and "non-finite action" in ep["failure"]


def test_results_do_not_depend_on_workers(tmp_path: Path) -> None:
    docs = []
    for w in (1, 2):
        out = tmp_path / f"w{w}.json"
        r = _run("--policy", "random", "-n", "3", "--workers", str(w), "--json", str(out))
        assert r.exit_code == 0, r.output
        docs.append(json.loads(out.read_text()))
    strip = lambda d: [{k: v for k, v in e.items() if k != "seconds"} for e in d["episodes"]]  # noqa: E731
    assert strip(docs[0]) == strip(docs[1])
    assert docs[0]["policy"]["class"].endswith("RandomSkills") and docs[0]["recipe"]["content_hash"]
    assert all(e["steps"] > 0 for e in docs[0]["episodes"])


@pytest.mark.slow
def test_video_has_picture_and_binaural_sound(tmp_path: Path) -> None:
    from echo_data.media import probe_mp4

    out = tmp_path / "r.json"
    r = _run("-n", "1", "--policy", "oracle", "--video", str(tmp_path / "v"), "--json", str(out))
    assert r.exit_code == 0, r.output
    ep = json.loads(out.read_text())["episodes"][0]
    info = probe_mp4(Path(ep["video"]))
    assert sorted(info["streams"]) == ["audio", "video"]
    assert info["audio_channels"] == 2 and info["audio_rate"] == 16000
    assert info["video_frames"] == ep["steps"]
    assert info["duration_s"] == pytest.approx(ep["steps"] / 10, abs=0.15)


# ---------------------------------------------------------------- what a learned policy is given, and STOP
def _privileged_things() -> tuple[type, ...]:
    from echo_data.envs.env import EchoDataEnv
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.world import World

    return (World, EpisodeSpec, SkillCall, EchoDataEnv)


def _holds_privileged(value: object, seen: int = 0) -> bool:
    """Whether `value` is, or holds (in dicts, lists, tuples), the world, the env, the spec or a skill call."""
    if isinstance(value, _privileged_things()):
        return True
    if isinstance(value, dict):
        return any(_holds_privileged(v) for v in [*value.keys(), *value.values()])
    if isinstance(value, (list, tuple)):
        return any(_holds_privileged(v) for v in value)
    return False


class _Spy:
    """A learned policy stand-in: replays `actions` (joint form), records what it is given;
    `ends_itself`: it says STOP (None) after the last action, else it is stopped by the runtime."""

    def __init__(self, actions: list, ends_itself: bool = False, observations: tuple[str, ...] | None = None) -> None:
        from echo_data.records import GOAL_POSE

        self.actions, self.ends_itself = list(actions), ends_itself
        self.observations = observations or ("observation.state", GOAL_POSE)
        self.infos: list[dict] = []
        self.obs: list[dict] = []
        self.i = 0

    def reset(self, info: dict) -> None:
        self.infos.append(info)
        self.i = 0

    def act(self, obs: dict):  # noqa: ANN201
        self.obs.append(obs)
        if self.i >= len(self.actions):
            return None
        self.i += 1
        return self.actions[self.i - 1]


class _SpyPlanner:
    """A learned planner stand-in that knows the answer from the test, and records its reset info."""

    def __init__(self, chain: list) -> None:
        self.chain, self.infos = chain, []

    def reset(self, info: dict) -> None:
        self.infos.append(info)

    def plan(self, first_obs: dict) -> list:
        return self.chain


@pytest.fixture(scope="module")
def nav_episode():
    """(env, spec, the scripted Navigate's joint actions and steps) on quickstart's first test episode, physics only."""
    import numpy as np

    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv

    env = EchoDataEnv(QUICK, split="test", images=False, audio=False)
    spec = env.sample_spec("test", 0)
    obs, info = env.reset(options={"spec": spec})
    actions: list = []
    expert = OracleSkills()
    run = run_episode(env, obs, info, OraclePlanner(), expert, on_step=lambda e, o, a, *rest: actions.append(np.array(a)), skills=1)
    expert.close()
    assert spec.chain[0].skill == "Navigate" and run.outcomes[0].success
    yield env, spec, actions
    env.close()


def test_a_learned_policy_gets_observations_only(nav_episode) -> None:  # noqa: ANN001
    """The runtime never hands a learned policy the world, the env, the episode spec or the skill
    call (in reset info or observations); the starred rows' goal comes as the observation
    GOAL_POSE; the scripted experts in the same composition still get their privileged info."""
    import numpy as np

    from echo_data.agents.builtin import OracleSkills
    from echo_data.agents.compose import SkillDispatch
    from echo_data.agents.runtime import run_episode, true_chain
    from echo_data.protocols import PLANNER_INFO, PRIVILEGED_INFO, SKILL_INFO
    from echo_data.records import GOAL_POSE
    from echo_data.skills.navigate import goal_pose

    env, spec, actions = nav_episode
    obs, info = env.reset(options={"spec": spec})
    goal = goal_pose(env.world, spec.chain[0].target)
    spy, oracle = _Spy(actions), OracleSkills()
    seen: list[dict] = []
    real_reset = oracle.reset
    oracle.reset = lambda i: (seen.append(i), real_reset(i))  # type: ignore[method-assign]
    planner = _SpyPlanner(true_chain(spec))
    run = run_episode(env, obs, info, planner, SkillDispatch({"Navigate": spy}, oracle), skills=2, max_steps=len(actions) + 3)
    oracle.close()
    assert [set(i) for i in planner.infos] == [set(PLANNER_INFO)]  # no chain, no spec: the answer comes from the observation
    assert run.outcomes and run.outcomes[0].success  # the spy replayed the expert's drive
    assert spy.infos and spy.obs
    for i in spy.infos:
        assert set(i) == set(SKILL_INFO) and not _holds_privileged(i), i
    for o in spy.obs:
        assert not _holds_privileged(o) and all(isinstance(v, np.ndarray) for v in o.values())
        np.testing.assert_allclose(o[GOAL_POSE], goal, atol=1e-5)
    assert seen and set(PRIVILEGED_INFO) <= set(seen[0]) and seen[0]["skill"] == "Pick"  # the expert is privileged


def test_a_learned_policy_that_ends_itself_is_judged_where_it_stops(nav_episode) -> None:  # noqa: ANN001
    """SoundSpaces' STOP: a learned policy with `ends_itself` runs until it returns None; the
    environment does not count the skill while it passes through the success region, and at the
    stop its test decides. Without `ends_itself` the runtime stops it at the first success."""
    from echo_data.agents.builtin import OraclePlanner
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EnvInputError

    env, spec, actions = nav_episode
    flags: list[tuple[bool, bool]] = []

    def watch(e, o, a, k, call, done) -> None:  # noqa: ANN001
        flags.append((bool(e.success_flags[0]), bool(done[0])))

    obs, info = env.reset(options={"spec": spec})
    run = run_episode(env, obs, info, OraclePlanner(), _Spy(actions, ends_itself=True), on_step=watch, skills=1)
    assert run.outcomes[0].success and run.outcomes[0].steps == len(actions) and env.progress == 1
    assert any(ok for ok, _ in flags) and not any(done for _, done in flags)  # in the region early, counted only at the stop
    # The hand-over record: stopped where the expert stops, at its interaction pose (the expert
    # arrives within ~3 cm and ~1.4 deg, studies/experts/results/handover_starts.json), arm held.
    at_stop = run.navigate[0]
    assert at_stop.goal_distance < 0.06 and at_stop.heading_error < math.radians(3) and at_stop.arm_moved < 0.01, at_stop
    assert flags[0] == (False, False)

    obs, info = env.reset(options={"spec": spec})
    run = run_episode(env, obs, info, OraclePlanner(), _Spy(actions[:3], ends_itself=True), skills=1)
    assert not run.outcomes[0].success and "stopped at step 3" in run.outcomes[0].reason and run.failure
    assert env.ended == "terminated" and env.progress == 0
    with pytest.raises(EnvInputError, match="call reset"):
        env.stop_skill()
    env.reset(options={"spec": spec})
    with pytest.raises(EnvInputError, match="agent_stops"):
        env.stop_skill()

    obs, info = env.reset(options={"spec": spec})
    run = run_episode(env, obs, info, OraclePlanner(), _Spy(actions), skills=1, drive_end="success")  # no STOP: cut at the first success
    first = next(i for i, (ok, _) in enumerate(flags) if ok)  # flags[i]: after i steps
    assert run.outcomes[0].success and run.outcomes[0].steps == first < len(actions)
    assert run.navigate[0].goal_distance > at_stop.goal_distance + 0.1  # cut at the region's rim, short of the expert's stop
    assert not run.navigate[0].handed_over

    obs, info = env.reset(options={"spec": spec})
    run = run_episode(env, obs, info, OraclePlanner(), _Spy(actions), skills=1)  # no STOP, the default: cut at the hand-over
    assert run.outcomes[0].success and first < run.outcomes[0].steps <= len(actions) and run.navigate[0].handed_over
