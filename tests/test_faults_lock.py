"""Two builds into one folder: the OS lock lets exactly one write; a dead build's lock never blocks."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from support.synth import null_library, synth_generate, synth_recipe

from echo_data.app.build import OutputError, build
from echo_data.dataset.lock import LOCK_NAME, BuildLock
from echo_data.dataset.validate import validate

TESTS = Path(__file__).resolve().parent
SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from pathlib import Path
from echo_data.app.build import OutputError, build
from support.synth import null_library, synth_generate, synth_recipe

def slow(*a, **k):
    import time
    time.sleep(0.05)
    return synth_generate(*a, **k)

if __name__ == "__main__":
    sys.stdin.read(1)  # both writers wait here, then start together
    try:
        build(synth_recipe(), Path({tests!r}), Path(sys.argv[1]), mode="resume", generate=slow, make_library=null_library, progress=False)
    except OutputError as e:
        print(e, file=sys.stderr)
        sys.exit(2)
"""


def test_two_writers_started_together_ten_times(tmp_path: Path) -> None:
    script = tmp_path / "writer.py"
    script.write_text(SCRIPT.format(tests=str(TESTS)))
    for round_ in range(10):
        out = tmp_path / f"ds{round_}"
        procs = [
            subprocess.Popen([sys.executable, str(script), str(out)], stdin=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for _ in range(2)
        ]
        time.sleep(1.0)  # both have imported echo_data and wait on stdin
        for p in procs:
            p.stdin.write("x")  # type: ignore[union-attr]
            p.stdin.close()  # type: ignore[union-attr]
        errs = [p.stderr.read() for p in procs]  # type: ignore[union-attr]
        codes = sorted(p.wait() for p in procs)
        assert codes == [0, 2], (round_, codes, errs)
        loser = errs[[p.returncode for p in procs].index(2)]
        assert len(loser.strip().splitlines()) == 1 and "another build is writing here (pid " in loser and " on host " in loser, loser
        assert validate(out) == [], round_


def test_lock_names_holder_and_a_dead_holder_never_blocks(tmp_path: Path) -> None:
    out = tmp_path / "ds"
    holder = subprocess.Popen(
        [sys.executable, "-c", f"import time; from echo_data.dataset.lock import BuildLock; BuildLock({str(out)!r}).acquire(); print('held', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout.readline().strip() == "held"  # type: ignore[union-attr]
    try:
        try:
            build(synth_recipe(), TESTS, out, mode="resume", generate=synth_generate, make_library=null_library, progress=False)
        except OutputError as e:
            assert f"pid {holder.pid} on host " in str(e)
        else:
            raise AssertionError("a second writer was let in")
        assert [p.name for p in out.iterdir()] == [LOCK_NAME]  # the refused build wrote nothing
    finally:
        os.kill(holder.pid, signal.SIGKILL)
        holder.wait()
    # The holder died with the lock file still naming it: the kernel released the lock.
    assert "pid" in (out / LOCK_NAME).read_text()
    build(synth_recipe(), TESTS, out, mode="resume", generate=synth_generate, make_library=null_library, progress=False)
    assert validate(out) == []
    with BuildLock(out):
        pass
