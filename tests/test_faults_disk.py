"""A full disk or a read-only output during a build: one line, exit 2, every finished episode
kept, and `--resume` (once there is room) ends with the same bytes as an undisturbed build."""

from __future__ import annotations

import errno
import shutil
import subprocess
import uuid
from pathlib import Path

import pytest
from support.synth import file_digests, null_library, synth_generate, synth_recipe

import echo_data.dataset.writer as writer_mod
from echo_data.app.build import OutputError, OutputWriteError, build
from echo_data.dataset.validate import validate

TESTS = Path(__file__).resolve().parent


def _build(out: Path, mode: str = "new") -> object:
    return build(synth_recipe(), TESTS, out, mode=mode, generate=synth_generate, make_library=null_library, progress=False)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "synth"
    _build(out)
    return out


def _stored(out: Path) -> int:
    return len(list((out / ".work").rglob("*.json"))) if (out / ".work").exists() else 0


@pytest.mark.parametrize("err", [errno.ENOSPC, errno.EROFS])
def test_write_error_mid_build_is_one_line_keeps_episodes_and_resumes(err: int, reference: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "synth"
    real = writer_mod.atomic_write_bytes
    calls = {"n": 0}

    def failing(path: Path, data: bytes) -> None:
        calls["n"] += 1
        if calls["n"] == 20:  # a few episodes and a shard in: the device fails under the build
            raise OSError(err, errno.errorcode[err] == "ENOSPC" and "No space left on device" or "Read-only file system", str(path))
        real(path, data)

    monkeypatch.setattr(writer_mod, "atomic_write_bytes", failing)
    with pytest.raises(OutputWriteError) as exc:
        _build(out)
    msg = str(exc.value)
    assert isinstance(exc.value, OutputError)  # the CLI maps it to exit 2
    assert len(msg.splitlines()) == 1 and "--resume" in msg and str(out) in msg
    assert ("No space left" in msg) == (err == errno.ENOSPC)
    kept = 2 * len(list((out / "data").glob("*.parquet"))) + _stored(out)  # 2 episodes per shard
    assert kept >= 3  # finished work stayed on disk
    monkeypatch.setattr(writer_mod, "atomic_write_bytes", real)
    summary = _build(out, mode="resume")
    assert summary.reused >= 3  # type: ignore[attr-defined]
    assert file_digests(out) == file_digests(reference)
    assert validate(out) == []


def _mount_tmpfs(where: Path, size: str) -> bool:
    where.mkdir(parents=True, exist_ok=True)
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", f"echo-data-{uuid.uuid4().hex[:6]}", str(where)], capture_output=True).returncode == 0


def test_real_full_disk_on_a_small_tmpfs(reference: Path, tmp_path: Path) -> None:
    """The real thing where the machine lets us mount: a tmpfs smaller than the dataset."""
    size = sum(p.stat().st_size for p in reference.rglob("*") if p.is_file())
    disk = tmp_path / "disk"
    if shutil.which("mount") is None or not _mount_tmpfs(disk, f"{max(size // 2 // 4096, 8) * 4}k"):
        pytest.skip("cannot mount a tmpfs here (needs root and CAP_SYS_ADMIN); the injected ENOSPC test covers the path")
    try:
        out = disk / "synth"
        with pytest.raises(OutputWriteError, match="No space left on device.*--resume"):
            _build(out)
        assert len(list((out / "data").glob("*.parquet"))) + _stored(out) >= 1
        assert subprocess.run(["mount", "-o", "remount,size=64m", str(disk)]).returncode == 0  # space freed
        _build(out, mode="resume")
        assert file_digests(out) == file_digests(reference)
        assert validate(out) == []
    finally:
        subprocess.run(["umount", "-l", str(disk)])
