"""Throughput: samples per second of every registered estimator on the BROAD trials.

Each estimator is warmed up first (numba compilation, caches), then timed end to end through
``motionlab.fusion.estimate`` (input validation, detectors and the filter) in 9-D over all
trials; each trial's best of ``--repeat`` runs counts. The ratio is to VQF's C++ ``offlineVQF``
timed in the same run on the same data.

Usage::

    python bench/throughput.py [--data DIR] [--filters a,b,...] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from broad import DEFAULT_DATA, load_trials

from motionlab.fusion import available, estimate


def _time(fn, trials: list[dict], repeat: int) -> float:
    """Wall time (s) over all trials, each trial's best of ``repeat`` runs (the machine is
    shared, so the minimum is the least disturbed measurement)."""
    total = 0.0
    for tr in trials:
        best = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            fn(tr)
            best = min(best, time.perf_counter() - t0)
        total += best
    return total


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of BROAD *.hdf5")
    ap.add_argument("--filters", default="", help="comma-separated estimators (default: all)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per trial (best counts)")
    args = ap.parse_args(argv)
    trials = load_trials(args.data)
    if not trials:
        sys.exit(f"error: no *.hdf5 trials in {args.data}")
    names = [n for n in args.filters.split(",") if n] or list(available())
    n_samples = sum(len(tr["gyr"]) for tr in trials)

    try:
        from vqf import offlineVQF
    except ModuleNotFoundError:
        sys.exit("error: the 'vqf' package is needed for the reference (pip install vqf)")

    def vqf_raw(tr):
        offlineVQF(tr["gyr"], tr["acc"], tr["mag"], 1.0 / tr["rate"])

    vqf_raw(trials[0])
    ref = n_samples / _time(vqf_raw, trials, args.repeat)

    rows = []
    for name in names:

        def fn(tr, name=name):
            estimate(name, tr["gyr"], tr["acc"], tr["mag"], tr["rate"])

        warm = dict(trials[0])
        for key in ("gyr", "acc", "mag"):
            warm[key] = trials[0][key][:2000]
        fn(warm)
        rows.append((name, n_samples / _time(fn, trials, args.repeat)))

    print(
        f"Throughput on {len(trials)} BROAD trials ({n_samples} samples, 9-D), best of "
        f"{args.repeat}\n"
    )
    print("| estimator | samples/s | ratio to offlineVQF |")
    print("|---|---:|---:|")
    print(f"| offlineVQF (C++, direct) | {ref:,.0f} | 1.00 |")
    for name, rate in sorted(rows, key=lambda r: -r[1]):
        print(f"| {name} | {rate:,.0f} | {rate / ref:.2f} |")


if __name__ == "__main__":
    main()
