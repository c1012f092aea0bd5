"""The build lock: one writer per dataset folder, released by the kernel when its holder dies.

`flock` on `<out>/.build.lock` (exclusive, non-blocking). The kernel drops the lock when the
holder's last descriptor closes, so a killed build never leaves a lock that blocks a resume;
the file's text (PID and host of the holder) only names the running build in the error. The
file is never deleted: unlinking a locked file lets a third writer lock a fresh inode while a
second still waits on the old one; it is emptied on release instead. Descriptors are close-on-exec, so spawned workers never
inherit the lock.

The same lock, waited for instead of refused (`wait=True`) and under another file name, serialises
the writers of one shared results file (the paper-table study's driver: several runs, one JSON).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import socket
import time
from pathlib import Path

LOCK_NAME = ".build.lock"


class BuildLockedError(RuntimeError):
    """Another build holds the folder; `str()` names its PID and host."""


class BuildLock:
    """Context manager holding the build lock of `out` (created with its parents if missing);
    `name`: the lock file's name in `out`; `wait`: block until the holder releases it instead of
    raising `BuildLockedError`."""

    def __init__(self, out: Path, *, name: str = LOCK_NAME, wait: bool = False) -> None:
        self.path = Path(out) / name
        self.wait = wait
        self.fd: int | None = None

    def acquire(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX if self.wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            os.close(fd)
            if e.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            raise BuildLockedError(f"{self.path.parent}: another build is writing here ({self.holder()}); wait for it to end or stop it") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on host {socket.gethostname()}\n".encode(), 0)
        self.fd = fd

    def holder(self) -> str:
        """The running build as its lock file names it (waits briefly while it writes its name)."""
        text = ""
        for _ in range(50):
            try:
                text = self.path.read_text().strip()
            except OSError:
                text = ""
            if text:
                break
            time.sleep(0.01)
        return text or "pid unknown"

    def release(self) -> None:
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self.fd, 0)  # no holder any more (and a finished dataset's bytes hold no PID)
            os.close(self.fd)  # closing the last descriptor releases the flock
            self.fd = None

    def __enter__(self) -> BuildLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
