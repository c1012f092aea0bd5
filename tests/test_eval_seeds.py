"""Several trainings in one evaluation (`echo_data.evaluation.seeds`): `--policy SKILL=A+B+C`
deals the episodes out over the runs and reports the pooled figure beside each seed's."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.evaluation.seeds import SeedSpecError, member_of, split_members

ROOT = Path(__file__).resolve().parents[1]


def test_members_line_up_the_runs_of_every_skill_by_position() -> None:
    assert split_members(("Pick=runs/p0+runs/p1", "Navigate=runs/n0+runs/n1", "oracle")) == [
        ("Pick=runs/p0", "Navigate=runs/n0", "oracle"), ("Pick=runs/p1", "Navigate=runs/n1", "oracle")]
    assert split_members(("Pick=runs/p0+runs/p1", "Navigate=runs/nav")) == [("Pick=runs/p0", "Navigate=runs/nav"), ("Pick=runs/p1", "Navigate=runs/nav")]
    assert split_members(("Pick=runs/p0", "oracle")) == [("Pick=runs/p0", "oracle")]
    assert split_members("oracle") == ["oracle"]
    assert [member_of(i, 3) for i in range(7)] == [0, 1, 2, 0, 1, 2, 0]


@pytest.mark.parametrize("specs, says", [
    (("Pick=a+b", "Navigate=c+d+e"), "same count"),
    (("Pick=a++b",), "empty run"),
])
def test_runs_that_do_not_line_up_are_refused(specs: tuple[str, ...], says: str) -> None:
    with pytest.raises(SeedSpecError, match=says):
        split_members(specs)


def test_evaluate_deals_episodes_to_seeds_and_reports_each(tmp_path: Path) -> None:
    """Two "trainings" of Navigate that differ for sure (the expert, and holding still): the even
    episodes are the first's (all succeed), the odd ones the second's (none does)."""
    out = tmp_path / "eval.json"
    res = CliRunner().invoke(app, ["evaluate", str(ROOT / "recipes" / "quickstart.yaml"), "-n", "3", "--policy", "Navigate=oracle+still",
                                   "--policy", "oracle", "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert [e["member"] for e in doc["episodes"]] == [0, 1, 0]
    assert [e["success"] for e in doc["episodes"]] == [True, False, True]
    seeds = doc["seeds"]
    assert [(m["k"], m["n"]) for m in seeds["per_seed"]] == [(2, 2), (0, 1)] and seeds["range"] == [0.0, 1.0]
    assert (seeds["pooled"]["k"], seeds["pooled"]["n"]) == (2, 3)
    assert [m["name"] for m in doc["policy"]["members"]] == ["Navigate=oracle,oracle", "Navigate=still,oracle"]
    assert "2 training seeds" in res.output


def test_mismatched_seed_lists_are_one_line_exit_2() -> None:
    res = CliRunner().invoke(app, ["evaluate", str(ROOT / "recipes" / "quickstart.yaml"), "-n", "2", "--policy", "Navigate=oracle+still",
                                   "--policy", "Pick=oracle+still+random"])
    assert res.exit_code == 2 and "same count" in res.output and len(res.output.strip().splitlines()) == 1
