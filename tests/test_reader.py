"""One reader (issue 46): every read of a built dataset goes through `echo_data/dataset/reader.py`,
and its one row reader yields exactly the rows stored in the shards.

The first half reads the package's source with `ast` (as test_layering does for imports): outside
the reader and the modules its docstring excuses (the writers, `validate.py`), no module opens a
Parquet file, loads a manifest, joins a path to `manifest.json` / `meta/episodes.parquet` or
reads a WAV. The second half compares the reader's views with pyarrow reading the shards."""

from __future__ import annotations

import ast
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "echo_data"
# The reader, and the exceptions its docstring gives with their reasons (`manifest.py`, which owns
# the manifest's format and defines `load_manifest`, names the file by its own constant).
ALLOWED = (
    "dataset/reader.py",
    "dataset/shards.py",  # writes shards and reads back the record a shard carries (build, validate)
    "dataset/written.py",  # reads a manifest of any format before --overwrite replaces it
    "dataset/validate.py",  # checks the raw files and bytes the reader would trust
    "app/build.py",  # resumes a build from its own manifest
)
SOUND_LIBRARY = "sounds/"  # user sound folders are read as sounds, not as a dataset
PARQUET_READS = {"read_table", "ParquetFile", "read_schema", "read_metadata", "ParquetDataset", "read_pandas", "read_parquet"}
AUDIO_READS = {"read", "SoundFile", "blocks", "info"}
DATASET_FILES = {"manifest.json", "episodes.parquet"}
DATASET_NAMES = {"MANIFEST", "EPISODES"}  # the constants, where imported from echo_data.dataset


def _call_name(node: ast.AST) -> str:
    func = node.func if isinstance(node, ast.Call) else node
    return func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""


def direct_reads(source: str) -> list[str]:
    """What in `source` reads a dataset's files without the reader: "line: what" for each."""
    tree = ast.parse(source)
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    imported = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and (n.module or "").startswith("echo_data.dataset")
                for a in n.names}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            name, func = _call_name(node), node.func
            owner = func.value.id if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) else ""
            if name in PARQUET_READS and owner in ("pq", "parquet", "pd", ""):
                found.append(f"{node.lineno}: {owner + '.' if owner else ''}{name}")
            elif name == "load_manifest":
                found.append(f"{node.lineno}: load_manifest")
            elif name in AUDIO_READS and owner in ("sf", "soundfile"):
                found.append(f"{node.lineno}: {owner}.{name}")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            right = node.right
            named = (isinstance(right, ast.Constant) and right.value in DATASET_FILES) or (
                isinstance(right, ast.Name) and right.id in DATASET_NAMES and right.id in imported)
            if named and not _in_message_or_write(node, parents):
                found.append(f"{node.lineno}: / {ast.unparse(right)}")
    return sorted(found, key=lambda f: int(f.split(":")[0]))


def _in_message_or_write(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> bool:
    """Whether a path join only names the file in a message (an f-string) or is written to."""
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.FormattedValue):
            return True
        if isinstance(node, ast.Call):
            return "write" in _call_name(node)
    return False


def test_direct_reads_are_found() -> None:
    src = (
        "import pyarrow.parquet as pq\nfrom echo_data.dataset.manifest import MANIFEST, load_manifest\n"
        "t = pq.read_table(p)\nf = pq.ParquetFile(p)\nm = load_manifest(root)\nok = (root / MANIFEST).is_file()\n"
        "j = (root / 'manifest.json').read_text()\ne = root / 'meta' / 'episodes.parquet'\nimport soundfile as sf\na = sf.read(w)\n"
    )
    assert [f.split(":")[0] for f in direct_reads(src)] == ["3", "4", "5", "6", "7", "8", "10"]
    quiet = (
        "MANIFEST = 'manifest.json'\nx = root / MANIFEST\nraise E(f\"{root / 'manifest.json'}: bad\")\n"
        "atomic_write_json(out / 'manifest.json', m)\npq.write_table(t, p)\nsf.write(p, a, 16000)\n"
    )
    assert direct_reads(quiet) == []


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if not str(p.relative_to(PACKAGE)).startswith(SOUND_LIBRARY))


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_only_the_reader_reads_a_dataset(path: Path) -> None:
    rel = str(path.relative_to(PACKAGE))
    found = direct_reads(path.read_text())
    if rel in ALLOWED:
        return
    assert not found, f"{rel} reads dataset files itself ({', '.join(found)}): go through echo_data/dataset/reader.py"


