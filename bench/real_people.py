"""Real people, no reference: every shipped protocol that fits each recording of
``../shared/datasets/human/``, run as ``motionlab run`` runs it.

Without a truth this bench cannot say "accurate". It says what a careful reader of the report
would check: the grade of every angle; for a hinge-like joint, the per-cycle range of its first
angle (a walking knee flexes about 55-70° per stride at a usual pace, Perry & Burnfield 2010,
further at a faster one: the verdict gives the walk's cadence and speed; ``implausible``
outside 45-80°) and the left/right difference; the angle between the independent estimates of
the joint's axis (the principal rotation axes and the constrained hinge fit, ``witness``); the
hinge fit's relative residual; for a knee in a walk, the thigh's angular speed over the
shank's (95th percentiles over the swings: above 1.25 the calibration refuses the two as
swapped, :mod:`motionlab.segments.gait_axes`); where the recording carries the vendor's own 9-D
orientations, the per-cycle range of the joint's rotation away from the stand from them (a
figure no axis choice can move, but one that counts the knee's axial rotation at extension
as a turn away from the stand) and the angle the vendor's relative orientation turns between the
instants of the cycle's lowest and highest first angle (how far the joint turned between its
extreme poses, whatever the axis: a witness for the flexion range); and, for a hinge joint,
the per-stride range of the gyroscopes' relative rate about the calibrated axes integrated
over the stride (no fusion involved: a fused flexion range far from it points at the fusion,
not the knee). Every per-cycle figure is taken from its angle low-passed as the product's
metrics take theirs (:func:`motionlab.kinematics.angle_filter.smoothed`, 6 Hz: a sensor's wobble at
heel strike is not a peak), so that the witnesses compare like with like. A protocol that
refuses a recording prints its one line instead.

Recordings (README of ``../shared``, section ``datasets/human``):

- ``qmt_full_body``: 16 Xsens sensors, 100 Hz; a stand (40-44 s), sitting down, a seated rest,
  standing up, then about 45 s of walking; the ``walk`` protocol (pelvis = ``hip``) and the
  ``arm`` protocol (thorax = ``upper_back``); one time vector ``t`` for every sensor, so one
  clock (marked as the readers mark one time column: the clock sync keeps the stamps);
- ``imt_dot/knee_tracking1``, ``knee_tracking2``: one Xsens DOT on the thigh and one on the
  shank (one leg; mapped as the right), free leg movement and walking throughout with no rest
  longer than about a second (the first starts seated): the ``walk`` protocol refuses both in
  one line, naming the stand it needs;
- ``imt_dot/shoulder_tracking``: chest and upper arm (no shipped protocol has a joint for them).

The walk cut short as a clinic records it (a stand and 10-25 s of walking):
``bench/real_short_walks.py``.

Usage::

    python bench/real_people.py [--data ../shared] [--only qmt,knee_tracking1,...]
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np
import scipy.io as sio
import yaml

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.errors import InputError
from motionlab.io.clock import mark_shared_clock
from motionlab.kinematics.angle_filter import as_metrics_take, smoothed
from motionlab.kinematics.joint_types import angle_columns
from motionlab.pipeline import PipelineOptions, analyse, load_inputs, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.session import SensorStream, Session, estimate_rate

WALK_RANGE_DEG = (45.0, 80.0)  # per-stride knee flexion range a walking knee can have
GYRO_MARGIN_S = 0.25  # s integrated before and after each stride for the gyroscopes' witness
QMT_WALK = ("hip", "upper_leg_right", "lower_leg_right", "upper_leg_left", "lower_leg_left")
QMT_SEGMENTS = {
    "walk": {"hip": "pelvis", "upper_leg_right": "thigh_r", "lower_leg_right": "shank_r",
             "upper_leg_left": "thigh_l", "lower_leg_left": "shank_l"},
    "arm": {"upper_back": "thorax", "upper_arm_right": "upperarm_r",
            "forearm_right": "forearm_r", "upper_arm_left": "upperarm_l",
            "forearm_left": "forearm_l"},
}  # fmt: skip
DOT = {
    "knee_tracking1": {"femur": "thigh_r", "tibia": "shank_r"},
    "knee_tracking2": {"femur": "thigh_r", "tibia": "shank_r"},
    "shoulder_tracking": {"chest": "thorax", "upperarm": "upperarm_r"},
}


def qmt_session(data: Path, protocol: str) -> tuple[Session, dict[str, np.ndarray]]:
    """The full-body recording's sensors for ``protocol`` as a session (time from 0 s), and the
    vendor's orientations by segment."""
    m = sio.loadmat(data / "full_body_example_data.mat", squeeze_me=True, struct_as_record=False)
    t = np.asarray(m["t"], float)
    session, vendor = Session(), {}
    for name, seg in QMT_SEGMENTS[protocol].items():
        d = m[name]
        session.sensors[seg] = SensorStream(
            label=seg, time=t - t[0], acc=np.asarray(d.acc, float), gyr=np.asarray(d.gyr, float),
            segment=seg, vendor="Xsens", source_units={"acc": "m/s^2", "gyr": "rad/s"},
        )  # fmt: skip
        vendor[seg] = rot.make_continuous(np.asarray(d.quat, float))
    # one time vector for every IMU: one clock, as the readers take one time column
    mark_shared_clock(list(session.sensors.values()), "one time vector t in the .mat file")
    prepare_sensors(session)
    return session, vendor


