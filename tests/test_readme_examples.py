"""The loading examples of the docs' "Exports and loading" page run as written, on a small
dataset at out/quickstart; the README's three are the same code, and its recipe example loads.

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

EXAMPLE = r"<!-- example: (\w+) -->\n```\w+\n(.*?)```"
README = dict(re.findall(EXAMPLE, (HERE.parent / "README.md").read_text(), flags=re.S))
EXAMPLES = dict(re.findall(EXAMPLE, (HERE.parent / "docs" / "loading.md").read_text(), flags=re.S))


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


def test_the_readme_shows_three_of_them_as_the_docs_do() -> None:
    assert set(README) == {"datasets", "torch", "lerobot", "recipe", "train_a_skill"}
    assert all(README[name] == EXAMPLES[name] for name in ("datasets", "torch", "lerobot"))


def test_the_readme_trains_a_skill_with_the_commands_the_user_check_runs() -> None:
    """studies/user_check runs exactly the README's "Training a skill" commands (its defaults)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("user_check", HERE.parent / "studies" / "user_check" / "user_check.py")
    assert spec is not None and spec.loader is not None
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)
    shown = [f"echo-data {' '.join(c)}" for c in study.commands(study.RECIPE, study.WORK, "Pick", 50).values()]
    assert README["train_a_skill"].strip().splitlines() == shown


def test_the_readme_recipe_loads_beside_recipes(tmp_path: Path) -> None:
    from echo_data.recipe import load_recipe

    path = tmp_path / "my_multi_event.yaml"  # as if beside recipes/: the extends path made absolute
    path.write_text(README["recipe"].replace("extends: recipes/", f"extends: {HERE.parent / 'recipes'}/"))
    recipe = load_recipe(path)
    assert recipe.name == "my_multi_event" and recipe.robot.head_camera.width == 224


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
    """The `lerobot-train` command of docs/loading.md as written, but for 2 steps: it trains offline (no
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