def test_the_allowed_modules_still_read() -> None:
    """The exceptions are real: each allowed module does read a dataset's files (else drop it)."""
    idle = [rel for rel in ALLOWED if rel != "dataset/reader.py" and not direct_reads((PACKAGE / rel).read_text())]
    assert not idle, f"{idle} no longer read dataset files: take them off ALLOWED"


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 4, "test": 1})


def _shards(root: Path, split: str) -> list[pa.Table]:
    import json

    manifest = json.loads((root / "manifest.json").read_text())
    return [pq.read_table(root / e["file"]) for e in manifest["shards"] if e["split"] == split]


def test_the_reader_yields_the_stored_rows(ds: Path) -> None:
    from echo_data.dataset.reader import StepReader

    for split in ("train", "test"):
        stored = pa.concat_tables(_shards(ds, split))
        reader = StepReader(ds, split)
        # per episode: every row once, in shard order, one episode per table
        episodes = list(reader.episodes())
        assert pa.concat_tables(episodes).equals(stored)
        assert all(len(set(t.column("episode_index").to_pylist())) == 1 for t in episodes)
        assert len(episodes) == len(set(stored.column("episode_index").to_pylist()))
        # projected, by row group: chosen rows in any order, each row group read once
        rows = np.random.default_rng(0).permutation(stored.num_rows)[: max(1, stored.num_rows // 2)]
        got: dict[int, dict[str, object]] = {}
        for sel, table in reader.batches(rows, ["index", "action"]):
            assert table.column_names == ["index", "action"]
            got.update({int(rows[i]): r for i, r in zip(sel, table.to_pylist(), strict=True)})
        assert got == {int(r): {"index": stored.column("index")[int(r)].as_py(), "action": stored.column("action")[int(r)].as_py()} for r in rows}
        # the decoded form and the index columns
        assert np.array_equal(reader.read(["index"], rows)["index"], stored.column("index").to_numpy()[rows])
        assert pa.concat_tables(reader.index_tables(["episode_index", "skill"])).equals(stored.select(["episode_index", "skill"]))
        assert list(reader.offsets) == [0, *np.cumsum([t.num_rows for t in _shards(ds, split)])]


def test_the_views_read_through_it(ds: Path) -> None:
    """The torch loader's rows and the exports' episodes are the stored rows."""
    pytest.importorskip("torch")
    from echo_data.dataset.episode_arrays import iter_episodes
    from echo_data.dataset.reader import read_manifest
    from echo_data.dataset.torch import StepDataset

    stored = pa.concat_tables(_shards(ds, "train"))
    steps = StepDataset(ds, columns=["index", "action", "skill"])
    batch = steps.take(np.arange(len(steps))[::-1])
    assert batch["index"].tolist() == stored.column("index").to_pylist()[::-1]
    assert np.array_equal(batch["action"].numpy(), np.asarray(stored.column("action").to_pylist(), dtype=np.float32)[::-1])
    assert batch["skill"] == stored.column("skill").to_pylist()[::-1]
    arrays = [e for e in iter_episodes(ds, read_manifest(ds), ["train"])]
    assert np.concatenate([e.columns["index"] for e in arrays]).tolist() == stored.column("index").to_pylist()
    assert [e.record["episode_index"] for e in arrays] == sorted(set(stored.column("episode_index").to_pylist()))