def dot_session(folder: Path, mapping: dict[str, str]) -> Session:
    """A DOT recording read as ``motionlab ingest`` reads it, with a sensor map."""
    sensors = {f.capitalize(): {"segment": seg} for f, seg in mapping.items()}
    with tempfile.TemporaryDirectory() as tmp:
        map_path = Path(tmp) / "map.yaml"
        map_path.write_text(yaml.safe_dump({"sensors": sensors}))
        return load_inputs([folder / f"{f}.csv" for f in mapping], map_path, "bench")


def stride_ranges(session: Session, column: str, side: str) -> np.ndarray:
    """Range (deg) of ``column`` in each stride of ``side`` (between consecutive initial
    contacts 0.6-1.8 s apart); empty without a gait analysis."""
    gait, angles = session.results.gait, session.results.angles
    if gait is None or not gait.ok or side not in (gait.events or {}):
        return np.array([])
    t = np.asarray(angles.time)
    x = as_metrics_take(angles, column)
    ic = np.asarray(gait.events[side].ic, float)
    out = []
    for a, b in zip(ic[:-1], ic[1:], strict=True):
        sel = (t >= a) & (t <= b)
        if 0.6 <= b - a <= 1.8 and sel.sum() > 10 and np.isfinite(x[sel]).all():
            out.append(np.ptp(x[sel]))
    return np.array(out)


def vendor_ranges(session: Session, vendor: dict, joint, side: str) -> np.ndarray:
    """Per-stride range (deg) of the joint's rotation away from the stand, from the vendor's
    orientations (no axis involved)."""
    gait, cal = session.results.gait, session.results.calibration
    stand = (cal.steps or {}).get("standing")
    if not vendor or gait is None or not gait.ok or not stand:
        return np.array([])
    t = session.sensors[joint.proximal].time
    rel = rot.mul(rot.conj(vendor[joint.proximal]), vendor[joint.distal])
    sel = (t >= stand[0]) & (t <= stand[1])
    r = rot.mul(rel, rot.conj(rot.mean(rel[sel])))
    angle = np.degrees(2.0 * np.arccos(np.clip(np.abs(r[:, 0]), 0.0, 1.0)))
    angle = smoothed(angle, estimate_rate(t))
    ic = np.asarray(gait.events[side].ic, float)
    pairs = [(a, b) for a, b in zip(ic[:-1], ic[1:], strict=True) if 0.6 <= b - a <= 1.8]
    return np.array([np.ptp(angle[(t >= a) & (t <= b)]) for a, b in pairs])


