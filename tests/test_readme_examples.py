"""The README's loading examples run as written, on a small dataset at out/quickstart.

datasets and torch examples run here; the LeRobot one in LeRobot's own environment (see
tests/test_export_lerobot.py); the LLaMA-Factory training YAML is checked the way LLaMA-Factory
reads it: `dataset_dir`/dataset_info.json names the dataset, whose sharegpt records have one
`<audio>` / `<image>` tag per media file and media paths that exist under `dataset_dir`.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest
import yaml
from support.lerobot_env import HERE, VENV_PYTHON
from support.synth import build_synth
from typer.testing import CliRunner

from echo_data.cli import app

README = (HERE.parent / "README.md").read_text()
EXAMPLES = dict(re.findall(r"<!-- example: (\w+) -->\n```\w+\n(.*?)```", README, flags=re.S))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("readme")
    build_synth(root / "out" / "quickstart", {"train": 3, "test": 1})
    return root


def _code(name: str) -> str:
    # the synthetic recipe is called "synth": its planner datasets are synth_train, synth_test
    return EXAMPLES[name].replace("quickstart_train", "synth_train")


def test_all_four_examples_are_there() -> None:
    assert set(EXAMPLES) == {"datasets", "torch", "lerobot", "llamafactory"}


@pytest.mark.parametrize("name", ["datasets", "torch"])
def test_python_example_runs(name: str, workdir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(workdir)
    scope: dict = {}
    exec(compile(_code(name), f"README:{name}", "exec"), scope)
    if name == "datasets":
        assert scope["heard"].shape == (32000, 2)
    else:
        assert scope["batch"]["action"].shape[1] == 12 and len(scope["seqs"]) == len(scope["steps"])


def test_lerobot_example_runs(workdir: Path, tmp_path: Path) -> None:
    if not VENV_PYTHON.is_file():
        if os.environ.get("CI"):
            pytest.fail(f"{VENV_PYTHON} missing: scripts/setup_lerobot.sh makes it")
        pytest.skip(f"no LeRobot environment at {VENV_PYTHON}")
    r = CliRunner().invoke(app, ["export", str(workdir / "out" / "quickstart"), "--out", str(workdir / "out" / "quickstart-lerobot"), "--overwrite"])
    assert r.exit_code == 0, r.output
    code = _code("lerobot") + "\nassert len(train) == 3 and frame['action'].shape == (12,) and len(next(iter(loader))['index']) > 0\nprint('ok')\n"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(PYTHONPATH=str(HERE / "lerobot_shim"), HF_HUB_OFFLINE="1", HF_HOME=str(tmp_path / "hf"))
    p = subprocess.run([str(VENV_PYTHON), "-c", code], cwd=workdir, capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0 and p.stdout.strip().endswith("ok"), p.stderr[-2000:]


def test_llamafactory_config_finds_the_planner_data(workdir: Path) -> None:
    cfg = yaml.safe_load(_code("llamafactory"))
    ddir = workdir / cfg["dataset_dir"]
    info = json.loads((ddir / "dataset_info.json").read_text())
    entry = info[cfg["dataset"]]
    assert entry["formatting"] == "sharegpt"
    records = json.loads((ddir / entry["file_name"]).read_text())
    assert len(records) == 3
    for rec in records:
        user, assistant = rec[entry["columns"]["messages"]]
        assert (user["role"], assistant["role"]) == ("user", "assistant")
        assert user["content"].count("<audio>") == len(rec["audios"]) and user["content"].count("<image>") == len(rec.get("images", []))
        assert all((ddir / m).is_file() for m in rec["audios"] + rec.get("images", []))
        json.loads(assistant["content"])  # the skill chain
