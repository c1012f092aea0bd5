"""One policy per skill in `echo-data evaluate` (`--policy SKILL=POLICY --policy FALLBACK`)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from echo_data.agents.compose import SkillDispatch, parse_specs
from echo_data.cli import app

ROOT = Path(__file__).resolve().parents[1]
QUICK = str(ROOT / "recipes" / "quickstart.yaml")


class _Tag:
    def __init__(self, tag: str, ends: bool, observations: tuple[str, ...] | None) -> None:
        self.tag, self.ends_itself, self.observations, self.seen = tag, ends, observations, []

    def reset(self, info):  # noqa: ANN001
        self.seen.append(info["skill"])

    def act(self, obs):  # noqa: ANN001
        return self.tag


def test_dispatch_routes_by_skill_and_reports_the_active_policy() -> None:
    nav = _Tag("nav", False, ("observation.audio.spectrogram", "observation.state"))
    rest = _Tag("rest", True, ("observation.state",))
    d = SkillDispatch({"Navigate": nav}, rest)
    assert d.observations == ("observation.audio.spectrogram", "observation.state")
    got = []
    for skill in ("Navigate", "Pick", "Navigate", "Place"):
        d.reset({"skill": skill})
        got.append((d.act({}), d.ends_itself))
    assert got == [("nav", False), ("rest", True), ("nav", False), ("rest", True)]
    assert nav.seen == ["Navigate", "Navigate"] and rest.seen == ["Pick", "Place"]
    assert SkillDispatch({"Navigate": nav}, _Tag("all", True, None)).observations is None  # reads everything


def test_specs_parse_with_oracle_as_default_fallback() -> None:
    assert parse_specs(["Navigate=runs/a", "random"]) == ({"Navigate": "runs/a"}, "random")
    assert parse_specs(["Pick=still"]) == ({"Pick": "still"}, "oracle")


@pytest.mark.parametrize(
    "specs, says",
    [
        (["Fly=oracle"], "unknown skill 'Fly'"),
        (["Navigate="], "no policy after '='"),
        (["Navigate=still", "Navigate=random"], "skill Navigate is given twice"),
        (["random", "still"], "2 fallback policies"),
        (["Navigate=clever", "oracle"], "policy 'clever': not a built-in"),
    ],
)
def test_bad_specs_are_one_line_and_exit_2(specs: list[str], says: str) -> None:
    args = [a for s in specs for a in ("--policy", s)]
    r = CliRunner().invoke(app, ["evaluate", QUICK, "-n", "1", *args])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and says in err[0], r.output


def test_named_skill_runs_its_policy_and_the_rest_the_experts(tmp_path: Path) -> None:
    # the experts drive to the object; `still` holds the arm through Pick, which runs out of budget
    out = tmp_path / "r.json"
    r = CliRunner().invoke(app, ["evaluate", QUICK, "-n", "1", "--policy", "Pick=still", "--policy", "oracle", "--json", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    skills = doc["episodes"][0]["skills"]
    assert skills[0]["skill"] == "Navigate" and skills[0]["success"]
    assert skills[1]["skill"] == "Pick" and not skills[1]["success"] and skills[1]["reason"] == "timeout"
    assert doc["policy"]["skills"]["Pick"]["class"].endswith("StillSkills")
    assert doc["policy"]["skills"]["*"]["class"].endswith("OracleSkills")
    assert doc["metrics"]["object_relocation"]["navigate_success"]["k"] >= 1


def test_dispatch_hands_privileged_info_to_privileged_members_only() -> None:
    """A composition is privileged when a member is (the runtime then gives it the world); it
    passes the world, the call and the spec on to that member only."""
    from echo_data.protocols import PRIVILEGED_INFO, is_privileged

    learned = _Tag("nav", True, ("observation.state",))
    expert = _Tag("rest", True, ("observation.state",))
    expert.privileged = True  # type: ignore[attr-defined]
    got: list[dict] = []
    learned.reset = got.append  # type: ignore[method-assign]
    expert.reset = got.append  # type: ignore[method-assign]
    d = SkillDispatch({"Navigate": learned}, expert)
    assert is_privileged(d) and not is_privileged(SkillDispatch({"Navigate": learned}, learned))
    full = {"skill": "Navigate", "target": "phone_0", **{k: object() for k in PRIVILEGED_INFO}}
    d.reset(dict(full))
    d.reset({**full, "skill": "Pick"})
    assert got[0] == {"skill": "Navigate", "target": "phone_0"} and set(PRIVILEGED_INFO) <= set(got[1])
