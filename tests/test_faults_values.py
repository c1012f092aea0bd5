"""Bad values are refused, not stored or clipped: an option that does not apply, a count larger
than the data, a policy's complex-valued actions, a manifest key the build never writes."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from support.cli import one_line_exit_2
from support.optional import needs_torch
from support.synth import build_synth, damageable_copy
from typer.testing import CliRunner

from echo_data.cli import app

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("values") / "synth", {"train": 2, "test": 1})


@pytest.mark.parametrize("extra, says", [
    (["bc", "--skill", "Navigate", "--inputs", "state", "--audio-form", "stored"], "--audio-form: does not apply without audio in --inputs"),
    (["bc", "--skill", "Navigate", "--inputs", "state", "--dagger-episodes", "2"], "--dagger-episodes / --dagger-steps / --dagger-chunk: do not apply without --dagger"),
    (["planner", "--inputs", "image", "--audio", "spectrogram"], "--audio: does not apply without audio in --inputs"),
    (["planner", "--train-episodes", "99"], "--train-episodes 99: the train split of"),
])
@needs_torch
def test_train_options_that_do_not_apply_or_exceed_the_data(extra: list[str], says: str, pristine: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    one_line_exit_2(["train", extra[0], str(pristine), *extra[1:], "--out", str(run), "--max-steps", "1", "--no-progress"], says)
    assert not (run / "config.json").exists()


class _Complex:
    observations = ("observation.state",)

    def reset(self, info: dict[str, Any]) -> None:
        pass

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        a = np.zeros(12, np.complex128)
        a[3:12] = obs["observation.state"][3:12]
        return a + 1e-3j


def test_complex_actions_are_refused_with_the_reason(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    one_line_exit_2(["evaluate", str(ROOT / "recipes" / "quickstart.yaml"), "-n", "1", "--policy", "test_faults_values:_Complex", "--json", str(out)],
                     "complex values")
    assert not out.exists()


def test_validate_names_unknown_manifest_keys(pristine: Path, tmp_path: Path) -> None:
    ds = damageable_copy(pristine, tmp_path)
    m = json.loads((ds / "manifest.json").read_text())
    m["colour"] = "blue"
    (ds / "manifest.json").write_text(json.dumps(m, indent=1))
    r = CliRunner().invoke(app, ["validate", str(ds)])
    assert r.exit_code == 1 and "manifest.json: unknown key 'colour'" in r.output.splitlines(), r.output
