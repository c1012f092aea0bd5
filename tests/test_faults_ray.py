"""Ray for real: a head and two worker nodes started with `ray start` on this machine; one
worker node's raylet is killed mid-build. The build finishes, writes every episode once, and
its bytes equal a local build's.

Slow (a minute or so: Ray notices a dead node by missed health checks), still run in CI.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import pytest
import ray  # noqa: F401  (the test extra installs it: a missing one fails, never skips)
from support.synth import file_digests, null_library, synth_generate, synth_recipe

from echo_data.app.build import build
from echo_data.dataset.validate import validate

pytestmark = pytest.mark.slow

TESTS = Path(__file__).resolve().parent
# the `ray` of the interpreter running the tests first: a cluster started by another Python's ray
# (one earlier on PATH, e.g. 3.11's beside a 3.12 venv) refuses this process's workers (version mismatch)
_OWN_RAY = Path(sys.executable).parent / "ray"
RAY = str(_OWN_RAY) if _OWN_RAY.is_file() else (shutil.which("ray") or str(_OWN_RAY))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _processes() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, command line) from /proc."""
    out = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                cmd = Path(f"/proc/{d}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
                ppid = int(Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            out[int(d)] = (ppid, cmd)
    return out


def _tree(roots: set[int], procs: dict[int, tuple[int, str]]) -> set[int]:
    mine = set(roots)
    while True:
        more = {p for p, (pp, _) in procs.items() if pp in mine} - mine
        if not more:
            return mine
        mine |= more


def _kill(pids: set[int]) -> None:
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


class Cluster:
    """A head (no CPUs: it only schedules) and worker nodes `node_a`, `node_b` (1 CPU each)."""

    def __init__(self) -> None:
        self.temp = tempfile.mkdtemp(prefix="edray-", dir="/tmp")  # short: Ray's socket paths have a length limit
        self.port = _free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.env = {
            **os.environ,
            "RAY_AUTH_MODE": "disabled",
            # notice a dead node in seconds rather than the default half minute
            "RAY_health_check_initial_delay_ms": "1000",
            "RAY_health_check_period_ms": "1000",
            "RAY_health_check_timeout_ms": "1000",
            "RAY_health_check_failure_threshold": "3",
            "LP_NUM_THREADS": "1",
            # worker processes import the generator the build sends them (tests/) and echo_data
            "PYTHONPATH": os.pathsep.join([str(TESTS), str(TESTS.parent), os.environ.get("PYTHONPATH", "")]),
        }
        common = ["--disable-usage-stats", "--object-store-memory", str(100 * 2**20)]
        self._run(["start", "--head", f"--port={self.port}", "--num-cpus=0", "--include-dashboard=false", f"--temp-dir={self.temp}", *common])
        for node in ("node_a", "node_b"):
            self._run(["start", f"--address={self.address}", "--num-cpus=1", f'--resources={{"{node}": 1}}', *common])

    def _run(self, args: list[str]) -> None:
        res = subprocess.run([RAY, *args], env=self.env, capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr[-2000:]

    def raylet(self, node: str) -> int:
        found = [p for p, (_, cmd) in _processes().items() if "raylet/raylet" in cmd and self.temp in cmd and f"{node},1" in cmd]
        assert len(found) == 1, found
        return found[0]

    def stop(self) -> None:
        """Kill this cluster's processes only (never `ray stop`: it would stop other users' Ray)."""
        procs = _processes()
        _kill(_tree({p for p, (_, cmd) in procs.items() if self.temp in cmd and p != os.getpid()}, procs))
        shutil.rmtree(self.temp, ignore_errors=True)


@pytest.fixture(scope="module")
def cluster():  # noqa: ANN201
    c = Cluster()
    try:
        yield c
    finally:
        c.stop()


DRIVER = """
import json, sys
sys.path.insert(0, {tests!r})
from pathlib import Path
import ray
import echo_data.dataset.writer as writer_mod
from echo_data.app.build import build
from support.synth import null_library, slow_generate, synth_recipe

log = open(sys.argv[2], "a")
real_store = writer_mod.DatasetWriter.store

def store(self, enc):
    real_store(self, enc)
    log.write(f"{{enc.split}} {{enc.index}}\\n")
    log.flush()
    if sum(1 for _ in open(sys.argv[2])) == 2:
        # Mid-build, name a worker node to kill: on one machine the driver attaches to one of the
        # raylets, and losing the driver's own node is the build host dying (that is --resume).
        mine = ray.get_runtime_context().get_node_id()
        node = next(n for n in ("node_b", "node_a") if not any(x["NodeID"] == mine and n in x["Resources"] for x in ray.nodes()))
        Path(sys.argv[3]).write_text(node)

writer_mod.DatasetWriter.store = store
if __name__ == "__main__":
    s = build(synth_recipe(), Path({tests!r}), Path(sys.argv[1]), workers=2, executor="ray", address=sys.argv[4],
              generate=slow_generate, make_library=null_library, progress=False)
    print("EPISODES", json.dumps(s.episodes))
"""


def test_raylet_killed_mid_build_gives_the_local_bytes(cluster: Cluster, tmp_path: Path) -> None:
    """The build runs as its own driver process (as `echo-data build --executor ray --address`)."""
    local = tmp_path / "local"
    build(synth_recipe(), TESTS, local, generate=synth_generate, make_library=null_library, progress=False)
    script, log, victim, out = tmp_path / "driver.py", tmp_path / "stored.txt", tmp_path / "victim.txt", tmp_path / "ray"
    script.write_text(DRIVER.format(tests=str(TESTS)))
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, str(script), str(out), str(log), str(victim), cluster.address], env=cluster.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = None
    while proc.poll() is None and killed is None and time.monotonic() - t0 < 300:
        if victim.is_file():
            killed = cluster.raylet(victim.read_text())
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    stdout, stderr = proc.communicate(timeout=300)
    print(f"ray build with a node killed: {time.monotonic() - t0:.1f} s")
    assert proc.returncode == 0, stderr[-3000:]
    assert killed is not None, "the build ended before a raylet could be killed"
    episodes = [ln.split(" ", 1)[1] for ln in stdout.splitlines() if ln.startswith("EPISODES ")]
    assert episodes and json.loads(episodes[-1]) == {"train": 5, "test": 3}, stdout[-2000:]
    stored = Counter(log.read_text().split("\n")[:-1])
    assert len(stored) == 8 and set(stored.values()) == {1}  # no episode written twice
    assert file_digests(out) == file_digests(local)
    assert validate(out) == []


def test_bad_address_is_one_line_exit_2_nothing_written(tmp_path: Path) -> None:
    from echo_data.app.build import OutputError

    port = _free_port()
    with pytest.raises(OutputError, match=rf"--address 127.0.0.1:{port}: cannot join the Ray cluster"):
        build(synth_recipe(), TESTS, tmp_path / "o", executor="ray", address=f"127.0.0.1:{port}", generate=synth_generate, make_library=null_library, progress=False)
    assert not (tmp_path / "o").exists()  # not even the lock file
