"""Where episodes are computed: in this process, a local process pool, or a Ray cluster.

All executors run `fn(task)` after `initializer(*initargs)` has run once in the worker, and
yield results as they finish (any order). Results never depend on which worker ran a task;
the caller orders them. Workers set LP_NUM_THREADS=1 (SAPIEN's renderer) so N workers use N
cores and stay reproducible.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing import get_context
from typing import Any, Literal, Protocol

ExecutorName = Literal["local", "ray"]
WORKER_ENV = {"LP_NUM_THREADS": "1"}


def default_workers() -> int:
    """The cores this process may run on (`os.sched_getaffinity`; all CPUs where it is missing):
    the default number of build workers."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


class ExecutorError(RuntimeError):
    """An executor cannot be used (e.g. Ray missing); the message says what to do."""


class Executor(Protocol):
    def imap_unordered(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]: ...

    def close(self) -> None: ...


def _init_worker(initializer: Callable[..., None], initargs: tuple[Any, ...]) -> None:
    os.environ.update(WORKER_ENV)
    initializer(*initargs)


class InlineExecutor:
    """workers=1: run tasks in this process, in order (no pickling, easy to debug)."""

    def __init__(self, initializer: Callable[..., None], initargs: tuple[Any, ...]) -> None:
        os.environ.update(WORKER_ENV)  # same renderer threading as pool workers -> same bytes
        initializer(*initargs)

    def imap_unordered(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        for task in tasks:
            yield fn(task)

    def close(self) -> None:
        pass


class LocalExecutor:
    """A spawn-context process pool with a bounded number of tasks in flight."""

    def __init__(self, workers: int, initializer: Callable[..., None], initargs: tuple[Any, ...]) -> None:
        self.workers = workers
        self.pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=get_context("spawn"),
            initializer=_init_worker,
            initargs=(initializer, initargs),
        )

    def imap_unordered(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        pending: set[Future] = set()
        it = iter(tasks)
        limit = 2 * self.workers
        try:
            while True:
                while len(pending) < limit:
                    task = next(it, _END)
                    if task is _END:
                        break
                    pending.add(self.pool.submit(fn, task))
                if not pending:
                    return
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in sorted(done, key=id):
                    yield fut.result()
        finally:
            for fut in pending:
                fut.cancel()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


_END = object()
_RAY_STATE: dict[str, Any] = {}
RAY_TASK_RETRIES = 5  # reruns of a task whose worker process or node died (not of episode errors)


def _ray_call(fn: Callable[[Any], Any], initializer: Callable[..., None], initargs: tuple[Any, ...], key: str, task: Any) -> Any:
    """Runs in a Ray worker process: initialise once per process (per build), then run the task."""
    if _RAY_STATE.get("key") != key:
        os.environ.update(WORKER_ENV)
        initializer(*initargs)
        _RAY_STATE["key"] = key
    return fn(task)


def _check_reachable(address: str) -> None:
    """Fail fast when nothing listens at host:port (Ray itself retries for minutes)."""
    import socket

    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if address == "local" or not sep or not port.isdigit():
        return
    try:
        socket.create_connection((host, int(port)), timeout=10).close()
    except OSError as e:
        raise ExecutorError(f"--address {address}: cannot join the Ray cluster (nothing answers there: {e.strerror or e})") from None


class RayExecutor:
    """Tasks on a Ray cluster: the one at `address` (`ray start --head` prints it), else the one
    RAY_ADDRESS names, else a local instance started for this build. Ray retries a task whose worker or node
    died (`max_retries`), so a lost node costs time, not episodes; each task's result reaches
    the writer once, however often it ran."""

    def __init__(self, workers: int, initializer: Callable[..., None], initargs: tuple[Any, ...], address: str | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise ExecutorError("--executor ray needs Ray: pip install 'echo-data[ray]' (or use --executor local)") from None
        self.ray = ray
        # The cluster at --address, else RAY_ADDRESS, else a private local instance: never one
        # that merely happens to run on this machine (`address="auto"` would join any of them).
        target = address or os.environ.get("RAY_ADDRESS") or "local"
        if not ray.is_initialized():
            _check_reachable(target)
            try:
                ray.init(address=target, log_to_driver=False)
            except Exception as e:  # ConnectionError, RuntimeError, ValueError, ... by Ray version
                raise ExecutorError(f"--address {target}: cannot join the Ray cluster ({' '.join(str(e).split())[:200]})") from None
        self.remote = ray.remote(num_cpus=1, max_retries=RAY_TASK_RETRIES, retry_exceptions=False)(_ray_call)
        self.initializer = initializer
        self.initargs_ref = ray.put(initargs)
        self.key = f"{os.getpid()}-{id(self)}"
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.in_flight = 2 * max(workers, cpus)

    def imap_unordered(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        ray = self.ray
        pending: list[Any] = []
        it = iter(tasks)
        try:
            while True:
                while len(pending) < self.in_flight:
                    task = next(it, _END)
                    if task is _END:
                        break
                    pending.append(self.remote.remote(fn, self.initializer, self.initargs_ref, self.key, task))
                if not pending:
                    return
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    yield ray.get(ref)
        finally:
            for ref in pending:
                ray.cancel(ref)

    def close(self) -> None:
        pass


def make_executor(
    name: str, workers: int, initializer: Callable[..., None], initargs: tuple[Any, ...], address: str | None = None
) -> InlineExecutor | LocalExecutor | RayExecutor:
    """The executor for `--executor name --workers N [--address A]` (workers=1 locally runs in-process)."""
    if address and name != "ray":
        raise ExecutorError("--address names a Ray cluster: use it with --executor ray")
    if workers < 1:
        raise ExecutorError(f"--workers must be >= 1, got {workers}")
    if name == "local":
        if workers == 1:
            return InlineExecutor(initializer, initargs)
        return LocalExecutor(workers, initializer, initargs)
    if name == "ray":
        return RayExecutor(workers, initializer, initargs, address)
    raise ExecutorError(f"unknown executor {name!r} (use local or ray)")
