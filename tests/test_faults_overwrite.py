"""`--overwrite` deletes only what echo-data wrote: a folder without echo-data's marker, holding
anything echo-data did not write, or containing (or inside) the exported dataset is refused in
one line, exit 2, and every byte of it stays; an echo-data output is replaced, file by file."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
from support.cli import one_line_exit_2
from support.synth import build_synth, damageable_copy, null_library, synth_generate, synth_recipe
from typer.testing import CliRunner

from echo_data.app.build import OutputError, build
from echo_data.cli import app
from echo_data.dataset.validate import validate
from echo_data.dataset.written import MARKER, read_marker

TESTS = Path(__file__).resolve().parent
QUICK = str(TESTS.parent / "recipes" / "quickstart.yaml")
SPLITS = {"train": 2, "test": 1}


def tree_digest(root: Path) -> dict[str, str]:
    """Every file and folder under `root` (the root included) with its sha256: the user's bytes."""
    out = {".": "dir"}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root).as_posix()
        out[rel] = "link" if p.is_symlink() else "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _synth_build(out: Path, mode: str = "new") -> object:
    return build(synth_recipe(splits=SPLITS), TESTS, out, mode=mode, generate=synth_generate, make_library=null_library, progress=False)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_synth(tmp_path_factory.mktemp("overwrite") / "synth", SPLITS)


def _thesis(where: Path) -> Path:
    """An ordinary folder of someone's work, with a file named like one of ours."""
    where.mkdir(parents=True)
    (where / "chapter1.tex").write_text("\\chapter{Results}\n")
    (where / "figures").mkdir()
    (where / "figures" / "plot.png").write_bytes(b"\x89PNG not really")
    (where / "manifest.json").write_text(json.dumps({"format": "another-tool/3", "files": ["chapter1.tex"]}))
    return where


def test_a_dataset_carries_the_marker(pristine: Path) -> None:
    marker = json.loads((pristine / MARKER).read_text())
    assert marker["kind"] == "dataset" and marker["format"].startswith("echo-data/") and marker["version"]
    assert validate(pristine) == []


def test_build_overwrite_refuses_a_folder_that_is_no_echo_data_dataset(tmp_path: Path) -> None:
    out = _thesis(tmp_path / "thesis")
    before = tree_digest(out)
    one_line_exit_2(["build", QUICK, "--out", str(out), "--overwrite", "--workers", "1", "--no-progress"], str(out), "not an echo-data manifest", "nothing was touched")
    assert tree_digest(out) == before


@pytest.mark.parametrize("foreign", ["notes.txt", "audio/train/my_take.wav", "data/old/keep.parquet", "planner/mine.json"])
def test_build_overwrite_refuses_a_dataset_holding_anything_else(foreign: str, pristine: Path, tmp_path: Path) -> None:
    ds = damageable_copy(pristine, tmp_path)
    (ds / foreign).parent.mkdir(parents=True, exist_ok=True)
    (ds / foreign).write_text("mine")
    before = tree_digest(ds)
    with pytest.raises(OutputError, match=f"holds {foreign}, which echo-data did not write"):
        _synth_build(ds, mode="overwrite")
    assert tree_digest(ds) == before


def test_build_overwrite_replaces_its_own_dataset_and_one_built_before_the_marker(pristine: Path, tmp_path: Path) -> None:
    ds = damageable_copy(pristine, tmp_path)
    (ds / "audio" / "train" / ".train-000000.wav.tmp-4242").write_bytes(b"a killed writer's leftover")
    _synth_build(ds, mode="overwrite")
    assert validate(ds) == [] and not list(ds.rglob("*.tmp-*"))
    (ds / MARKER).unlink()  # as datasets built before the marker existed
    _synth_build(ds, mode="overwrite")
    assert (ds / MARKER).is_file() and validate(ds) == []


