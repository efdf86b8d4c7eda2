"""The benches' process pool: one BLAS thread per worker, as ``motionlab`` runs.

The CLI and ``motionlab batch`` run numpy with one OpenBLAS thread
(:data:`motionlab.cli.BLAS_THREADS`); a bench's pool of spawned workers would otherwise start
each with a thread per core, which spin on the same cores: two workers on two cores analysed
the simulated arm sessions of ``real_world.py`` in 10.2 s median against 2.5 s with one thread
each. The variables are set (unless the user set them) before the workers start, so that their
numpy loads with them; this process's own numpy is already loaded and keeps its threads.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from multiprocessing.pool import Pool

from motionlab.cli import BLAS_THREADS


def worker_pool(workers: int) -> Pool:
    """A pool of ``workers`` spawned processes, each with one BLAS thread."""
    for name, value in BLAS_THREADS.items():
        os.environ.setdefault(name, value)
    return mp.get_context("spawn").Pool(workers)
