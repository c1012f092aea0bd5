"""The environment's listening thread: a step's audio heard on it (with idle-time RIR prefetch) is
bit for bit what the same calls give in the caller's thread; a vector env's worker pins its thread pools."""

from __future__ import annotations

import multiprocessing
import time

import numpy as np
from test_env_audio_online import _spec

from echo_data.envs.audio import OnlineTrack
from echo_data.envs.listener import listener
from echo_data.envs.workers import pin_worker_threads
from echo_data.recipe import Recipe
from echo_data.sounds import SoundLibrary


def test_heard_on_the_thread_with_prefetch_equals_heard_inline() -> None:
    """A head turning 4 degrees a step (a new yaw bin every step or two), one source resolved
    mid-way: blocks, spectrograms and log-mels identical; the thread's idle time computed RIRs
    that the steps then found cached."""
    recipe = Recipe(name="t")
    lib = SoundLibrary.builtin()
    spec = _spec(recipe, lib)
    x, y, yaw = spec.start
    poses = [(x + 0.03 * t, y, recipe.acoustics.ear_height, yaw + 0.07 * t) for t in range(24)]
    inline, threaded = OnlineTrack(spec, recipe, lib), OnlineTrack(spec, recipe, lib)
    for tr in (inline, threaded):
        tr.pre_roll(poses[0])
    ears = listener()
    assert ears.prefetch
    for t, pose in enumerate(poses):
        silenced = [0] if t == 10 else []
        a = inline.hear(pose, silenced=silenced)
        b = threaded.hear_soon(pose, silenced=silenced).result()
        for u, v in zip(a, b):
            assert u.dtype == v.dtype and np.array_equal(u, v)
        time.sleep(0.05)  # idle time between steps, as while the cameras render
    assert np.array_equal(inline.finish(), threaded.finish())
    ahead = threaded.epochs[0].cache.rirs_computed - inline.epochs[0].cache.rirs_computed
    assert ahead > 0  # the prefetch ran (and its keys are the next yaw bins, so most were used)


def _pinned() -> tuple[bool, list[int]]:
    from threadpoolctl import threadpool_info

    return pin_worker_threads(), [p["num_threads"] for p in threadpool_info()]


def test_a_worker_process_pins_its_thread_pools_and_the_main_process_does_not() -> None:
    assert pin_worker_threads() is False
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        pinned, threads = pool.apply(_pinned)
    assert pinned and threads and set(threads) == {1}
