"""Joint-angle accuracy on simulated protocols: RMSE against the simulator's truth.

For each protocol and seed, ``motionlab.simulate`` (preset, random mounting up to 30°, 5 s pauses
between steps and tasks) gives a session whose streams get what ``motionlab ingest`` does to every
recording (clock repair, gaps up to ``--gap-max`` filled, 0.1 s as ingest's default; longer
packet losses stay gaps, which fusion bridges from the sample times). Every sensor is fused with
the default estimator (the offline smoother), 6-D unless ``--mag``; ``calibrate`` and the angles
follow as ``motionlab run`` does them. RMSE (deg) per joint and plane over the protocol's task
blocks (true times; each joint read on its proximal sensor's clock) for four variants:

- ``recorded``: the preset as it is: every IMU has its own clock (offset σ 10 ms, drift σ 20 ppm
  in ``typical``) and its raw, uncalibrated errors; no clock sync;
- ``clock sync``: the same recording put on one clock by ``motionlab sync`` (the default of
  ``motionlab run``; :mod:`motionlab.clocksync`);
- ``clock sync + sensorcal``: and every sensor calibrated beforehand with ``motionlab
  sensorcal`` from a simulated calibration recording with the sensor's own error draws (each
  axis up and down at three headings, still for 4 s, joined by 1 s turns): accelerometer bias,
  scale and misalignment by the multi-position fit, gyroscope bias from the rest windows, with
  ``--mag`` the magnetometer's ellipsoid. The gyroscope's scale and misalignment stay (a still
  recording cannot show them). This is the full pipeline of the brief (sensor calibration,
  then mounting calibration);
- ``shared clock + sensorcal``: the IMUs share one clock (offset and drift 0; jitter and packet
  loss kept), as a radio-synchronised system's do: what a perfect clock sync would give.

A second table gives the clock differences left between neighbouring sensors (the sync's pairs)
before and after the sync, against the simulator's true sampling instants.

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
from collections import Counter
from functools import partial

import numpy as np
from seeds import seeds_arg

from motionlab import rotations as rot
from motionlab import timebase
from motionlab.clocksync import ClockFit, sync_tree, synchronise
from motionlab.fusion import estimate, get
from motionlab.ingest import DEFAULT_GAP_MAX
from motionlab.kinematics.session_angles import angle_table, nominal_calibration
from motionlab.protocol import Protocol, load_protocol
from motionlab.results import FusionEntry, Results
from motionlab.segments import calibrate_segments, segment_orientations, sensor_for_segment
from motionlab.segments.sensors import sensor_quats
from motionlab.sensorcal import apply_calibration
from motionlab.sensorcal.stage import calibrate_sensor, merge
from motionlab.session import SensorStream
from motionlab.simulate import simulate
from motionlab.simulate.errors import ChannelDraw, Preset, apply_channel, get_preset

PROTOCOLS = ("knee", "elbow", "lumbar", "upper_body_children")
VARIANTS = ("recorded", "clock sync", "clock sync + sensorcal", "shared clock + sensorcal")
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


def true_clock(session, truth, stamps: dict, label: str):
    """Function: session time of sensor ``label`` (its clock, corrected by the clock sync when
    that was applied) → true time (s), from the true instant of each recorded stamp."""
    st = stamps[label]
    sync = session.sensors[label].attrs.get("clock_sync")
    if sync is not None:
        st = ClockFit(**sync).corrected_time(st)
    return lambda t: truth.true_time(label, st, t)


def joint_clocks(session, truth, stamps: dict, protocol: Protocol) -> dict:
    """Per joint: its proximal sensor's :func:`true_clock` (session time → true time)."""
    return {
        name: true_clock(session, truth, stamps, sensor_for_segment(session, j.proximal))
        for name, j in protocol.joints.items()
    }


