"""The process's listening thread: an environment's step audio runs on it while the main thread
renders the cameras, and in the time between steps it computes what the ears will probably need next.

Why a thread of our own and not `concurrent.futures.ThreadPoolExecutor`: the idle-time work must
yield to the next step's audio between two units of work, which needs a look at the queue that an
executor does not offer. Jobs run one at a time, first come first served, so a track's calls keep
their order and every value is the one the caller would have computed itself (SAPIEN's picture
calls and scipy's FFTs release the GIL, which is what makes the overlap pay).

Idle-time work (`Idle.prefetch_one`) only fills caches whose values are pure functions of their
keys (`echo_data.acoustics.stream.RirCache`), so it changes when a value is computed, never what
it is. `ECHO_DATA_PREFETCH=0` turns it off (the audio still runs on the thread);
`ECHO_DATA_LISTENER=0` runs the audio in the caller's thread, as before this module (to compare).
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, Protocol


class Idle(Protocol):
    """Work for the listening thread's idle time, one small unit per call."""

    def prefetch_one(self) -> bool:
        """Do one unit of work; False when there is nothing left worth doing."""
        ...


def _switch(name: str) -> bool:
    return os.environ.get(name, "1").strip().lower() not in ("0", "false", "no", "off")


def prefetch_enabled() -> bool:
    """Idle-time prefetching is on unless the environment variable ECHO_DATA_PREFETCH is 0."""
    return listener_enabled() and _switch("ECHO_DATA_PREFETCH")


def listener_enabled() -> bool:
    """The listening thread is used unless the environment variable ECHO_DATA_LISTENER is 0."""
    return _switch("ECHO_DATA_LISTENER")


def run_now(fn: Callable[..., Any], *args: Any) -> Future[Any]:
    """fn(*args) in the caller's thread, as a finished `Future` (exceptions are raised, not stored)."""
    f: Future[Any] = Future()
    f.set_result(fn(*args))
    return f


class Listener:
    """One daemon thread running submitted jobs in order; between jobs, the last job's idle work."""

    def __init__(self) -> None:
        self._jobs: queue.SimpleQueue[tuple[Future[Any], Callable[..., Any], tuple[Any, ...], Idle | None]] = queue.SimpleQueue()
        self._idle: Idle | None = None
        self.prefetch = prefetch_enabled()
        self._thread = threading.Thread(target=self._run, name="echo-data-ears", daemon=True)
        self._thread.start()

    def submit(self, fn: Callable[..., Any], *args: Any, idle: Idle | None = None) -> Future[Any]:
        """Run fn(*args) on the thread; afterwards, while nothing else is queued, `idle.prefetch_one()`."""
        f: Future[Any] = Future()
        self._jobs.put((f, fn, args, idle))
        return f

    def _next(self) -> tuple[Future[Any], Callable[..., Any], tuple[Any, ...], Idle | None]:
        while True:
            if self._idle is None:
                return self._jobs.get()
            try:
                return self._jobs.get_nowait()
            except queue.Empty:
                pass
            try:
                more = self._idle.prefetch_one()
            except Exception:  # idle work is optional: a failure there surfaces when the value is really needed
                more = False
            if not more:
                self._idle = None

    def _run(self) -> None:
        while True:
            f, fn, args, idle = self._next()
            if not f.set_running_or_notify_cancel():
                continue
            try:
                f.set_result(fn(*args))
            except BaseException as e:  # handed to the caller's .result()
                f.set_exception(e)
            self._idle = idle if self.prefetch else None


_LISTENERS: dict[int, Listener] = {}
_LOCK = threading.Lock()


def listener() -> Listener:
    """This process's listening thread (made on first use, so a forked or spawned worker makes its own)."""
    pid = os.getpid()
    with _LOCK:
        hit = _LISTENERS.get(pid)
        if hit is None:
            hit = _LISTENERS[pid] = Listener()
    return hit
