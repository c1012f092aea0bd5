"""The README's loading examples run as written, on a small dataset at out/quickstart.

datasets, torch, robomimic and zarr examples run here (after the export the README names); the
LeRobot one in LeRobot's own environment (see tests/test_export_lerobot.py); the LLaMA-Factory training YAML is checked the way LLaMA-Factory
reads it: `dataset_dir`/dataset_info.json names the dataset, whose sharegpt records have one
`<audio>` / `<image>` tag per media file and media paths that exist under `dataset_dir`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml
from support.lerobot_env import HERE, run_lerobot
from support.optional import needs_torch
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
    assert set(EXAMPLES) == {"datasets", "torch", "lerobot", "lerobot_train", "robomimic", "zarr", "llamafactory"}


@pytest.mark.parametrize("name", ["datasets", pytest.param("torch", marks=needs_torch), pytest.param("robomimic", marks=needs_torch), "zarr"])
def test_python_example_runs(name: str, workdir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(workdir)
    if name in ("robomimic", "zarr"):
        target = {"robomimic": "out/quickstart.hdf5", "zarr": "out/quickstart.zarr"}[name]
        r = CliRunner().invoke(app, ["export", "out/quickstart", "--format", name, "--out", target, "--split", "train", "--overwrite"])
        assert r.exit_code == 0, r.output
    scope: dict = {}
    exec(compile(_code(name), f"README:{name}", "exec"), scope)
    if name == "datasets":
        assert scope["heard"].shape == (32000, 2)
    elif name == "robomimic":
        assert scope["item"]["actions"].shape == (10, 12)
    elif name == "zarr":
        assert scope["first"].shape == (scope["ends"][0], 12) and scope["rgb"].dtype.name == "uint8"
    else:
        assert scope["batch"]["action"].shape[1] == 12 and len(scope["seqs"]) == len(scope["steps"])


def test_lerobot_example_runs(workdir: Path, tmp_path: Path) -> None:
    r = CliRunner().invoke(app, ["export", str(workdir / "out" / "quickstart"), "--out", str(workdir / "out" / "quickstart-lerobot"), "--overwrite"])
    assert r.exit_code == 0, r.output
    code = _code("lerobot") + "\nassert train.num_episodes == 3 and frame['action'].shape == (12,) and len(next(iter(loader))['index']) > 0\nprint('ok')\n"
    p = run_lerobot(["-c", code], tmp_path, cwd=workdir)
    assert p.returncode == 0 and p.stdout.strip().endswith("ok"), p.stderr[-2000:]


def test_lerobot_train_command_runs_offline_on_the_train_split(workdir: Path, tmp_path: Path) -> None:
    """The README's `lerobot-train` command as written, but for 2 steps: it trains offline (no
    ImageNet download: an empty torch hub cache) and reads no test episode."""
    import shlex
    import subprocess

    from support.lerobot_env import VENV_PYTHON, lerobot_env

    r = CliRunner().invoke(app, ["export", str(workdir / "out" / "quickstart"), "--out", str(workdir / "out" / "quickstart-lerobot"), "--overwrite"])
    assert r.exit_code == 0, r.output
    argv = shlex.split(EXAMPLES["lerobot_train"].replace("\\\n", " "))
    assert argv[0] == ".venv-lerobot/bin/lerobot-train" and sum(a.startswith("--steps=") for a in argv) == 1
    argv = [str(VENV_PYTHON.parent / "lerobot-train")] + ["--steps=2" if a.startswith("--steps=") else a for a in argv[1:]]
    env = lerobot_env(tmp_path) | {"TORCH_HOME": str(tmp_path / "torch"), "OMP_NUM_THREADS": "1"}
    p = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600, cwd=workdir)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-3000:]
    log = p.stdout + p.stderr
    assert "dataset.num_episodes=3" in log and "End of training" in log  # the 3 train episodes; the test one is not in the folder
    assert (workdir / "outputs" / "act-quickstart" / "checkpoints").is_dir()


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