def errors(table: dict, truth, clocks: dict, protocol: Protocol, tasks: list) -> dict:
    """Per column: the error samples (deg) over the task blocks, where an angle is given (none
    inside a sensor's packet-loss gap, :func:`motionlab.kinematics.session_angles.in_gaps`).

    Each joint's angles are read on its proximal sensor's clock (``clocks[joint]``: session
    time → true time), so the truth is read at the true instants its sensors sampled: a joint
    angle's error is its own, whatever the other joints' clocks (the clock sync's accuracy
    between joints is reported on its own).
    """
    out = {}
    for col, values in table.items():
        if col == "time_s":
            continue
        joint = next(j for j in protocol.joints if col.startswith(f"{j}_"))
        true_time = clocks[joint](table["time_s"])
        inside = np.zeros(len(true_time), bool)
        for t0, t1 in tasks:
            inside |= (true_time >= t0) & (true_time <= t1)
        ref = np.interp(true_time, truth.time, truth.joint_angles[col])
        out[col] = (values - ref)[inside & np.isfinite(values)]  # none inside packet losses
    return out


def clock_errors(session, truth, protocol: Protocol, stamps: dict, tasks: list) -> dict:
    """Per sensor pair of the clock sync tree: the largest clock difference left over the task
    blocks (s): true instant of the sensor's sample minus the reference's, at one session time."""
    out = {}
    for ref, label in sync_pairs(session, protocol):
        t = session.sensors[ref].time
        t_ref = true_clock(session, truth, stamps, ref)(t)
        inside = np.zeros(len(t), bool)
        for t0, t1 in tasks:
            inside |= (t_ref >= t0) & (t_ref <= t1)
        diff = true_clock(session, truth, stamps, label)(t[inside]) - t_ref[inside]
        out[f"{ref}→{label}"] = float(np.max(np.abs(diff)))
    return out


def sync_pairs(session, protocol: Protocol) -> list[tuple[str, str]]:
    """(reference, sensor) labels of the clock sync's tree."""
    label = partial(sensor_for_segment, session)
    return [(label(a), label(b)) for a, b in sync_tree(session, protocol)]


def angles(
    session, truth, protocol: Protocol, args, nominal: bool = False, sync: bool = False
) -> dict:
    """RMSE per column of one prepared session (and with the calibration off), the clock
    differences left between sensor pairs (s), and messages."""
    session = dataclasses.replace(session, sensors=dict(session.sensors), results=Results())
    stamps = {label: s.time.copy() for label, s in session.sensors.items()}
    for label, s in session.sensors.items():  # as motionlab ingest does
        s, _ = timebase.repair_clock(s, label)
        session.sensors[label], _ = timebase.fill_short_gaps(s, args.gap_max)
    fits = synchronise(session, protocol) if sync else []
    fused = {}
    for label, s in session.sensors.items():
        mag = s.mag if args.mag else None
        res = estimate(args.estimator, s.gyr, s.acc, mag, rate=s.rate_hz, time=s.time)
        fused[label] = FusionEntry(res.name, res.quat, magnetometer=mag is not None)
    session.results.fusion = fused
    cal = calibrate_segments(session, protocol)
    quats = sensor_quats(session, protocol)
    tables = {"cal": angle_table(segment_orientations(protocol, cal, quats), protocol)}
    if nominal:
        off = nominal_calibration(protocol, cal.steps)
        tables["nominal"] = angle_table(segment_orientations(protocol, off, quats), protocol)
    tasks = [(s["start_s"], s["end_s"]) for s in truth.steps if s["phase"] == "task"]
    clocks = joint_clocks(session, truth, stamps, protocol)
    out = {}
    for key, table in tables.items():
        err = errors(table, truth, clocks, protocol, tasks)
        out[key] = {c: float(np.sqrt(np.mean(e**2))) for c, e in err.items()}
    out["clocks"] = clock_errors(session, truth, protocol, stamps, tasks)
    out["status"] = {f"{f.reference}→{f.sensor}": f.status for f in fits}
    out["messages"] = [m for s in cal.segments.values() for m in s.quality.messages]
    return out


