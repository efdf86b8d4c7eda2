"""Joint-angle accuracy on simulated protocols: RMSE against the simulator's truth.

For each protocol and seed: ``motionlab.simulate`` (preset, random mounting up to 30°, 5 s pauses
between steps and tasks) gives the session, whose streams get what ``motionlab ingest`` does to
every recording (clock repair, gaps up to ``--gap-max`` filled, 0.1 s as ingest's default;
longer packet losses stay gaps, which the fusion filters integrate across as one sample); every
sensor is fused 6-D (no magnetometer) with the default estimator (the offline smoother) as
``motionlab fuse`` stores it; ``calibrate`` and the angles follow. RMSE (deg) per joint and
plane over the protocol's task blocks (true times) is printed for the calibrated angles and with
the calibration off (the protocol's nominal sensor placement, same heading alignment): the
difference is the cross-talk the calibration removes. Targets (issue 5): knee and elbow flexion
≤ 1.0°, other knee/elbow angles ≤ 2.0°, lumbar ≤ 1.5°.

Needs no data files. Usage::

    python bench/joint_angles.py [--protocols knee,elbow,...] [--seeds 0,1,2]
                                 [--preset typical] [--mounting 30] [--estimator default]
                                 [--gap-max 0.1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from motionlab import timebase
from motionlab.fusion import estimate, get
from motionlab.ingest import DEFAULT_GAP_MAX
from motionlab.kinematics.session_angles import (
    angle_table,
    nominal_calibration,
    sensor_quats,
)
from motionlab.protocol import Protocol, load_protocol
from motionlab.segments import calibrate, segment_orientations
from motionlab.simulate import simulate

PROTOCOLS = ("knee", "elbow", "lumbar", "upper_body_children")
TASK_S = 30.0  # simulated time per task
REST_S = 5.0  # pause between steps and tasks (3 s of stillness after the 2 s blend)


def target(column: str) -> float:
    """Target RMSE (deg) of an angle column."""
    if column.startswith("lumbar"):
        return 1.5
    return 1.0 if column.endswith("_flexion_deg") else 2.0


def duration(protocol: Protocol) -> float:
    """Recording length: the calibration steps, the tasks and the rests between them."""
    steps = sum(s.duration_s for s in protocol.calibration)
    blocks = len(protocol.calibration) + max(len(protocol.tasks), 1) + 1
    return steps + REST_S * blocks + TASK_S * max(len(protocol.tasks), 1)


def errors(table: dict, truth, stamps: np.ndarray, true: np.ndarray, tasks: list) -> dict:
    """Per column: the error samples (deg) over the task blocks.

    The table's time is the clock of the sensor whose ``stamps`` are given; ``true`` holds the
    true time of each of its samples (from the truth), so the truth is read at true times.
    """
    true_time = np.interp(table["time_s"], stamps, true)
    inside = np.zeros(len(true_time), bool)
    for t0, t1 in tasks:
        inside |= (true_time >= t0) & (true_time <= t1)
    out = {}
    for col, values in table.items():
        if col != "time_s":
            ref = np.interp(true_time, truth.time, truth.joint_angles[col])
            out[col] = (values - ref)[inside]
    return out


def run_one(
    protocol: Protocol, seed: int, preset: str, mounting: float, estimator: str, gap_max: float
) -> dict:
    """RMSE per column, calibrated and nominal, and the calibration quality, for one seed."""
    session, truth = simulate(
        protocol, duration(protocol), seed, preset, mounting_max_deg=mounting, rest_s=REST_S
    )
    stamps = {label: s.time.copy() for label, s in session.sensors.items()}
    for label, s in session.sensors.items():  # as motionlab ingest does
        s, _ = timebase.repair_clock(s, label)
        session.sensors[label], _ = timebase.fill_short_gaps(s, gap_max)
    fused = {}
    for label, s in session.sensors.items():
        res = estimate(estimator, s.gyr, s.acc, None, rate=s.rate_hz, time=s.time)
        fused[label] = {"name": res.name, "quat": res.quat}
    session.results["fusion"] = fused
    cal = calibrate(session, protocol)
    quats = sensor_quats(session, protocol)
    tables = {
        "cal": angle_table(segment_orientations(protocol, cal, quats), protocol),
        "nominal": angle_table(
            segment_orientations(protocol, nominal_calibration(protocol, cal["steps"]), quats),
            protocol,
        ),
    }
    tasks = [(s["start_s"], s["end_s"]) for s in truth.steps if s["phase"] == "task"]
    first = next(iter(protocol.joints.values())).proximal
    out = {}
    for key, table in tables.items():
        true = truth.sensors[first]["sample_time"]
        err = errors(table, truth, stamps[first], true, tasks)
        out[key] = {c: float(np.sqrt(np.mean(e**2))) for c, e in err.items()}
    out["messages"] = [m for s in cal["segments"].values() for m in s["quality"]["messages"]]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocols", default=",".join(PROTOCOLS))
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--preset", default="typical")
    parser.add_argument("--mounting", type=float, default=30.0, help="largest mounting error (°)")
    parser.add_argument("--estimator", default="default")
    parser.add_argument(
        "--gap-max", type=float, default=DEFAULT_GAP_MAX, help="ingest --gap-max (s)"
    )
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    est = get(args.estimator).name
    print(f"estimator: {est} (6-D), preset {args.preset}, mounting ≤ {args.mounting:g}°, "
          f"gaps ≤ {args.gap_max:g} s filled, seeds {seeds}; RMSE (deg), task blocks")  # fmt: skip
    print()
    print("| protocol | angle | RMSE mean | RMSE max | target | ok | calibration off (mean) |")
    print("|---|---|---:|---:|---:|:-:|---:|")
    notes = []
    for name in args.protocols.split(","):
        protocol = load_protocol(name)
        t0 = time.perf_counter()
        runs = [run_one(protocol, s, args.preset, args.mounting, est, args.gap_max) for s in seeds]
        for col in runs[0]["cal"]:
            cal = np.array([r["cal"][col] for r in runs])
            nom = np.array([r["nominal"][col] for r in runs])
            ok = "✓" if cal.max() <= target(col) else "✗"
            print(f"| {name} | {col} | {cal.mean():.2f} | {cal.max():.2f} | {target(col):.1f} | "
                  f"{ok} | {nom.mean():.2f} |")  # fmt: skip
        for seed, r in zip(seeds, runs, strict=True):
            notes += [f"{name} seed {seed}: {m}" for m in r["messages"]]
        notes.append(f"{name}: {time.perf_counter() - t0:.0f} s for {len(seeds)} seeds")
    print()
    for n in notes:
        print(n)


if __name__ == "__main__":
    main()
