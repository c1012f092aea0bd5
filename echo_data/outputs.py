"""Where a command may write: the one check of an output folder before anything is written.

The build, `preview` and `sounds export` refuse a bad `--out` (a file, a read-only or too long
path) the same way, before minutes of work and with nothing left behind.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


class OutputError(ValueError):
    """Bad input for a command's output (path, mode, recipe mismatch): exit 2, nothing written."""


def check_output_path(out: Path) -> None:
    """Refuse an output that is a file or lies somewhere not writable (nothing is left behind)."""
    p = Path(out).absolute()
    try:
        too_long = [part for part in p.parts if len(os.fsencode(part)) > 255]
        if too_long or len(os.fsencode(str(p))) >= 4096:
            raise OutputError(f"{out}: path too long (at most 255 bytes per folder name, 4095 in all)")
        if p.exists() and not p.is_dir():
            raise OutputError(f"{out}: exists and is not a directory")
        anc = p
        while not anc.exists():
            anc = anc.parent
        if not anc.is_dir():
            raise OutputError(f"{out}: {anc} is a file, not a directory")
        os.rmdir(tempfile.mkdtemp(prefix=".echo-data-probe-", dir=anc))
    except OSError as e:
        raise OutputError(f"{out}: not writable ({e.strerror or e})") from None