def run_one(protocol: Protocol, seed: int, args) -> dict:
    """``{variant: {column: RMSE}}``, the calibration-off RMSE, the clock differences left per
    sensor pair (``{variant: {pair: s}}``), the sync's verdicts and the messages of one seed."""
    preset = get_preset(args.preset)
    sim = {"mounting_max_deg": args.mounting, "rest_s": REST_S}
    rec, truth = simulate(protocol, duration(protocol), seed, preset, **sim)
    rec_cal = dataclasses.replace(rec, sensors=dict(rec.sensors), results=Results())
    notes = sensor_calibrated(rec_cal, truth, preset, args.mag, seed)
    shared, truth_s = simulate(protocol, duration(protocol), seed, shared_clock(preset), **sim)
    notes += sensor_calibrated(shared, truth_s, preset, args.mag, seed)
    runs = {
        "recorded": angles(rec, truth, protocol, args, nominal=True),
        "clock sync": angles(rec, truth, protocol, args, sync=True),
        "clock sync + sensorcal": angles(rec_cal, truth, protocol, args, sync=True),
        "shared clock + sensorcal": angles(shared, truth_s, protocol, args),
    }
    return {
        **{v: r["cal"] for v, r in runs.items()},
        "nominal": runs["recorded"]["nominal"],
        "clocks": {v: r["clocks"] for v, r in runs.items()},
        "status": {v: runs[v]["status"] for v in ("clock sync", "clock sync + sensorcal")},
        "messages": runs["recorded"]["messages"] + [f"sensorcal {n}" for n in notes],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocols", default=",".join(PROTOCOLS))
    parser.add_argument("--seeds", type=seeds_arg, default="0,1,2")
    parser.add_argument("--preset", default="typical")
    parser.add_argument("--mounting", type=float, default=30.0, help="largest mounting error (°)")
    parser.add_argument("--estimator", default="default")
    parser.add_argument("--mag", action="store_true", help="9-D: fuse the magnetometer too")
    parser.add_argument(
        "--gap-max", type=float, default=DEFAULT_GAP_MAX, help="ingest --gap-max (s)"
    )
    args = parser.parse_args()
    seeds = args.seeds
    args.estimator = get(args.estimator).name
    print(f"estimator: {args.estimator} ({'9' if args.mag else '6'}-D), preset {args.preset}, "
          f"mounting ≤ {args.mounting:g}°, gaps ≤ {args.gap_max:g} s filled, seeds {seeds}; "
          "RMSE (deg) over the task blocks, mean / max over the seeds")  # fmt: skip
    print()
    head = " | ".join(f"{v} mean | max" for v in VARIANTS)
    print(f"| protocol | angle | target | {head} | calibration off (mean) |")
    print("|---|---|---:|" + "---:|---:|" * len(VARIANTS) + "---:|")
    notes, clock_rows = [], []
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
        for pair in runs[0]["clocks"]["recorded"]:
            cells = []
            for v in ("recorded", "clock sync", "clock sync + sensorcal"):
                ms = np.array([r["clocks"][v][pair] for r in runs]) * 1e3
                cells.append(f"{ms.mean():.1f} | {ms.max():.1f}")
            verdicts = Counter(r["status"][v].get(pair, "-") for r in runs for v in r["status"])
            said = ", ".join(f"{k} ×{n}" for k, n in verdicts.items())
            clock_rows.append(f"| {name} | {pair} | {' | '.join(cells)} | {said} |")
        for seed, r in zip(seeds, runs, strict=True):
            notes += [f"{name} seed {seed}: {m}" for m in r["messages"]]
        notes.append(f"{name}: {time.perf_counter() - t0:.0f} s for {len(seeds)} seeds")
    print()
    print("Clock differences between neighbouring sensors over the task blocks (ms; largest")
    print("|true instant of the sensor's sample − the reference's| at one session time), as")
    print("recorded and after `motionlab sync` on the raw and on the sensorcal-corrected data,")
    print("mean / max over the seeds, and the sync's verdicts (both variants):")
    print()
    print("| protocol | pair | recorded mean | max | synced mean | max | synced + sensorcal mean "
          "| max | verdicts |")  # fmt: skip
    print("|---|---|---:|---:|---:|---:|---:|---:|---|")
    for row in clock_rows:
        print(row)
    print()
    for n in notes:
        print(n)


if __name__ == "__main__":
    main()
