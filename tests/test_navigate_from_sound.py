"""studies/learners/navigate_from_sound.py: its bad input is one line, exit 2, nothing written. (Its
--tiny path shares build, training, choice and scoring with studies/learners/sanity_learners.py, whose
tiny path tests/test_sanity_learners.py runs; the driver's own --tiny run is in docs/learners.md.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DRIVER = ROOT / "studies" / "learners" / "navigate_from_sound.py"


@pytest.mark.parametrize("args, says", [
    (("--learners", "bc-rnn,gpt"), "--learners 'bc-rnn,gpt': each must be one of bc-rnn, bc, act"),
    (("--learners", ","), "--learners"),
    (("--workers", "0"), "--workers, --episodes and --select-episodes must be >= 1"),
    (("-n", "0"), "must be >= 1"),
])
def test_bad_arguments_are_one_line_and_exit_2(tmp_path: Path, args: tuple[str, ...], says: str) -> None:
    out = tmp_path / "nav.json"
    r = subprocess.run([sys.executable, str(DRIVER), *args, "--work", str(tmp_path / "work"), "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("navigate_from_sound.py: ") and says in r.stderr, r.stderr
    assert not out.exists() and not (tmp_path / "work").exists()
