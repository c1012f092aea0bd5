"""Kill-safety: a build killed at any moment resumes to the same bytes as an uninterrupted one."""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.synth import file_digests, null_library, synth_generate, synth_recipe

import echo_data.app.build as build_mod
import echo_data.dataset.writer as writer_mod
from echo_data.app.build import build
from echo_data.dataset.validate import validate

TESTS = Path(__file__).resolve().parent
SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from pathlib import Path
from echo_data.app.build import build
from support.synth import null_library, slow_generate, synth_recipe

if __name__ == "__main__":
    build(synth_recipe(), Path({tests!r}), Path({out!r}), mode="resume", generate=slow_generate,
          make_library=null_library, progress=False)
"""


def _files(root: Path) -> set[tuple[str, int]]:
    """What is on disk now (names and sizes), to see that a run has started writing.

    os.walk, not rglob: the build creates and removes folders (its write probe, temporary shards)
    while this looks, and os.walk skips a folder that vanished instead of raising.
    """
    out = set()
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            p = Path(folder) / name
            with contextlib.suppress(FileNotFoundError):  # renamed under our feet
                out.add((str(p.relative_to(root)), p.stat().st_size if name in files else -1))
    return out


def _shard_hashes(root: Path) -> list[tuple[str, str]]:
    return [(e["file"], e["sha256"]) for e in json.loads((root / "manifest.json").read_text())["shards"]]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "synth"
    build(synth_recipe(), TESTS, out, generate=synth_generate, make_library=null_library, progress=False)
    return out


def test_sigkill_at_random_moments_then_resume(reference: Path, tmp_path: Path) -> None:
    out = tmp_path / "synth"
    script = tmp_path / "run_build.py"
    script.write_text(SCRIPT.format(tests=str(TESTS), out=str(out)))
    rng = random.Random(20261121)
    interrupted = 0
    for _ in range(4):
        before = _files(out)
        proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 30
        while proc.poll() is None and _files(out) == before and time.monotonic() < deadline:
            time.sleep(0.02)  # wait until this run writes something, then kill at a random moment
        time.sleep(rng.uniform(0.0, 1.5))
        if proc.poll() is None:
            interrupted += 1
            os.killpg(proc.pid, signal.SIGKILL)  # the build's own process group, started above
        proc.wait()
        assert proc.returncode in (0, -signal.SIGKILL), proc.stderr.read().decode()[-2000:]
        proc.stderr.close()
    assert interrupted >= 3, "the build finished before it could be killed: make the generator slower"
    build(synth_recipe(), TESTS, out, mode="resume", generate=synth_generate, make_library=null_library, progress=False)
    assert _shard_hashes(out) == _shard_hashes(reference)
    assert file_digests(out) == file_digests(reference)
    assert validate(out) == []


class _Crash(Exception):
    pass


def test_crash_between_shard_rename_and_manifest(reference: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The worst moment: a shard is on disk but the manifest does not name it yet."""
    out = tmp_path / "synth"
    calls = {"n": 0}
    real = build_mod.write_manifest

    def crashing(path: Path, manifest: dict) -> None:
        calls["n"] += 1
        if calls["n"] == 3:  # 1: initial manifest, 2: first shard, 3: second shard
            raise _Crash
        real(path, manifest)

    monkeypatch.setattr(build_mod, "write_manifest", crashing)  # the initial manifest
    monkeypatch.setattr(writer_mod, "write_manifest", crashing)  # one per shard written
    with pytest.raises(_Crash):
        build(synth_recipe(), TESTS, out, generate=synth_generate, make_library=null_library, progress=False)
    monkeypatch.undo()
    assert (out / "data" / "train-00001-of-00003.parquet").is_file()
    assert len(json.loads((out / "manifest.json").read_text())["shards"]) == 1
    (out / "data" / ".test-00000-of-00002.parquet.tmp-999").write_bytes(b"half a shard")  # a killed writer's leftover
    (out / "data" / "train-00000-of-00003.parquet").write_bytes(b"corrupted")  # a listed shard gone bad
    summary = build(synth_recipe(), TESTS, out, mode="resume", generate=synth_generate, make_library=null_library, progress=False)
    assert summary.generated == 8 - 2  # the second shard's episodes were still stored; the first is redone
    assert file_digests(out) == file_digests(reference)
    assert validate(out) == []
