"""Joint angles of a whole session: sensor orientations → segment orientations → angle table.

Sensor orientations come from, in this order: the fusion stage's results
(``session.results.fusion[label].quat``, as ``motionlab fuse`` stores them), running the
default estimator 6-D on the raw accelerometer and gyroscope, or the vendor's ``quat``. 6-D as
``motionlab run`` fuses: the heading alignment gives each segment's heading relative to its
neighbour, and an uncalibrated magnetometer only adds errors (carrying angle and pronation up to
5–10° in ``bench/joint_angles.py --mag``; docs/kinematics.md).
A segment's sensor is the one whose ``segment`` attribute names it (set by ``ingest --map``), else
the sensor labelled like the segment. Every joint is resampled onto one time base: the time of
the first joint's proximal sensor, cut to the span all sensors cover.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion import estimate
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.protocol import Protocol
from motionlab.results import HeadingCorrection, SegmentCalibration
from motionlab.segments import segment_orientations, sensor_for_segment
from motionlab.segments.hip_axis import apply_turn
from motionlab.session import Session, estimate_rate

SegmentQuats = dict[str, tuple[np.ndarray, np.ndarray]]


def sensor_orientation(session: Session, label: str, estimator: str = "default") -> np.ndarray:
    """(N, 4) sensor → earth orientation of one sensor (see the module docstring)."""
    fused = session.results.fusion.get(label)
    if fused is not None:
        q = np.asarray(fused.quat, dtype=float)
        if q.shape != (session.sensors[label].n_samples, 4):
            raise InputError(
                f"fusion result has shape {q.shape}, the sensor {session.sensors[label].n_samples}"
                " samples",
                where=f"results/fusion/{label}/quat",
                remedy="fuse again with force=True after ingest",
                argument="force",
            )
        return q
    s = session.sensors[label]
    if s.acc is not None and s.gyr is not None:
        return estimate(estimator, s.gyr, s.acc, None, estimate_rate(s.time), time=s.time).quat
    if s.quat is not None:
        return np.asarray(s.quat, dtype=float)
    raise InputError(
        f"sensor '{label}' has neither an orientation nor acc and gyr",
        where=f"sensor {label}",
        remedy="run motionlab fuse or ingest a file with orientation",
    )


def nominal_calibration(protocol: Protocol, steps: dict[str, Any]) -> SegmentCalibration:
    """A calibration holding each segment's nominal mounting (the protocol's placement).

    "Calibration off": sensors are taken to sit exactly as the protocol's ``sensor_axes`` say;
    ``steps`` (the found step times) still serve the heading alignment.
    """
    segments = {
        seg: {"mounting": rot.from_matrix(spec.nominal_mounting().T)}
        for seg, spec in protocol.segments.items()
    }
    return SegmentCalibration(protocol.name, steps=steps, segments=segments)


def session_segments(
    session: Session,
    protocol: Protocol,
    calibration: SegmentCalibration | None,
    estimator: str = "default",
    align_heading: bool = True,
    segments: list[str] | None = None,
    corrections: dict[str, HeadingCorrection] | None = None,
) -> SegmentQuats:
    """``{segment: (time, q_segment)}`` for the joints' segments (or ``segments``).

    ``calibration`` is ``session.results.calibration`` (``None``: sensor frames are used as
    segment frames).
    """
    quats = sensor_quats(session, protocol, segments, estimator)
    return segment_orientations(protocol, calibration, quats, align_heading, corrections)


def joint_segments(protocol: Protocol) -> list[str]:
    """The segments the protocol's joints use, in order of first use."""
    return list(dict.fromkeys(s for j in protocol.joints.values() for s in (j.proximal, j.distal)))


def sensor_quats(
    session: Session,
    protocol: Protocol,
    segments: list[str] | None = None,
    estimator: str = "default",
) -> SegmentQuats:
    """``{segment: (time, q_sensor)}`` of the joints' segments (or ``segments``).

    Rows without a finite orientation (a vendor file's gaps, e.g. ``NaN`` rows of a ``.sto``)
    are left out, as missing samples are: the angles SLERP across them."""
    quats = {}
    for seg in segments or joint_segments(protocol):
        label = sensor_for_segment(session, seg)
        if label is None:
            raise InputError(
                f"no sensor on segment '{seg}'",
                where=f"protocol {protocol.name}",
                remedy="name the sensor after the segment or set its segment at ingest",
            )
        q = sensor_orientation(session, label, estimator)
        ok = np.isfinite(q).all(axis=1)
        quats[seg] = (
            (session.sensors[label].time[ok], q[ok])
            if not ok.all()
            else (session.sensors[label].time, q)
        )
    return quats


def angle_table(
    seg_q: SegmentQuats, protocol: Protocol, calibration: SegmentCalibration | None = None
) -> dict[str, Any]:
    """``{"time_s": (N,), "<joint>_<side>_<angle>_deg": (N,), ...}`` for every protocol joint.

    A hip whose flexion axis the ``calibration`` measured from the movement
    (``calibration.hip_axes``, :mod:`motionlab.segments.hip_axis`) is measured about it."""
    first = next(iter(protocol.joints.values()))
    t = seg_q[first.proximal][0]
    used = {s for j in protocol.joints.values() for s in (j.proximal, j.distal)}
    t0 = max(seg_q[s][0][0] for s in used)
    t1 = min(seg_q[s][0][-1] for s in used)
    t = t[(t >= t0) & (t <= t1)]
    out: dict[str, Any] = {"time_s": t}
    for joint in protocol.joints.values():
        qp = rot.resample(*seg_q[joint.proximal], t)
        qd = rot.resample(*seg_q[joint.distal], t)
        axis = calibration.hip_axes.get(joint.name) if calibration is not None else None
        if axis and axis.get("used"):
            qd = apply_turn(qp, qd, float(axis["turn_deg"]))
        out.update(joint_angles(qp, qd, joint))
    return out


def session_angles(
    session: Session,
    protocol: Protocol,
    calibration: SegmentCalibration | None,
    estimator: str = "default",
    align_heading: bool = True,
    corrections: dict[str, HeadingCorrection] | None = None,
) -> dict[str, Any]:
    """The angle table (degrees) of every protocol joint, see :func:`angle_table`;
    ``corrections`` receives each joint's heading correction (:func:`segment_orientations`)."""
    seg_q = session_segments(
        session, protocol, calibration, estimator, align_heading, corrections=corrections
    )
    return angle_table(seg_q, protocol, calibration)
