"""`evaluate` loses nothing it finished: each episode is recorded as it completes, a killed
evaluation resumes to the JSON an uninterrupted one writes, bad targets are refused before the
first episode and a planner's odd answers fail that episode with the reason (never the file)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from echo_data.cli import app

ROOT = Path(__file__).resolve().parents[1]
QUICK = str(ROOT / "recipes" / "quickstart.yaml")
RO = Path("/sys/echo-data-test")  # not writable, even for root


def _evaluate(*args: str) -> Any:
    return CliRunner().invoke(app, ["evaluate", QUICK, "-n", "1", "--policy", "still", *args])


def _one_error_line(r: Any, *needles: str) -> None:
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert r.exit_code == 2 and len(err) == 1, r.output
    assert "Traceback" not in r.output
    for n in needles:
        assert n in err[0], (n, err[0])


def _timings_aside(doc: dict[str, Any]) -> dict[str, Any]:
    """The results without what depends on the clock or the worker count."""
    d = {k: v for k, v in doc.items() if k not in ("wall_seconds", "workers")}
    d["episodes"] = [{k: v for k, v in e.items() if k != "seconds"} for e in doc["episodes"]]
    d["metrics"] = {s: {k: v for k, v in m.items() if k != "seconds"} for s, m in doc["metrics"].items()}
    return d


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "echo_data.cli", "evaluate", QUICK, "--split", "train", "-n", "4", "--policy", "still", *args]


@pytest.mark.slow
def test_sigkill_then_resume_gives_the_uninterrupted_json(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    full = tmp_path / "full.json"
    subprocess.run(_cli("--workers", "2", "--json", str(full)), check=True, env=env, capture_output=True, timeout=600)
    assert not (tmp_path / "full.episodes.jsonl").exists()  # removed once the JSON holds everything

    out = tmp_path / "cut.json"
    log = tmp_path / "cut.episodes.jsonl"
    proc = subprocess.Popen(_cli("--workers", "2", "--json", str(out)), env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and (not log.exists() or log.read_text().count("\n") < 2):  # the header and one episode
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the evaluation and its workers, as a crash would
    proc.wait()
    recorded = [json.loads(x) for x in log.read_text().splitlines()[1:]]
    assert not out.exists() and 1 <= len(recorded) < 4, len(recorded)

    r = subprocess.run(_cli("--workers", "2", "--json", str(out), "--resume"), env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    resumed, uninterrupted = json.loads(out.read_text()), json.loads(full.read_text())
    assert _timings_aside(resumed) == _timings_aside(uninterrupted)
    by_index = {e["index"]: e for e in resumed["episodes"]}
    for rec in recorded:  # the episodes finished before the kill were not run again
        assert by_index[rec["index"]]["seconds"] == rec["seconds"]
    assert not log.exists()


def test_records_are_written_as_episodes_finish_and_resume_refuses_another_evaluation(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    log = tmp_path / "r.episodes.jsonl"
    log.write_text(json.dumps({"evaluation": {"recipe": "other"}}) + "\n")
    r = _evaluate("--json", str(out))  # without --resume a left-over record file is not overwritten
    _one_error_line(r, str(log), "--resume")
    r = _evaluate("--json", str(out), "--resume")
    _one_error_line(r, str(log), "different evaluation", "recipe")
    assert not out.exists()
    log.unlink()
    r = _evaluate("--resume")
    _one_error_line(r, "--resume", "--json")


@pytest.mark.parametrize("target, says", [("folder", "is a folder"), ("readonly", "not writable")])
def test_json_target_is_checked_before_the_first_episode(target: str, says: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import echo_data.evaluation.run as run_mod

    ran: list[int] = []
    real = run_mod.evaluate_episode
    monkeypatch.setattr(run_mod, "evaluate_episode", lambda job, i: ran.append(i) or real(job, i))
    if target == "folder":
        out = tmp_path / "r.json"
        out.mkdir()
    else:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        if os.access(ro, os.W_OK):  # root ignores the mode bits: use a folder no one can write
            ro = Path("/sys")
        out = ro / "r.json"
    r = _evaluate("--json", str(out))
    _one_error_line(r, "--json", str(out), says)
    assert ran == []


def test_video_target_is_checked_before_the_first_episode(tmp_path: Path) -> None:
    f = tmp_path / "v"
    f.write_text("x")
    _one_error_line(_evaluate("--video", str(f / "sub")), "--video", str(f))
    _one_error_line(_evaluate("--video", str(RO / "v")), "--video", "not writable")


class _Planner:
    """Answers with whatever `ANSWERS[kind]` gives."""

    observations: tuple[str, ...] = ()
    kind = ""

    def plan(self, first_obs: dict[str, np.ndarray]) -> Any:
        return ANSWERS[self.kind]()


class _ArrayPlanner(_Planner):
    kind = "array"


class _GeneratorPlanner(_Planner):
    kind = "generator"


class _ObjectPlanner(_Planner):
    kind = "object"


class _NumpyStrings(_Planner):
    kind = "numpy strings"


ANSWERS = {
    "array": lambda: np.array([1.0, 2.0]),
    "generator": lambda: ({"skill": "Navigate", "target": "x"} for _ in range(2)),
    "object": lambda: object(),
    "numpy strings": lambda: [{"skill": np.str_("Navigate"), "target": np.str_("phone")}],
}


@pytest.mark.parametrize("cls, says", [
    ("_ArrayPlanner", "got ndarray"), ("_GeneratorPlanner", "got generator"), ("_ObjectPlanner", "got object"), ("_NumpyStrings", "plan wrong"),
])
def test_a_planner_answer_json_cannot_hold_fails_the_episode_with_the_reason(cls: str, says: str, tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    r = _evaluate("--planner", f"test_faults_evaluate:{cls}", "--json", str(out))
    assert r.exit_code == 0, r.output
    ep = json.loads(out.read_text())["episodes"][0]
    assert not ep["success"] and says in ep["failure"], ep["failure"]
    assert ep["planned_chain"] is None or all(type(v) is str for c in ep["planned_chain"] for v in c.values())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]  # no record file, no temporary left


def test_json_and_video_never_overwrite_a_users_file(tmp_path: Path) -> None:
    """`--json OUT` replaces only an earlier evaluation result; `--video DIR` refuses a folder
    already holding a name it would write. Both before the first episode, every byte kept."""
    mine = tmp_path / "results.json"
    mine.write_text('{"my": "numbers"}')
    _one_error_line(_evaluate("--json", str(mine)), "--json", str(mine), "no echo-data evaluation result", "nothing was touched")
    assert mine.read_text() == '{"my": "numbers"}'
    films = tmp_path / "films"
    films.mkdir()
    (films / "test-000000.mp4").write_bytes(b"my own film")
    (films / "notes.txt").write_text("mine")
    _one_error_line(_evaluate("--video", str(films)), "--video", "holds test-000000.mp4 already", "nothing was touched")
    assert (films / "test-000000.mp4").read_bytes() == b"my own film" and sorted(p.name for p in films.iterdir()) == ["notes.txt", "test-000000.mp4"]


def test_an_earlier_result_is_recognised_and_nothing_else(tmp_path: Path) -> None:
    from echo_data.evaluation.run import RESULT_KEYS, is_result

    doc: dict[str, Any] = {k: {} for k in RESULT_KEYS}
    doc["versions"] = {"echo-data": "0.1.0"}
    p = tmp_path / "r.json"
    p.write_text(json.dumps(doc))
    assert is_result(p)
    for broken in ({**doc, "versions": {"other-tool": "1"}}, {k: v for k, v in doc.items() if k != "episodes"}, [doc]):
        p.write_text(json.dumps(broken))
        assert not is_result(p)
    p.write_bytes(b"\xff\xfe not json")
    assert not is_result(p)


@pytest.mark.parametrize("line", ['{"foo": 1}', "[1, 2]", '{"index": "3"}', '{"index": 0}', "7"])
def test_resume_refuses_a_journal_line_that_is_json_but_no_episode_record(tmp_path: Path, line: str) -> None:
    """A record file edited by hand or written by something else: one line naming the file and
    the line, never a KeyError from deep inside the resume."""
    from echo_data.evaluation.journal import Journal, JournalError

    key = {"recipe": "r", "split": "test"}
    log = tmp_path / "r.episodes.jsonl"
    good = {"index": 0, "skipped": "no solvable layout"}
    log.write_text("\n".join([json.dumps({"evaluation": key}), json.dumps(good), line]) + "\n")
    with pytest.raises(JournalError, match=rf"{log}: line 3 is not an episode record"):
        Journal(log, key, resume=True)
    log.write_text("\n".join([json.dumps({"evaluation": key}), json.dumps(good)]) + "\n")
    assert Journal(log, key, resume=True).records == {0: good}
    log.write_text(json.dumps({"evaluation": [1]}) + "\n")
    with pytest.raises(JournalError, match="names no evaluation"):
        Journal(log, key, resume=True)