@pytest.mark.parametrize("fmt", ["zarr", "lerobot"])
def test_export_overwrite_of_the_datasets_parent_deletes_nothing(fmt: str, pristine: Path, tmp_path: Path) -> None:
    parent = tmp_path / "work"
    ds = damageable_copy(pristine, parent)
    _thesis(parent / "thesis")
    before = tree_digest(parent)
    one_line_exit_2(["export", str(ds), "--format", fmt, "--out", str(parent), "--overwrite"], "contains the source dataset")
    one_line_exit_2(["export", str(ds), "--format", fmt, "--out", str(ds), "--overwrite"], "inside the source dataset")
    one_line_exit_2(["export", str(ds), "--format", fmt, "--out", str(ds / "data"), "--overwrite"], "inside the source dataset")
    assert tree_digest(parent) == before


@pytest.mark.parametrize("fmt", ["zarr", "lerobot"])
def test_export_overwrite_refuses_an_ordinary_folder_and_a_tampered_export(fmt: str, pristine: Path, tmp_path: Path) -> None:
    thesis = _thesis(tmp_path / "thesis")
    before = tree_digest(thesis)
    one_line_exit_2(["export", str(pristine), "--format", fmt, "--out", str(thesis), "--overwrite"], str(thesis), "marker", "nothing was touched")
    assert tree_digest(thesis) == before

    out = tmp_path / "export"
    assert CliRunner().invoke(app, ["export", str(pristine), "--format", fmt, "--out", str(out)]).exit_code == 0
    marker = read_marker(out)
    assert marker is not None and marker["kind"] == f"{fmt} export" and marker["files"] and marker["version"]
    assert (out / MARKER).is_file() == (fmt == "lerobot")  # zarr's is in its root .zattrs: zarr warns about other files
    r = CliRunner().invoke(app, ["export", str(pristine), "--format", fmt, "--out", str(out), "--overwrite"])
    assert r.exit_code == 0, r.output  # its own export is replaced
    (out / "meta" / "my_notes.md").write_text("mine")
    before = tree_digest(out)
    one_line_exit_2(["export", str(pristine), "--format", fmt, "--out", str(out), "--overwrite"], "holds meta/my_notes.md, which echo-data did not write")
    assert tree_digest(out) == before
    other = "lerobot" if fmt == "zarr" else "zarr"  # an export of the other kind is not this kind's to replace
    (out / "meta" / "my_notes.md").unlink()
    one_line_exit_2(["export", str(pristine), "--format", other, "--out", str(out), "--overwrite"], f"not a {other} export")


def test_robomimic_overwrite_replaces_only_its_own_file(pristine: Path, tmp_path: Path) -> None:
    paper = tmp_path / "paper.hdf5"
    paper.write_bytes(b"my own results, not HDF5")
    one_line_exit_2(["export", str(pristine), "--format", "robomimic", "--out", str(paper), "--overwrite"], "not an echo-data robomimic export")
    assert paper.read_bytes() == b"my own results, not HDF5"
    ours = tmp_path / "demo.hdf5"
    for extra in ([], ["--overwrite"]):
        r = CliRunner().invoke(app, ["export", str(pristine), "--format", "robomimic", "--out", str(ours), *extra])
        assert r.exit_code == 0, r.output


def test_zarr_export_targets_and_sources_that_cannot_be_used_are_one_line(pristine: Path, tmp_path: Path) -> None:
    """The issue's Zarr cases that were tracebacks: into the dataset itself, into an existing
    folder without --overwrite, from a folder that is no dataset (read-only: test_faults_writes)."""
    before = tree_digest(pristine)
    one_line_exit_2(["export", str(pristine), "--format", "zarr", "--out", str(pristine)], "inside the source dataset")
    one_line_exit_2(["export", str(pristine), "--format", "zarr", "--out", str(pristine / "z")], "inside the source dataset")
    assert tree_digest(pristine) == before
    thesis = _thesis(tmp_path / "thesis")
    kept = tree_digest(thesis)
    one_line_exit_2(["export", str(pristine), "--format", "zarr", "--out", str(thesis)], str(thesis), "already exists", "--overwrite")
    one_line_exit_2(["export", str(thesis), "--format", "zarr", "--out", str(tmp_path / "z")], str(thesis / "manifest.json"), "not an echo-data")
    (thesis / "manifest.json").unlink()
    kept = tree_digest(thesis)
    one_line_exit_2(["export", str(thesis), "--format", "zarr", "--out", str(tmp_path / "z")], str(thesis), "not an echo-data dataset")
    assert tree_digest(thesis) == kept and not (tmp_path / "z").exists()