def vendor_swings(session: Session, vendor: dict, joint, column: str, side: str) -> np.ndarray:
    """Per stride, the angle (deg) of the vendor's relative orientation between the instants of
    our ``column``'s lowest and highest value: how far the joint turned between its extreme poses,
    whatever the axis (no calibration, no frame, no stand involved)."""
    gait, angles = session.results.gait, session.results.angles
    if not vendor or gait is None or not gait.ok or side not in (gait.events or {}):
        return np.array([])
    t = session.sensors[joint.proximal].time
    rel = rot.mul(rot.conj(vendor[joint.proximal]), vendor[joint.distal])
    ta = np.asarray(angles.time)
    x = as_metrics_take(angles, column)
    ic = np.asarray(gait.events[side].ic, float)
    out = []
    for a, b in zip(ic[:-1], ic[1:], strict=True):
        k = np.flatnonzero((ta >= a) & (ta <= b) & np.isfinite(x))
        if 0.6 <= b - a <= 1.8 and len(k) > 10:
            lo, hi = (
                rel[np.argmin(np.abs(t - ta[i]))] for i in (k[np.argmin(x[k])], k[np.argmax(x[k])])
            )
            d = rot.mul(rot.conj(lo), hi)
            out.append(np.degrees(2.0 * np.arccos(min(1.0, abs(float(d[0]))))))
    return np.array(out)


def gyro_ranges(session: Session, jname: str, joint, side: str) -> np.ndarray:
    """Per-stride range (deg) of the hinge angle integrated from the gyroscopes alone: the
    distal rate about the distal axis less the proximal rate about the proximal axis (the
    calibrated axes), integrated from :data:`GYRO_MARGIN_S` before each stride to as long after
    it with the drift removed linearly (the joint is back where it was at the next initial
    contact), low-passed there and its range taken over the stride (the margins keep the
    filter's ends off the heel strikes)."""
    gait, fit = session.results.gait, session.results.calibration.hinges.get(jname)
    if gait is None or not gait.ok or fit is None:
        return np.array([])
    prox, dist = (session.sensors[sensor_for_segment(session, seg)]
                  for seg in (joint.proximal, joint.distal))  # fmt: skip
    t = prox.time
    rate = np.interp(t, dist.time, dist.gyr @ fit.axis_distal) - prox.gyr @ fit.axis_proximal
    fs = estimate_rate(t)
    ic = np.asarray(gait.events[side].ic, float)
    out = []
    for a, b in zip(ic[:-1], ic[1:], strict=True):
        wide = (t >= a - GYRO_MARGIN_S) & (t <= b + GYRO_MARGIN_S)
        if 0.6 <= b - a <= 1.8 and wide.sum() > 10:
            tw = t[wide]
            angle = np.degrees(np.cumsum(rate[wide] * np.gradient(tw)))
            ends = np.interp([a, b], tw, angle)
            trend = ends[0] + (ends[1] - ends[0]) * (tw - a) / (b - a)
            angle = smoothed(angle - trend, fs)
            out.append(np.ptp(angle[(tw >= a) & (tw <= b)]))
    return np.array(out)


def _fmt(x: np.ndarray) -> str:
    if not len(x):
        return "–"
    q1, q2, q3 = np.percentile(x, [25, 50, 75])
    return f"{q2:.0f} ({q1:.0f}–{q3:.0f}), n={len(x)}"


def _plausibility(ranges: np.ndarray, session: Session) -> str:
    """Whether a walking knee's per-stride flexion ranges (deg) are plausible (median within
    ``WALK_RANGE_DEG``), with the share of strides inside and the walk's pace (the band is for
    walkers at a usual pace; a knee flexes further at a faster one)."""
    lo, hi = WALK_RANGE_DEG
    inside = np.mean((ranges >= lo) & (ranges <= hi))
    word = "plausible" if lo <= np.median(ranges) <= hi else "implausible"
    gait = session.results.gait
    pace = gait.summary if gait is not None and gait.summary is not None else None
    at = ""
    if pace is not None and np.isfinite(pace.cadence_steps_per_min):
        at = f"; {pace.cadence_steps_per_min:.0f} steps/min"
        if np.isfinite(pace.walking_speed_m_s):  # with the subject's height or leg lengths
            at += f", {pace.walking_speed_m_s:.1f} m/s"
    return f"{word} ({100 * inside:.0f}% of strides in {lo:.0f}–{hi:.0f}°{at})"


