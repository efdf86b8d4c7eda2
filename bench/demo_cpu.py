"""CPU seconds per stage of `motionlab demo`'s two runs, in this process (first or second).

    PYTHONPATH=. python3 bench/demo_cpu.py OUTDIR          # as `motionlab demo -o OUTDIR`

`run` prints each stage's wall time; on a shared machine those move with the load. This runs the
demo's two `run`s as the command does (`run_pipeline` on the bundled sessions) with each stage
also timed by `time.process_time()` (this process's CPU, all threads), and prints both, then the
whole process's CPU (imports included: the first `run` in a process pays for loading numpy,
scipy, numba and matplotlib). The command line's settings apply (``motionlab.cli`` is imported
first: one BLAS thread). Whether numba compiles is up to its cache: empty it
(`find motionlab -name '*.nb[ic]' -delete`) for the first run after an install.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import time
from pathlib import Path

import motionlab.cli  # noqa: F401  # first: the command's settings (one BLAS thread)
from motionlab import pipeline
from motionlab.cli.demo import DEMO_DIR, EXAMPLES

CPU: dict[str, float] = {}
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
        stages = ", ".join(f"{k} {v:.1f}" for k, v in CPU.items())
        rows.append(f"{name}: run {cpu:.1f} s CPU ({wall:.1f} s wall): {stages}")
    print("\n".join(rows))
    times = os.times()
    print(f"process: {times.user + times.system:.1f} s CPU (user+sys, imports included)")


if __name__ == "__main__":
    main()
