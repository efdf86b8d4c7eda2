"""A session bound to a protocol: which sensor is on which segment (:func:`sensor_for_segment`),
the protocol as the session's sensors allow it (:func:`sensed_protocol`), and the signals a
sensor with only an orientation stands in with (:func:`signals_from_orientation`).

Low in the layers (docs/architecture.md, "Layers"): the sync, the calibration, the angles, the
gait analysis and the validation all ask it, none of them above another.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from motionlab import rotations as rot
from motionlab.protocol import Protocol
from motionlab.session import Session
from motionlab.timebase import interp_columns


def sensor_for_segment(session: Session, segment: str) -> str | None:
    """Label of the sensor on protocol segment ``segment`` (e.g. ``shank_r``).

    A sensor matches when its ``segment`` attribute is the protocol name (``shank_r``), or is the
    bare name with the side in ``side`` (``shank`` + ``r``, as a sensor map writes it), or when its
    label is the segment name.
    """
    for label, s in session.sensors.items():
        if s.segment == segment or (s.side and f"{s.segment}_{s.side}" == segment):
            return label
    return segment if segment in session.sensors else None


def sensed_protocol(protocol: Protocol, session: Session) -> Protocol:
    """The protocol without the joints that use an optional segment with no sensor (the walk
    protocol's hips when the pelvis sensor is left off); the protocol itself when no joint is
    dropped. Segments stay (calibration steps may name them; a missing optional one is skipped
    there as before)."""
    missing = {
        seg
        for seg, spec in protocol.segments.items()
        if not spec.required and sensor_for_segment(session, seg) is None
    }
    if not missing:
        return protocol
    joints = {
        k: j
        for k, j in protocol.joints.items()
        if j.proximal not in missing and j.distal not in missing
    }
    if len(joints) == len(protocol.joints):
        return protocol
    return dataclasses.replace(protocol, joints=joints)  # segments kept: steps may name them


def signals_from_orientation(
    t: np.ndarray, q: np.ndarray, gravity: float = 9.81
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time, acc, gyr)`` a sensor with only an orientation (OpenSense ``.sto``, Xsens DOT
    quaternions, a vendor's fusion) stands in with for calibration: gravity along the earth
    vertical seen in the sensor frame (m/s², the specific force at rest; the vendor's own
    estimate of it) and the body-frame angular velocity of the orientation series (rad/s,
    :func:`motionlab.rotations.angular_velocity` at the sample times). ``q`` maps
    sensor to the Z-up earth frame."""
    q = rot.make_continuous(q)
    acc = gravity * rot.rotate(rot.conj(q), np.broadcast_to([0.0, 0.0, 1.0], (len(q), 3)))
    gyr = np.zeros((len(q), 3))
    if len(q) > 1:
        mid, rates = rot.angular_velocity(t, q)
        gyr = interp_columns(t, mid, rates)
    return t, acc, gyr
