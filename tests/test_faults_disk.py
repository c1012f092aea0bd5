"""A full disk or a read-only output during a build: one line, exit 2, every finished episode
kept, and `--resume` (once there is room) ends with the same bytes as an undisturbed build."""

from __future__ import annotations

import errno
import hashlib
import resource
import shutil
import subprocess
import sys
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


# ---------------------------------------------------------------- every command that writes

def _limited(limit: int, argv: list[str]) -> subprocess.CompletedProcess[str]:
    """ARGV run in a process whose files may not grow past `limit` bytes (RLIMIT_FSIZE): every
    write beyond fails with EFBIG inside the real writers (Arrow, zarr, HDF5, the MP4 muxer,
    libsndfile), as it would on a full disk. Python ignores SIGXFSZ, so the write returns an error."""

    def limit_files() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return subprocess.run([sys.executable, *argv], preexec_fn=limit_files, capture_output=True, text=True, timeout=600)


def _one_line_exit_2(res: subprocess.CompletedProcess[str], *needles: str) -> None:
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]
    assert res.returncode == 2 and len(errors) == 1 and "Traceback" not in res.stderr, (res.returncode, res.stderr[-3000:])
    for n in needles:
        assert n in errors[0], (n, errors[0])


def _tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("fmt, out, limit", [("zarr", "export", 4000), ("lerobot", "export", 60000), ("robomimic", "export.hdf5", 60000)])
def test_export_onto_a_full_disk_is_one_line_and_keeps_the_old_export(fmt: str, out: str, limit: int, reference: Path, tmp_path: Path) -> None:
    target = tmp_path / out
    cli = ["-m", "echo_data.cli", "export", str(reference), "--format", fmt, "--out", str(target)]
    assert subprocess.run([sys.executable, *cli], capture_output=True, text=True, timeout=600).returncode == 0
    before = _tree(target) if target.is_dir() else {"": hashlib.sha256(target.read_bytes()).hexdigest()}
    _one_line_exit_2(_limited(limit, [*cli, "--overwrite"]), "--out", "File too large")
    after = _tree(target) if target.is_dir() else {"": hashlib.sha256(target.read_bytes()).hexdigest()}
    assert after == before  # the old export, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == [out]  # no temporary sibling left


@pytest.mark.parametrize("argv, made", [
    (["view", "{ds}", "--out", "{tmp}/ep.mp4"], 20000),
    (["view", "{ds}", "--rerun", "{tmp}/ep.rrd"], 3000),
    (["sounds", "export", "{tmp}/sounds", "-c", "phone"], 5000),
])
def test_view_and_sounds_onto_a_full_disk_are_one_line(argv: list[str], made: int, reference: Path, tmp_path: Path) -> None:
    args = [a.format(ds=reference, tmp=tmp_path) for a in argv]
    _one_line_exit_2(_limited(made, ["-m", "echo_data.cli", *args]), "cannot write")
    assert list(tmp_path.iterdir()) == []  # nothing half-written, no temporary file


_BUILD = """
import sys
from pathlib import Path
sys.path.insert(0, {tests!r})
from support.synth import null_library, synth_generate, synth_recipe
from echo_data.app.build import OutputError, build
try:
    build(synth_recipe(), Path({tests!r}), Path({out!r}), generate=synth_generate, make_library=null_library, progress=False)
except OutputError as e:
    print(f"error: {{e}}", file=sys.stderr)
    sys.exit(2)
"""


def test_build_onto_a_real_write_limit_is_one_line_and_resumes(reference: Path, tmp_path: Path) -> None:
    """Not an injected error: the build's writers meet EFBIG from the kernel; a resume with room
    ends with the same bytes (that finished episodes are kept is the injected test's above)."""
    out = tmp_path / "synth"
    smallest = min(p.stat().st_size for p in (reference / "data").glob("*.parquet"))
    res = _limited(smallest // 2, ["-c", _BUILD.format(tests=str(TESTS), out=str(out))])
    _one_line_exit_2(res, str(out), "File too large", "free space", "--resume")
    _build(out, mode="resume")
    assert file_digests(out) == file_digests(reference)
    assert validate(out) == []


@pytest.mark.slow
@pytest.mark.parametrize("size", ["8k", "64k"])
def test_preview_onto_a_full_disk_is_one_line_and_leaves_nothing(size: str, tmp_path: Path) -> None:
    """The preview is written aside and swapped in whole: a full disk (a small tmpfs; a write
    limit would also stop the renderer's own mapped files) leaves no folder and no temporary sibling."""
    recipe = tmp_path / "r.yaml"
    recipe.write_text(f"extends: {TESTS.parent / 'recipes' / 'quickstart.yaml'}\nrobot:\n  head_camera: {{width: 48, height: 48}}\n"
                      "  wrist_camera: {width: 32, height: 32, rgb: false}\n")
    disk = tmp_path / "disk"
    if shutil.which("mount") is None or not _mount_tmpfs(disk, size):
        pytest.skip("cannot mount a tmpfs here (needs root and CAP_SYS_ADMIN)")
    try:
        res = subprocess.run([sys.executable, "-m", "echo_data.cli", "preview", str(recipe), "--out", str(disk / "pv")], capture_output=True, text=True, timeout=600)
        _one_line_exit_2(res, "--out", "No space left on device")
        assert list(disk.iterdir()) == []
    finally:
        subprocess.run(["umount", "-l", str(disk)])


@pytest.mark.slow
def test_evaluate_onto_a_full_disk_is_one_line_and_keeps_the_finished_episodes(tmp_path: Path) -> None:
    """`--json` under a write limit smaller than the results: one line; the finished episode's
    record stays whole beside it and no half-written results file is left."""
    out = tmp_path / "r.json"
    res = _limited(1500, ["-m", "echo_data.cli", "evaluate", str(TESTS.parent / "recipes" / "quickstart.yaml"), "-n", "1", "--policy", "still", "--json", str(out)])
    _one_line_exit_2(res, "--json", str(out))
    assert not out.exists() and not list(tmp_path.glob(".*tmp*"))
    for line in (tmp_path / "r.episodes.jsonl").read_text().splitlines():
        assert isinstance(__import__("json").loads(line), dict)
