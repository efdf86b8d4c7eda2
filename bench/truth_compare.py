"""A ``motionlab run`` output of a simulated recording against the simulator's truth.

Every angle column of the output's CSVs is read against ``truth.joint_angles`` at the true
instants of its samples: the output's ``time_s`` is the clock sync's reference sensor's clock
(each sensor's own when the sync was not applied), so each joint is read on its proximal
sensor's clock, corrected by the sync's fit when applied, mapped to the true time through that
sensor's recorded stamps and their true instants (:meth:`motionlab.simulate.truth.Truth.true_time`,
as ``bench/real_world.py`` reads them). ``naive`` is the RMSE with ``time_s`` taken as the true
time, which the clock's offset puts out of step (a 240-s walk, seed 4: the pelvis's clock 23 ms
off, knee flexion 5.4° / 5.7° instead of 2.0° / 2.5°). Per column: grade, RMSE (deg), mean error,
offset-free RMSE (SD), per-minute RMSE.

Usage::

    python bench/truth_compare.py OUTPUT_DIR SESSION.h5 TRUTH.h5 [--protocol NAME]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from joint_angles import joint_clocks

from motionlab.protocol import load_protocol
from motionlab.session import load_session
from motionlab.simulate.truth import load_truth


def minute_rmse(t: np.ndarray, e: np.ndarray) -> list[float]:
    """RMSE (deg) of ``e`` per whole minute of ``t`` (s) with more than 100 samples."""
    out = []
    for m in range(int(t[-1] // 60) + 1):
        inside = (t >= 60 * m) & (t < 60 * (m + 1))
        if inside.sum() > 100:
            out.append(float(np.sqrt(np.mean(e[inside] ** 2))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("output", type=Path, help="the run's output folder (session.h5, csv/)")
    ap.add_argument("session", type=Path, help="the simulated recording (its recorded stamps)")
    ap.add_argument("truth", type=Path, help="the simulator's truth file")
    ap.add_argument("--protocol", help="the protocol run (default: the recording's metadata)")
    args = ap.parse_args()
    truth = load_truth(args.truth)
    recorded = load_session(args.session)
    protocol = load_protocol(args.protocol or recorded.metadata["protocol"])
    stamps = {label: s.time for label, s in recorded.sensors.items()}
    clocks = joint_clocks(load_session(args.output / "session.h5"), truth, stamps, protocol)
    grades = pd.read_csv(args.output / "csv" / "grades.csv").set_index("column")["grade"]
    print(f"{'column':24s} {'grade':15s} {'naive':>6s} {'rms':>6s} {'bias':>6s} {'sd':>6s}  "
          "per-minute rms")  # fmt: skip
    for path in sorted((args.output / "csv").glob("*_angles.csv")):
        table = pd.read_csv(path)
        t = table["time_s"].to_numpy()
        for col in table.columns[1:]:
            if col not in truth.joint_angles:
                continue
            values = table[col].to_numpy()
            ok = np.isfinite(values)
            if not ok.any():
                print(f"{col:24s} {grades.get(col, '?'):15s} no values")
                continue
            true_t = clocks[next(j for j in protocol.joints if col.startswith(f"{j}_"))](t)
            e = (values - np.interp(true_t, truth.time, truth.joint_angles[col]))[ok]
            naive = (values - np.interp(t, truth.time, truth.joint_angles[col]))[ok]
            per_min = " ".join(f"{v:.1f}" for v in minute_rmse(true_t[ok], e))
            print(
                f"{col:24s} {grades.get(col, '?'):15s} {np.sqrt(np.mean(naive**2)):6.2f} "
                f"{np.sqrt(np.mean(e**2)):6.2f} {e.mean():+6.2f} {e.std():6.2f}  {per_min}"
            )


if __name__ == "__main__":
    main()
