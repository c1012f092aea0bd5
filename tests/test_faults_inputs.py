"""Bad input, as a careful user would try it: one line naming the file and the key (or the
argument), exit 2, nothing written. Each case went wrong before (accepted, a traceback, a
usage box, a hang or gigabytes of memory)."""

from __future__ import annotations

import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
import yaml

from echo_data.cli import main
from echo_data.dataset.manifest import plan_shards
from echo_data.recipe import MAX_SPLIT_EPISODES, Recipe, RecipeError, load_recipe
from echo_data.sounds.user_folders import MAX_FILE_SECONDS

RO = Path("/sys/echo-data-test")  # not writable, even for root


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """`echo-data ARGV` in this process (the installed entry point); exit code and stderr."""
    old = sys.argv
    sys.argv = ["echo-data", *argv]
    try:
        with pytest.raises(SystemExit) as exc:
            main()
    finally:
        sys.argv = old
    return int(exc.value.code or 0), capsys.readouterr().err


def _one_line_exit_2(code: int, err: str, *needles: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (code, err)
    for n in needles:
        assert n in lines[0], (n, lines[0])


SMALL = "name: t\nsplits: {train: 1}\n"
RECIPES = {
    "duplicate key": (SMALL + "seed: 1\nseed: 2\n", ["duplicate key 'seed'", "line 4"]),
    "duplicate nested key": ("name: t\nrobot: {control_hz: 10, control_hz: 5}\n", ["duplicate key 'control_hz'"]),
    "negative composition": ("name: t\ncomposition: {object_relocation: {train: -5}, state_transition: {train: 10}}\n", ["composition", "-5"]),
    "huge composition": ("name: t\ncomposition: {object_relocation: {train: 100000000000}}\n", ["composition", "object_relocation.train"]),
    "seed true": (SMALL + "seed: true\n", ["seed:", "true/false"]),
    "nan weight": (SMALL + "events: {categories: {phone: .nan, alarm: 1.0}}\n", ["events.categories.phone", "finite"]),
    "inf setting weight": (SMALL + "setting: {object_relocation: .inf}\n", ["setting.object_relocation", "finite"]),
    "negative max_steps": (SMALL + "robot: {max_steps: {Navigate: -1}}\n", ["robot.max_steps", "Navigate"]),
    "all-zero splits": ("name: t\nsplits: {train: 0, test: 0}\n", ["splits", "nothing to build"]),
    "300-character name": ("name: " + "a" * 300 + "\nsplits: {train: 1}\n", ["name:", "100"]),
}


@pytest.mark.parametrize("case", sorted(RECIPES))
def test_bad_recipe_is_one_line_exit_2_nothing_written(case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text, needles = RECIPES[case]
    recipe = tmp_path / "r.yaml"
    recipe.write_text(text)
    out = tmp_path / "out"
    code, err = _run(["build", str(recipe), "--out", str(out)], capsys)
    _one_line_exit_2(code, err, str(recipe), *needles)
    assert not out.exists()
    with pytest.raises(RecipeError):
        load_recipe(recipe)


def test_fifo_recipe_does_not_hang(tmp_path: Path) -> None:
    fifo = tmp_path / "r.yaml"
    os.mkfifo(fifo)
    res = subprocess.run(
        [sys.executable, "-m", "echo_data.cli", "build", str(fifo), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    _one_line_exit_2(res.returncode, res.stderr, str(fifo), "not a regular file")


def _user_recipe(tmp_path: Path, wav: np.ndarray, sr: int, subtype: str) -> Path:
    folder = tmp_path / "phones"
    folder.mkdir()
    sf.write(str(folder / "ring.wav"), wav, sr, subtype=subtype)
    sf.write(str(folder / "ring2.wav"), 0.5 * np.sin(np.arange(sr) * 0.3), sr, subtype="PCM_16")
    recipe = tmp_path / "r.yaml"
    recipe.write_text(SMALL + "sounds: {folders: {phone: phones}}\n")
    return recipe


def test_user_wav_with_nan_is_refused_at_load(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x = 0.5 * np.sin(np.arange(16000) * 0.2)
    x[12345] = np.nan
    recipe = _user_recipe(tmp_path, x, 16000, "FLOAT")
    out = tmp_path / "out"
    code, err = _run(["build", str(recipe), "--out", str(out)], capsys)
    _one_line_exit_2(code, err, "ring.wav", "NaN or infinite", "12345")
    assert not out.exists()


def test_user_wav_longer_than_the_cap_is_refused_from_its_header(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sr = 8000
    recipe = _user_recipe(tmp_path, np.zeros(int((MAX_FILE_SECONDS + 1) * sr), dtype=np.int16), sr, "PCM_16")
    out = tmp_path / "out"
    code, err = _run(["build", str(recipe), "--out", str(out)], capsys)
    _one_line_exit_2(code, err, "ring.wav", f"at most {MAX_FILE_SECONDS:.0f} s")
    assert not out.exists()


@pytest.fixture
def recipe_file(tmp_path: Path) -> Path:
    p = tmp_path / "ok.yaml"
    p.write_text(yaml.safe_dump({"name": "t", "splits": {"train": 1}}))
    return p


def test_cli_arguments(recipe_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = str(recipe_file)
    out = tmp_path / "out"
    cases = [
        (["build", r, "--out", str(out), "--limit", "0"], ["--limit"]),
        (["build", r, "--out", str(tmp_path / ("d" * 300))], ["path too long"]),
        (["build", r, "--out", str(out), "--workers", "abc"], ["build", "'--workers'", "valid integer"]),
        (["build", r, "--out", str(out), "--limit", "1.5"], ["'--limit'"]),
        (["preview", r, "--seed", "-1", "--out", str(out)], ["preview", "'--seed'"]),
        (["trial", r, "--seed", "-5"], ["trial", "'--seed'"]),
        (["preview", r, "--out", str(recipe_file)], ["--out", "not a directory"]),
        (["preview", r, "--out", str(RO)], ["--out", "not writable"]),
        (["sounds", "export", str(recipe_file)], ["not a directory"]),
        (["sounds", "export", str(RO), "-c", "phone"], ["not writable"]),
    ]
    before = sorted(os.listdir(tmp_path))
    for argv, needles in cases:
        code, err = _run(argv, capsys)
        _one_line_exit_2(code, err, *needles)
    assert sorted(os.listdir(tmp_path)) == before and recipe_file.read_text().startswith("name")


def test_episode_plan_memory_does_not_grow_with_the_count() -> None:
    """The plan of a million episodes is a few objects; it was one list entry per shard and
    one task per episode (a huge composition was killed by the kernel at 24 GB)."""
    recipe = Recipe(name="t", splits={"train": MAX_SPLIT_EPISODES, "test": MAX_SPLIT_EPISODES})
    tracemalloc.start()
    try:
        plans = plan_shards(recipe, None)
        last = plans["test"][-1]
        files = sum(1 for p in plans["train"] if p.shard % 1000 == 0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert last.last == MAX_SPLIT_EPISODES and files == len(plans["train"]) // 1000 + 1
    assert peak < 200_000, peak
    assert plans["train"].of_file(plans["train"][7].file) == plans["train"][7]
    assert plans["train"].of_file("data/train-00007-of-00008.parquet") is None


def test_preview_replaces_only_an_earlier_preview(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`preview --out DIR` writes into a new, empty or earlier preview folder only: a folder of
    other files is refused before the simulation with every byte kept."""
    from test_faults_overwrite import _thesis, tree_digest

    r = str(Path(__file__).resolve().parents[1] / "recipes" / "quickstart.yaml")
    thesis = _thesis(tmp_path / "thesis")
    (thesis / "topdown.png").write_bytes(b"my own plan")  # a name preview also writes
    before = tree_digest(thesis)
    code, err = _run(["preview", r, "--out", str(thesis)], capsys)
    _one_line_exit_2(code, err, "--out", str(thesis), "nothing was touched")
    assert tree_digest(thesis) == before

    from echo_data.dataset.written import MARKER, NotWrittenByUs, write_marker
    from echo_data.preview import FILES, FORMAT, KIND, check_preview_out
    old = tmp_path / "old"  # a preview from before the marker: only preview files
    old.mkdir()
    for name in FILES:
        (old / name).write_bytes(b"x")
    check_preview_out(old)
    (old / "mine.txt").write_text("mine")
    with pytest.raises(NotWrittenByUs, match="holds mine.txt"):
        check_preview_out(old)
    (old / "mine.txt").unlink()
    write_marker(old, KIND, FORMAT, FILES[:2])  # a marked preview: its list, not the names, decides
    with pytest.raises(NotWrittenByUs, match="holds acoustic_map.png, which echo-data did not write"):
        check_preview_out(old)
    write_marker(old, "dataset", "echo-data/2")
    with pytest.raises(NotWrittenByUs, match="not a preview"):
        check_preview_out(old)
    assert (old / MARKER).is_file()
