"""Steps of the episodes now running, so the build's bar moves inside a long episode.

A build's bar counts finished episodes; one episode of a long chain takes a minute, so without
this the bar sits at 0 until the first one ends. Each worker owns one slot of a shared int64
array (steps done, step budget) and writes it at most every `INTERVAL` seconds: no message per
step, no lock (an aligned int64 store is atomic on the platforms we run; a torn pair only skews
one refresh of the bar). The builder's bar thread reads the slots (`running_fraction`).

Outside a build (trial, evaluate, tests) no slot is installed and `step` is a time check.
Ray workers get no slot: their bar moves per finished episode only.
"""

from __future__ import annotations

import time
from typing import Any

INTERVAL = 0.5  # seconds between two writes of a worker's slot

_slots: Any = None  # multiprocessing RawArray('q', 2 * workers), or None
_slot = 0
_last = 0.0


def make_slots(workers: int, ctx: Any) -> tuple[Any, Any]:
    """The shared slots for `workers` workers and the counter that hands each worker its slot
    (both made by the pool's multiprocessing context `ctx`, passed to workers at their start)."""
    return ctx.RawArray("q", 2 * workers), ctx.Value("i", 0)


def install(slots: Any, counter: Any) -> None:
    """Claim this worker's slot (called once per worker, in the pool's initializer)."""
    global _slots, _slot
    with counter.get_lock():
        _slot = counter.value % (len(slots) // 2)
        counter.value += 1
    _slots = slots


def uninstall() -> None:
    """Forget this process's slot (the build is over)."""
    global _slots
    _slots = None


def prepare() -> None:
    """An episode (attempt) is being sampled: scene, acoustics, sounds (no steps yet)."""
    if _slots is not None:
        _slots[2 * _slot], _slots[2 * _slot + 1] = 0, -1


def begin(budget: int) -> None:
    """An episode (attempt) starts with at most `budget` steps."""
    global _last
    if _slots is not None:
        _slots[2 * _slot], _slots[2 * _slot + 1] = 0, max(int(budget), 1)
        _last = time.monotonic()


def step(done: int) -> None:
    """`done` steps of the running episode are finished (throttled to one write per INTERVAL)."""
    global _last
    if _slots is None:
        return
    now = time.monotonic()
    if now - _last >= INTERVAL:
        _slots[2 * _slot] = int(done)
        _last = now


def end() -> None:
    """The running episode is over (before its result is sent: the bar never counts it twice)."""
    if _slots is not None:
        _slots[2 * _slot] = _slots[2 * _slot + 1] = 0


def preparing(slots: Any) -> int:
    """How many workers are sampling an episode (`prepare`) rather than stepping it."""
    return sum(slots[k + 1] < 0 for k in range(0, len(slots), 2))


def running_fraction(slots: Any, expected: float | None) -> float:
    """Episodes' worth of work done inside the running episodes: each contributes its steps over
    `expected` (the mean length of this run's finished episodes) or, before any finished, over
    its step budget; at most 0.95 each, since a finished episode is counted by the caller."""
    total = 0.0
    for k in range(0, len(slots), 2):
        done, budget = slots[k], slots[k + 1]
        if budget > 0:
            total += min(done / min(expected or budget, budget), 0.95)
    return total
