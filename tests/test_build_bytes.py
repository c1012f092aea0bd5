"""A refactor must not change a byte of what a build writes: the tiny quickstart (three test
episodes, 32² cameras, the real pipeline) is built and every file it writes is compared with the
digests recorded before issue 46's restructuring (`tests/data/tiny_quickstart_hashes.json`),
re-recorded once when each chain entry's record gained its hand-over (`outcomes[k].handover`:
meta/episodes.parquet, the shard's episode records and the card's byte counts changed, nothing
else). The manifest is left out: it holds the build's timestamps (its shard and WAV sha256 are the
files' own digests, compared here directly)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
from support.recipes import ROOT, tiny_recipe

FIXTURE = ROOT / "tests" / "data" / "tiny_quickstart_hashes.json"
# Written per build (timestamps, the lock) rather than from the episodes.
NOT_CONTENT = {"manifest.json", ".build.lock", ".echo-data.json"}


def digests(root: Path) -> dict[str, str]:
    """sha256 of every file a build wrote under `root`, by relative path."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name not in NOT_CONTENT
    }


@pytest.mark.slow
def test_tiny_quickstart_builds_the_recorded_bytes(tmp_path: Path) -> None:
    from echo_data.app.build import build

    out = tmp_path / "ds"
    build(tiny_recipe(), ROOT / "recipes" / "quickstart.yaml", out, progress=False)
    got, want = digests(out), json.loads(FIXTURE.read_text())
    changed = sorted(k for k in want.keys() | got.keys() if got.get(k) != want.get(k))
    assert not changed, f"files whose bytes changed: {changed}"
