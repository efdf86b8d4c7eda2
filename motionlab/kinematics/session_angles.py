"""Joint angles of a whole session: sensor orientations → segment orientations → angle table.

Sensor orientations are (:mod:`motionlab.segments.sensors`) the fusion stage's results
(``session.results.fusion[label].quat``, as ``motionlab fuse`` stores them) or, for a sensor
without raw accelerometer and gyroscope, the vendor's ``quat``; a sensor with raw signals and
no fusion result is refused. ``motionlab run`` fuses 6-D: the heading alignment gives each
segment's heading relative to its neighbour, and an uncalibrated magnetometer only adds errors
(carrying angle and pronation up to 5–10° in ``bench/joint_angles.py --mag``;
docs/kinematics.md).
A segment's sensor is the one whose ``segment`` attribute names it (set by ``ingest --map``), else
the sensor labelled like the segment. Every joint is resampled onto one time base: the time of
the first joint's proximal sensor, cut to the span all sensors cover; inside a packet-loss gap
of either of a joint's sensors (:func:`in_gaps`) its angles are NaN.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.protocol import Protocol
from motionlab.results import HeadingCorrection, SegmentCalibration, SegmentRecord
from motionlab.segments import segment_orientations
from motionlab.segments.hip_axis import apply_turn
from motionlab.segments.sensors import SegmentQuats, sensor_quats
from motionlab.session import Session
from motionlab.timebase import find_gaps

#: a sensor's gap longer than this (s; ingest's default ``--gap-max`` fills shorter ones) has no
#: angles of its joints inside it
ANGLE_GAP_S = 0.1


def nominal_calibration(protocol: Protocol, steps: dict[str, Any]) -> SegmentCalibration:
    """A calibration holding each segment's nominal mounting (the protocol's placement).

    "Calibration off": sensors are taken to sit exactly as the protocol's ``sensor_axes`` say;
    ``steps`` (the found step times) still serve the heading alignment.
    """
    segments = {
        seg: SegmentRecord(rot.from_matrix(spec.nominal_mounting().T), "nominal")
        for seg, spec in protocol.segments.items()
    }
    return SegmentCalibration(protocol.name, steps=steps, segments=segments)


def session_segments(
    session: Session,
    protocol: Protocol,
    calibration: SegmentCalibration | None,
    align_heading: bool = True,
    segments: list[str] | None = None,
    corrections: dict[str, HeadingCorrection] | None = None,
) -> SegmentQuats:
    """``{segment: (time, q_segment)}`` for the joints' segments (or ``segments``).

    ``calibration`` is ``session.results.calibration`` (``None``: sensor frames are used as
    segment frames).
    """
    quats = sensor_quats(session, protocol, segments)
    return segment_orientations(protocol, calibration, quats, align_heading, corrections)


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
        if axis is not None and axis.used:
            qd = apply_turn(qp, qd, float(axis.turn_deg))
        lost = in_gaps(seg_q[joint.proximal][0], t) | in_gaps(seg_q[joint.distal][0], t)
        for column, values in joint_angles(qp, qd, joint).items():
            out[column] = np.where(lost, np.nan, values)
    return out


def in_gaps(stamps: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N,) bool: the instants ``t`` (s) that fall inside a gap of a sensor's ``stamps`` longer
    than ``ANGLE_GAP_S`` (and 1.5 sampling intervals): packet losses that ingest kept as gaps,
    where the sensor recorded nothing and an angle would be the fusion's bridge or an
    interpolation across the gap, not a measurement."""
    if len(stamps) < 2:
        return np.zeros(len(t), bool)
    big = np.zeros(len(stamps), bool)  # interval i (stamps[i] to stamps[i + 1]) is a gap
    gaps = find_gaps(stamps)
    big[gaps[np.diff(stamps)[gaps] > ANGLE_GAP_S]] = True
    i = np.clip(np.searchsorted(stamps, t, side="right") - 1, 0, len(stamps) - 1)
    return big[i] & (t > stamps[i]) & (t < stamps[np.minimum(i + 1, len(stamps) - 1)])


def session_angles(
    session: Session,
    protocol: Protocol,
    calibration: SegmentCalibration | None,
    align_heading: bool = True,
    corrections: dict[str, HeadingCorrection] | None = None,
) -> dict[str, Any]:
    """The angle table (degrees) of every protocol joint, see :func:`angle_table`;
    ``corrections`` receives each joint's heading correction (:func:`segment_orientations`)."""
    seg_q = session_segments(session, protocol, calibration, align_heading, corrections=corrections)
    return angle_table(seg_q, protocol, calibration)
