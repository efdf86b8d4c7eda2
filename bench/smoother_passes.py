"""Where the default smoother's time goes: µs of one thread's CPU per sample, per pass, on the
BROAD trials (9-D), interleaved with VQF's C++ ``offlineVQF`` on the same trial so that a change
of load hits both (the machine is shared); each trial's best of ``--repeat``.

Usage::

    python bench/smoother_passes.py [--data DIR] [--repeat 3] [--param key=value ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

from broad import DEFAULT_DATA, load_trials

from motionlab.fusion import estimate, mekf

#: the smoother's stages, timed by wrapping these functions of :mod:`motionlab.fusion.mekf`;
#: a function called more than once per run is listed per call (``_blocks #1``: the first)
STAGES = (
    "fusion_rest", "steady_mask", "_blocks", "field_gate", "lowpassed_acc", "_result",
)  # fmt: skip


def _wrapped(fn, name: str, acc: dict[str, float]):
    def timed(*args, **kwargs):
        calls = sum(1 for k in acc if k.startswith(name + " #"))
        t0 = time.thread_time()
        out = fn(*args, **kwargs)
        acc[f"{name} #{calls + 1}"] = time.thread_time() - t0
        return out

    return timed


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of BROAD *.hdf5")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per trial (best counts)")
    ap.add_argument("--param", action="append", default=[], help="key=value of the smoother")
    args = ap.parse_args(argv)
    params = dict(item.split("=", 1) for item in args.param)
    trials = load_trials(args.data)
    if not trials:
        sys.exit(f"error: no *.hdf5 trials in {args.data}")
    from vqf import offlineVQF

    stages: dict[str, float] = defaultdict(float)
    for attr in STAGES:
        if hasattr(mekf, attr):
            setattr(mekf, attr, _wrapped(getattr(mekf, attr), attr, stages))
    n_total = sum(len(tr["gyr"]) for tr in trials)
    warm = {k: trials[0][k][:2000] for k in ("gyr", "acc", "mag")}
    estimate("smoother", warm["gyr"], warm["acc"], warm["mag"], trials[0]["rate"])
    offlineVQF(warm["gyr"], warm["acc"], warm["mag"], 1.0 / trials[0]["rate"])
    best_vqf, best_sm = 0.0, 0.0
    best_stage: dict[str, float] = defaultdict(float)
    for tr in trials:
        vq, sm, st = [], [], []
        for _ in range(args.repeat):
            t0 = time.thread_time()
            offlineVQF(tr["gyr"], tr["acc"], tr["mag"], 1.0 / tr["rate"])
            vq.append(time.thread_time() - t0)
            stages.clear()
            t0 = time.thread_time()
            estimate("smoother", tr["gyr"], tr["acc"], tr["mag"], tr["rate"], **params)
            sm.append(time.thread_time() - t0)
            st.append(dict(stages))
        best_vqf += min(vq)
        i = min(range(len(sm)), key=sm.__getitem__)
        best_sm += sm[i]
        for k in st[0]:
            best_stage[k] += min(s.get(k, 0.0) for s in st)
    us = 1e6 / n_total
    print(f"BROAD, {len(trials)} trials, {n_total} samples, 9-D; µs of CPU per sample, best of "
          f"{args.repeat} per trial, interleaved\n")  # fmt: skip
    print("| pass | µs/sample |\n|---|---:|")
    for k in best_stage:
        print(f"| {k} | {best_stage[k] * us:.3f} |")
    print(f"| whole `estimate` | {best_sm * us:.3f} |")
    print(f"| offlineVQF | {best_vqf * us:.3f} |")
    print(f"\nsmoother / offlineVQF throughput: {best_vqf / best_sm:.2f}")


if __name__ == "__main__":
    main()
