"""Particle filter vs MEKF vs VQF (online and offline) on the BROAD trials: total RMSE per trial.

Run by hand: ``python bench/particle_broad.py [--data DIR] [--n 1024] [--six-d]``.
Prints one table (degrees, RMS over the ``movement`` samples; Laidig et al. 2021 error
definitions via :func:`motionlab.validation.orientation_error.orientation_errors`) and the
particle filter's throughput in samples per second of CPU time and of wall time (one core, after
JIT warm-up; the wall time also counts waiting for a shared CPU).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import h5py
import numpy as np

from motionlab.fusion import estimate
from motionlab.fusion.particle import ParticleParams
from motionlab.validation.orientation_error import orientation_errors

DEFAULT = Path(__file__).resolve().parents[1].parent / "shared" / "datasets" / "broad"


def _vqf(gyr, acc, mag, rate, offline):
    from vqf import VQF, offlineVQF

    m = np.ascontiguousarray(mag) if mag is not None else None
    if offline:
        out = offlineVQF(gyr, acc, m, 1.0 / rate)
    else:
        out = VQF(1.0 / rate).updateBatch(gyr, acc, m)
    return out["quat9D" if mag is not None else "quat6D"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT)
    ap.add_argument("--n", type=int, default=1024, help="particles")
    ap.add_argument("--proposal", default=ParticleParams.proposal, help="vmf | bingham")
    ap.add_argument("--resampling", default=ParticleParams.resampling)
    ap.add_argument("--six-d", action="store_true", help="no magnetometer (inclination only)")
    args = ap.parse_args()
    files = sorted(args.data.glob("*.hdf5"))
    key = "inclination_rmse_deg" if args.six_d else "total_rmse_deg"
    cols = ("particle", "mekf", "vqf", "vqf_offline")
    print(f"{key} ({'6-D' if args.six_d else '9-D'}), N={args.n}, {args.proposal}, "
          f"{args.resampling}")  # fmt: skip
    print(f"{'trial':40s}" + "".join(f"{c:>12s}" for c in cols) + f"{'resets':>8s}")
    rows, cpu, wall = [], [], []
    for f in files:
        with h5py.File(f) as h:
            gyr, acc = h["imu_gyr"][:], h["imu_acc"][:]
            mag = None if args.six_d else h["imu_mag"][:]
            ref, move, rate = (
                h["opt_quat"][:],
                h["movement"][:].astype(bool),
                h.attrs["sampling_rate"],
            )
        t0, c0 = time.perf_counter(), time.process_time()
        pf = estimate("particle", gyr, acc, mag, rate=rate, n_particles=args.n,
                      proposal=args.proposal, resampling=args.resampling)  # fmt: skip
        cpu.append(len(gyr) / (time.process_time() - c0))
        wall.append(len(gyr) / (time.perf_counter() - t0))
        quats = {
            "particle": pf.quat,
            "mekf": estimate("mekf", gyr, acc, mag, rate=rate).quat,
            "vqf": _vqf(gyr, acc, mag, rate, False),
            "vqf_offline": _vqf(gyr, acc, mag, rate, True),
        }
        row = [orientation_errors(quats[c], ref, move)[key] for c in cols]
        rows.append(row)
        resets = len(pf.extra["resets"])
        print(f"{f.stem:40s}" + "".join(f"{v:12.2f}" for v in row) + f"{resets:8d}")
    print(f"{'mean':40s}" + "".join(f"{v:12.2f}" for v in np.mean(rows, axis=0)))
    print(f"{'max':40s}" + "".join(f"{v:12.2f}" for v in np.max(rows, axis=0)))
    for what, speed in (("CPU", cpu), ("wall", wall)):
        print(f"particle throughput ({what} time): median {np.median(speed[1:] or speed):.0f} "
              f"samples/s (first trial, with any JIT compile: {speed[0]:.0f})")  # fmt: skip


if __name__ == "__main__":
    main()
