"""A session's strides, found once for every page that reads them.

The gait analysis (:mod:`.gait`: spatio-temporal parameters, stride curves) and the joint
metrics of a walk (:mod:`.metrics`: per-stride ranges and peaks of the knees and hips) take the
same strides: each knee's shank sagittal angular velocity (the raw gyroscope turned into the
shank frame by the calibrated mounting) → events (:func:`.gait_events.detect`, told the gaps
ingest filled: one longer than it bridges is no data) → strides kept or rejected with the
reason (:func:`.gait_events.strides`; turns from the vertical angular velocity of the pelvis
sensor, else of the side's shank sensor). A report whose joint pages counted 45 strides where
its gait page kept 41 (turns and gait initiation left out there only) described two different
walks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.fusion.stage import filled_spans
from motionlab.kinematics import gait_events as ge
from motionlab.protocol import Protocol
from motionlab.results import SegmentCalibration
from motionlab.segments.sensors import sensor_orientation
from motionlab.session import Session

PELVIS_SEGMENT = "pelvis"


@dataclass
class LegStrides:
    """One leg's gait events and strides (times in s) and the shank segment they come from."""

    segment: str
    side: str
    events: ge.SideEvents
    strides: ge.Strides


def shank_angular_velocity(
    session: Session, protocol: Protocol, calibration: SegmentCalibration
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{segment: (time s, ω_z rad/s)}``: the gyroscope about the segment's z axis (positive:
    the lower end swings forward) of each knee's shank."""
    out = {}
    for joint in protocol.joints.values():
        seg = joint.distal
        label = sensor_for_segment(session, seg)
        cal = calibration.segments.get(seg)
        if joint.type != "knee" or label is None or cal is None:
            continue
        s = session.sensors[label]
        if s.gyr is None:
            continue
        w = rot.rotate(rot.conj(np.asarray(cal.mounting)), s.gyr)  # sensor → segment
        out[seg] = (s.time, w[:, 2])
    return out


def yaw_rate(session: Session, label: str) -> tuple[np.ndarray, np.ndarray]:
    """``(time s, vertical angular velocity rad/s)`` of one fused sensor (earth z of its
    gyroscope)."""
    s = session.sensors[label]
    q = sensor_orientation(session, label)
    return s.time, rot.rotate(q, s.gyr)[:, 2]


def session_strides(
    session: Session,
    protocol: Protocol,
    calibration: SegmentCalibration,
    spans: dict[str, tuple[float, float]],
) -> dict[str, LegStrides]:
    """``{shank segment: LegStrides}`` of every knee's leg over the gait tasks' ``spans``
    (``{task: (start_s, end_s)}``, at least one; strides inside each, joined in order); empty
    without a shank sensor under a knee joint."""
    side_of = {j.distal: j.side for j in protocol.joints.values() if j.type == "knee"}
    pelvis_label = sensor_for_segment(session, PELVIS_SEGMENT)
    out = {}
    for seg, (time, wz) in shank_angular_velocity(session, protocol, calibration).items():
        side = side_of[seg]
        shank = sensor_for_segment(session, seg)
        ev = ge.detect(time, wz, filled_spans(session.sensors[shank]) if shank else None)
        label = pelvis_label or sensor_for_segment(session, seg)
        yaw = yaw_rate(session, label) if label else None
        parts = [ge.strides(side, ev, yaw, span) for span in spans.values()]
        strides = ge.Strides(
            side,
            *(np.concatenate([getattr(p, k) for p in parts]) for k in ("ic", "fc", "next_ic")),
            np.concatenate([p.kept for p in parts]),
            [r for p in parts for r in p.reason],
        )
        out[seg] = LegStrides(seg, side, ev, strides)
    return out
