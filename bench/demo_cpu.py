"""CPU seconds per stage of `motionlab demo`'s two runs, in this process (first or second).

    PYTHONPATH=. python3 bench/demo_cpu.py OUTDIR          # as `motionlab demo -o OUTDIR`

`run` prints each stage's wall time; on a shared machine those move with the load. This runs the
demo's two `run`s as the command does (`run_pipeline` on the bundled sessions) with each stage
also timed by `time.process_time()` (this process's CPU, all threads), and prints both, then the
whole process's CPU (imports included: the first `run` in a process pays for loading numpy,
scipy, numba and matplotlib). The command line's settings apply (``motionlab.cli`` is imported
first: one BLAS thread). Whether numba compiles is up to its cache: empty it
(`find motionlab -name '*.nb[ic]' -delete`) for the first run after an install.

Last, a machine reference: VQF's C++ ``offlineVQF`` over a fixed signal (with vqf installed),
and each run's CPU in units of it. Seconds differ between machines (the same code took 5.1-5.4
s and 3.0-3.1 s for the demo's knee run on two machines of one kind, docs/performance.md);
the ratio says whether a change of seconds is the code's or the machine's.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import time
from pathlib import Path

import numpy as np

import motionlab.cli  # noqa: F401  # first: the command's settings (one BLAS thread)
from motionlab import pipeline
from motionlab.cli.demo import DEMO_DIR, EXAMPLES

CPU: dict[str, float] = {}
RUN_CPU: dict[str, float] = {}  # each example's run, CPU s
REFERENCE_SAMPLES = 500_000
_call = pipeline._Stages.__call__


@contextlib.contextmanager
def _timed(self, name):
    c = time.process_time()
    with _call(self, name):
        yield
    CPU[name] = time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", type=Path, help="output folder, as `motionlab demo -o OUTDIR`")
    out = ap.parse_args().outdir
    pipeline._Stages.__call__ = _timed
    rows = []
    for name, (file, protocol) in EXAMPLES.items():
        CPU.clear()
        c, t = time.process_time(), time.perf_counter()
        options = pipeline.PipelineOptions(protocol, force=True, progress=False)
        pipeline.run_pipeline([DEMO_DIR / file], out / name, options)
        cpu, wall = time.process_time() - c, time.perf_counter() - t
        RUN_CPU[name] = cpu
        stages = ", ".join(f"{k} {v:.1f}" for k, v in CPU.items())
        rows.append(f"{name}: run {cpu:.1f} s CPU ({wall:.1f} s wall): {stages}")
    print("\n".join(rows))
    times = os.times()
    print(f"process: {times.user + times.system:.1f} s CPU (user+sys, imports included)")
    ref = reference_cpu()
    if ref is None:
        print("reference: vqf is not installed (pip install vqf), no machine reference")
        return
    ratios = ", ".join(f"{name} {cpu / ref:.1f}" for name, cpu in RUN_CPU.items())
    print(f"reference: offlineVQF over {REFERENCE_SAMPLES:,} samples {ref:.3f} s CPU (best of 3); "
          f"each run's CPU in references: {ratios}")  # fmt: skip


def reference_cpu() -> float | None:
    """CPU seconds (best of 3) of VQF's C++ ``offlineVQF`` (a fixed third-party workload) over
    :data:`REFERENCE_SAMPLES` deterministic 9-D samples at 100 Hz: seconds on this machine in
    units that do not move with motionlab's code, so that runs on two machines compare as
    ratios (``None`` without vqf)."""
    try:
        from vqf import offlineVQF
    except ImportError:
        return None
    rng = np.random.default_rng(0)
    n = REFERENCE_SAMPLES
    gyr = np.ascontiguousarray(np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0) % 2.0 - 1.0)
    acc = np.ascontiguousarray(rng.normal(0, 0.3, (n, 3)) + [0.0, 0.0, 9.81])
    mag = np.ascontiguousarray(rng.normal(0, 0.5, (n, 3)) + [20.0, 0.0, -40.0])
    best = np.inf
    for _ in range(3):
        c = time.process_time()
        offlineVQF(gyr, acc, mag, 0.01)
        best = min(best, time.process_time() - c)
    return best


if __name__ == "__main__":
    main()
