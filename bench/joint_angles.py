"""Joint-angle accuracy on simulated protocols: RMSE against the simulator's truth.

For each protocol and seed, ``motionlab.simulate`` (preset, random mounting up to 30°, 5 s pauses
between steps and tasks) gives a session whose streams get what ``motionlab ingest`` does to every
recording (clock repair, gaps up to ``--gap-max`` filled, 0.1 s as ingest's default; longer
packet losses stay gaps, which fusion bridges from the sample times). Every sensor is fused with
the default estimator (the offline smoother), 6-D unless ``--mag``; ``calibrate`` and the angles
follow as ``motionlab run`` does them. RMSE (deg) per joint and plane over the protocol's task
blocks (true times) is printed for three variants of the recording:

- ``recorded``: the preset as it is: every IMU has its own clock (offset σ 10 ms, drift σ 20 ppm
  in ``typical``) and its raw, uncalibrated errors;
- ``shared clock``: the IMUs share one clock (offset and drift 0; jitter and packet loss kept),
  as the sensors of a synchronised system do and as motionlab assumes (it has no IMU-to-IMU
  synchronisation);
- ``+ sensorcal``: shared clock, and every sensor calibrated beforehand with ``motionlab
  sensorcal`` from a simulated calibration recording with the sensor's own error draws (each
  axis up and down at three headings, still for 4 s, joined by 1 s turns): accelerometer bias,
  scale and misalignment by the multi-position fit, gyroscope bias from the rest windows, with
  ``--mag`` the magnetometer's ellipsoid. The gyroscope's scale and misalignment stay (a still
  recording cannot show them).

With the calibration off (the protocol's nominal sensor placement, same heading alignment, the
``recorded`` variant) the same table shows the cross-talk the calibration removes. Targets
(issue 5): knee and elbow flexion ≤ 1.0°, other knee/elbow angles ≤ 2.0°, lumbar ≤ 1.5°; ✓/✗
marks the largest RMSE over the seeds.

Needs no data files. Usage::

    python bench/joint_angles.py [--protocols knee,elbow,...] [--seeds 0,1,2]
                                 [--preset typical] [--mounting 30] [--estimator default]
                                 [--mag] [--gap-max 0.1]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from motionlab import rotations as rot
from motionlab import timebase
from motionlab.fusion import estimate, get
from motionlab.ingest import DEFAULT_GAP_MAX
from motionlab.kinematics.session_angles import angle_table, nominal_calibration, sensor_quats
from motionlab.protocol import Protocol, load_protocol
from motionlab.segments import calibrate, segment_orientations
from motionlab.sensorcal import apply_calibration
from motionlab.sensorcal.stage import calibrate_sensor, merge
from motionlab.session import SensorStream
from motionlab.simulate import simulate
from motionlab.simulate.errors import ChannelDraw, Preset, apply_channel, get_preset

PROTOCOLS = ("knee", "elbow", "lumbar", "upper_body_children")
VARIANTS = ("recorded", "shared clock", "+ sensorcal")
TASK_S = 30.0  # simulated time per task
REST_S = 5.0  # pause between steps and tasks (3 s of stillness after the 2 s blend)
CAL_HOLD_S, CAL_TURN_S = 4.0, 1.0  # calibration recording: still pose, turn to the next
G = 9.81


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


def shared_clock(preset: Preset) -> Preset:
    """``preset`` with the IMUs on one clock: no offset or drift (jitter and packet loss kept)."""
    timing = dataclasses.replace(preset.timing, clock_offset_sigma_s=0.0, clock_drift_sigma=0.0)
    return dataclasses.replace(preset, timing=timing)


def calibration_poses() -> np.ndarray:
    """(18, 4) sensor → earth orientations: each sensor axis up and down (on a calibration cube,
    so that the multi-position fit knows the directions and finds the misalignment too), each
    at three headings (for the magnetometer's coverage)."""
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for n, d in enumerate(np.vstack([np.eye(3), -np.eye(3)])):  # q takes d to up
        axis, angle = np.cross(d, up), np.arccos(np.clip(d @ up, -1.0, 1.0))
        tilt = rot.from_axis_angle(axis if np.linalg.norm(axis) > 1e-9 else [1.0, 0, 0], angle)
        out += [rot.mul(rot.from_axis_angle(up, 0.7 * n + h), tilt) for h in (0.0, 2.1, 4.2)]
    return rot.make_continuous(np.array(out))


def calibration_recording(
    stream: SensorStream, info: dict, preset: Preset, field: np.ndarray, seed: int
) -> SensorStream:
    """A still-pose calibration recording of one simulated sensor with its own error draws."""
    rate = float(stream.attrs.get("rate_hz", 100.0))
    poses = calibration_poses()
    hold, turn = int(CAL_HOLD_S * rate), int(CAL_TURN_S * rate)
    quats, rates = [], []
    for a, b in zip(poses, np.vstack([poses[1:], poses[:1]]), strict=True):
        step = rot.to_rotvec(rot.mul(rot.conj(a), b))  # body frame, a → b
        frac = (np.arange(turn) + 1) / turn
        quats += [np.tile(a, (hold, 1)), rot.mul(a, rot.from_rotvec(frac[:, None] * step))]
        rates += [np.zeros((hold, 3)), np.tile(step / CAL_TURN_S, (turn, 1))]
    q, gyr = np.vstack(quats), np.vstack(rates)
    ideal = {
        "gyr": gyr,
        "acc": rot.rotate(rot.conj(q), np.array([0.0, 0.0, G])),
        "mag": rot.rotate(rot.conj(q), field) @ info["soft_iron"].T + info["hard_iron"],
    }
    rng = np.random.default_rng([seed, 7919])
    out = {
        ch: apply_channel(ideal[ch], getattr(preset, ch),
                          ChannelDraw(info[f"{ch}_bias"][0], info[f"{ch}_matrix"]), rate, rng)[0]
        for ch in ideal
    }  # fmt: skip
    return SensorStream(stream.label, np.arange(len(q)) / rate, serial=stream.serial, **out)


def sensor_calibrated(session, truth, preset: Preset, mag: bool, seed: int) -> list[str]:
    """Calibrate every sensor of ``session`` in place from its simulated calibration recording;
    returns the notes of kinds that could not be fitted."""
    kinds = ("gyro", "multipos") + (("mag",) if mag else ())
    field = np.asarray(truth.config["earth_field_uT"], float)
    notes = []
    for label, s in session.sensors.items():
        rec = calibration_recording(s, truth.sensors[label], preset, field, seed)
        results, skipped = calibrate_sensor(rec, kinds)
        notes += [f"{label}: {v}" for v in skipped.values()]
        session.sensors[label] = apply_calibration(s, merge(None, rec, results, "simulated", True))
    return notes


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


def angles(session, truth, protocol: Protocol, args, nominal: bool = False) -> dict:
    """RMSE per column of one prepared session (and with the calibration off), and messages."""
    stamps = {label: s.time.copy() for label, s in session.sensors.items()}
    for label, s in session.sensors.items():  # as motionlab ingest does
        s, _ = timebase.repair_clock(s, label)
        session.sensors[label], _ = timebase.fill_short_gaps(s, args.gap_max)
    fused = {}
    for label, s in session.sensors.items():
        mag = s.mag if args.mag else None
        res = estimate(args.estimator, s.gyr, s.acc, mag, rate=s.rate_hz, time=s.time)
        fused[label] = {"name": res.name, "quat": res.quat}
    session.results["fusion"] = fused
    cal = calibrate(session, protocol)
    quats = sensor_quats(session, protocol)
    tables = {"cal": angle_table(segment_orientations(protocol, cal, quats), protocol)}
    if nominal:
        off = nominal_calibration(protocol, cal["steps"])
        tables["nominal"] = angle_table(segment_orientations(protocol, off, quats), protocol)
    tasks = [(s["start_s"], s["end_s"]) for s in truth.steps if s["phase"] == "task"]
    first = next(iter(protocol.joints.values())).proximal
    out = {}
    for key, table in tables.items():
        true = truth.sensors[first]["sample_time"]
        err = errors(table, truth, stamps[first], true, tasks)
        out[key] = {c: float(np.sqrt(np.mean(e**2))) for c, e in err.items()}
    out["messages"] = [m for s in cal["segments"].values() for m in s["quality"]["messages"]]
    return out


def run_one(protocol: Protocol, seed: int, args) -> dict:
    """``{variant: {column: RMSE}}``, the calibration-off RMSE and the messages of one seed."""
    preset = get_preset(args.preset)
    sim = {"mounting_max_deg": args.mounting, "rest_s": REST_S}
    rec, truth = simulate(protocol, duration(protocol), seed, preset, **sim)
    recorded = angles(rec, truth, protocol, args, nominal=True)
    shared, truth_s = simulate(protocol, duration(protocol), seed, shared_clock(preset), **sim)
    calibrated = dataclasses.replace(shared, sensors=dict(shared.sensors), results={})
    notes = sensor_calibrated(calibrated, truth_s, preset, args.mag, seed)
    synced = angles(shared, truth_s, protocol, args)
    both = angles(calibrated, truth_s, protocol, args)
    return {
        "recorded": recorded["cal"],
        "shared clock": synced["cal"],
        "+ sensorcal": both["cal"],
        "nominal": recorded["nominal"],
        "messages": recorded["messages"] + [f"sensorcal {n}" for n in notes],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocols", default=",".join(PROTOCOLS))
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--preset", default="typical")
    parser.add_argument("--mounting", type=float, default=30.0, help="largest mounting error (°)")
    parser.add_argument("--estimator", default="default")
    parser.add_argument("--mag", action="store_true", help="9-D: fuse the magnetometer too")
    parser.add_argument(
        "--gap-max", type=float, default=DEFAULT_GAP_MAX, help="ingest --gap-max (s)"
    )
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    args.estimator = get(args.estimator).name
    print(f"estimator: {args.estimator} ({'9' if args.mag else '6'}-D), preset {args.preset}, "
          f"mounting ≤ {args.mounting:g}°, gaps ≤ {args.gap_max:g} s filled, seeds {seeds}; "
          "RMSE (deg) over the task blocks, mean / max over the seeds")  # fmt: skip
    print()
    head = " | ".join(f"{v} mean | max" for v in VARIANTS)
    print(f"| protocol | angle | target | {head} | calibration off (mean) |")
    print("|---|---|---:|" + "---:|---:|" * len(VARIANTS) + "---:|")
    notes = []
    for name in args.protocols.split(","):
        protocol = load_protocol(name)
        t0 = time.perf_counter()
        runs = [run_one(protocol, s, args) for s in seeds]
        for col in runs[0]["recorded"]:
            cells = []
            for v in VARIANTS:
                x = np.array([r[v][col] for r in runs])
                ok = "✓" if x.max() <= target(col) else "✗"
                cells.append(f"{x.mean():.2f} | {x.max():.2f} {ok}")
            nom = np.mean([r["nominal"][col] for r in runs])
            print(f"| {name} | {col} | {target(col):.1f} | {' | '.join(cells)} | {nom:.2f} |")
        for seed, r in zip(seeds, runs, strict=True):
            notes += [f"{name} seed {seed}: {m}" for m in r["messages"]]
        notes.append(f"{name}: {time.perf_counter() - t0:.0f} s for {len(seeds)} seeds")
    print()
    for n in notes:
        print(n)


if __name__ == "__main__":
    main()