def report(name: str, protocol: str, session: Session, vendor: dict) -> list[str]:
    """Table rows of one analysed recording."""
    cal = session.results.calibration
    joints = {k: j for k, j in load_protocol(protocol).joints.items() if k in cal.grades}
    flex = {
        k: stride_ranges(session, angle_columns(j)[0][1], j.side) if j.side else np.array([])
        for k, j in joints.items()
    }
    rows = []
    for jname, joint in joints.items():
        rng, fit = flex[jname], cal.hinges.get(jname)
        other = flex.get(jname[:-1] + ("l" if jname.endswith("r") else "r"), np.array([]))
        diff = f"{abs(np.median(rng) - np.median(other)):.0f}°" if len(rng) and len(other) else "–"
        verdict = _plausibility(rng, session) if len(rng) and joint.type == "knee" else ""
        peer = vendor_ranges(session, vendor, joint, joint.side) if joint.side else np.array([])
        column = angle_columns(joint)[0][1]
        swing = vendor_swings(session, vendor, joint, column, joint.side) if joint.side else []
        gyro = gyro_ranges(session, jname, joint, joint.side) if joint.side else np.array([])
        rows.append(
            f"| {name} | {protocol} | {jname} | {' / '.join(cal.grades[jname].grades)} | "
            f"{_fmt(rng)} | {_fmt(gyro)} | {_fmt(peer)} | {_fmt(np.asarray(swing))} | {diff} | "
            f"{_num(fit.witness_deg if fit else None)} | "
            f"{_num(fit.relative_residual if fit else None, 2)} | "
            f"{_num(fit.consistency_deg if fit else None)} | "
            f"{_num(fit.speed_ratio if fit else None, 2)} | "
            f"{verdict} |"
        )
    return rows


def _num(x, digits: int = 1) -> str:
    return "–" if x is None or not np.isfinite(float(x)) else f"{float(x):.{digits}f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent
                    / "shared")  # fmt: skip
    ap.add_argument("--only", default="", help="comma-separated recording names")
    args = ap.parse_args()
    human = args.data / "datasets" / "human"
    if not human.is_dir():
        raise SystemExit(f"no {human}: give --data (the shared folder)")
    only = set(filter(None, args.only.split(",")))
    jobs = [("qmt_full_body", p) for p in ("walk", "arm")]
    jobs += [(k, "walk" if "knee" in k else "arm") for k in DOT]
    print(
        "| recording | protocol | joint | grades (3 planes) | first angle per cycle, median "
        "(IQR) | gyroscopes alone per cycle | vendor 9-D rotation from stand per cycle "
        "| vendor 9-D turn between the cycle's extreme poses | L−R "
        "| witness ° | hinge residual "
        "| part consistency ° | thigh / shank speed | plausibility |"
    )
    print("|---|---|---|---|---|---|---|---|---|---:|---:|---:|---:|---|")
    for name, protocol in jobs:
        if only and name not in only:
            continue
        vendor: dict = {}
        try:
            if name == "qmt_full_body":
                session, vendor = qmt_session(human / name, protocol)
            else:
                session = dot_session(human / "imt_dot" / name, DOT[name])
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                analyse(session, PipelineOptions(protocol=protocol, progress=False))
        except InputError as exc:
            print(f"| {name} | {protocol} | – | refused: {exc} | | | | | | | | | |")
            continue
        for row in report(name, protocol, session, vendor):
            print(row)


if __name__ == "__main__":
    main()
