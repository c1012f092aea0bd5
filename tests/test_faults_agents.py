"""An agent declaring its observations wrongly is one line naming the agent and the key, exit 2,
before any episode (not a crash inside the runtime or a worker)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from echo_data.agents.builtin import StillSkills
from echo_data.cli import app

QUICK = str(Path(__file__).resolve().parents[1] / "recipes" / "quickstart.yaml")


class _NotATuple(StillSkills):
    observations = 5  # type: ignore[assignment]


class _AString(StillSkills):
    observations = "observation.state"  # type: ignore[assignment]


class _Unknown(StillSkills):
    observations = ("observation.state", "observation.images.head_rbg")


class _NotAKey(StillSkills):
    observations = ("observation.state", None)  # type: ignore[assignment]


class _PlannerUnknown:
    observations = ("observation.audio.mel", "observation.audio.melody")

    def plan(self, first_obs: dict[str, np.ndarray]) -> Any:
        return []


@pytest.mark.parametrize("args, says", [
    (["--policy", "test_faults_agents:_NotATuple"], "policy 'test_faults_agents:_NotATuple': observations must be a tuple"),
    (["--policy", "test_faults_agents:_AString"], "observations must be a tuple of observation keys, got str"),
    (["--policy", "test_faults_agents:_Unknown"], "observations: 'observation.images.head_rbg' is not an observation of this recipe"),
    (["--policy", "Navigate=test_faults_agents:_NotAKey", "--policy", "still"], "policy 'test_faults_agents:_NotAKey': observations: None"),
    (["--planner", "test_faults_agents:_PlannerUnknown"], "planner 'test_faults_agents:_PlannerUnknown': observations: 'observation.audio.melody'"),
])
def test_wrong_observations_are_one_line_naming_the_agent_and_key(args: list[str], says: str, tmp_path: Path) -> None:
    r = CliRunner().invoke(app, ["evaluate", QUICK, "-n", "1", "--json", str(tmp_path / "r.json"), *args])
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert r.exit_code == 2 and len(err) == 1 and says in err[0], r.output
    assert list(tmp_path.iterdir()) == []
