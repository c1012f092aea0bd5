"""Threads of an environment that runs in a worker process of a vector env (`gymnasium.make_vec(...,
vectorization_mode="async")`), one of several on the machine.

Each worker process otherwise brings a BLAS thread pool per library (numpy's and scipy's OpenBLAS:
one thread per core each, measured with `threadpoolctl` in a worker) and lavapipe, when it renders
on the CPU, one rasteriser thread per core: N workers on N cores would hold N x cores threads. A
worker steps one environment at a time, so it gets one thread of each; the environment's own
listening thread (`echo_data.envs.listener`) is the only extra one. The main process (a learner
with torch, say) is left alone: only child processes of `multiprocessing` are pinned.
"""

from __future__ import annotations

import multiprocessing
import os
import sys

WORKER_THREADS = {"LP_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def in_worker_process() -> bool:
    """True in a child process made by `multiprocessing` (a vector env's worker, a build worker)."""
    return multiprocessing.parent_process() is not None


def pin_worker_threads() -> bool:
    """In a worker process: one thread per pool (set where not already set by the user; pools that
    exist already are limited through `threadpoolctl` when it is installed; torch if imported).
    Returns whether it pinned anything (False in the main process)."""
    if not in_worker_process():
        return False
    for k, v in WORKER_THREADS.items():
        os.environ.setdefault(k, v)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: the environment variables still hold for pools made from here on
        pass
    else:
        threadpool_limits(int(os.environ["OPENBLAS_NUM_THREADS"]))
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(int(os.environ["OMP_NUM_THREADS"]))
    return True
