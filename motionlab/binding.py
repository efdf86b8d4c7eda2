"""A session bound to a protocol: which sensor is on which segment (:func:`sensor_for_segment`),
the protocol as the session's sensors allow it (:func:`sensed_protocol`, the joints it drops:
:func:`unsensed_joints`), and the signals a sensor with only an orientation stands in with
(:func:`signals_from_orientation`).

Low in the layers (docs/architecture.md, "Layers"): the sync, the calibration, the angles, the
gait analysis and the validation all ask it, none of them above another.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
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


def segment_name(segment: str, side: str) -> str:
    """The protocol segment name of a sensor map's ``segment`` and ``side`` (``shank`` and
    ``r``: ``shank_r``; a name that has its side already is kept)."""
    if not segment or not side or segment.endswith(f"_{side}"):
        return segment
    return f"{segment}_{side}"


def sensor_list(session: Session) -> str:
    """The session's sensors with the segment each is mapped to, for an error message:
    ``"Femur (thigh_r), Tibia (shank_r)"``; ``"none"`` for no sensor."""
    placed = {k: segment_name(s.segment, s.side) for k, s in session.sensors.items()}
    return ", ".join(f"{k} ({seg})" if seg else k for k, seg in placed.items()) or "none"


def foreign_segments(protocol: Protocol, session: Session) -> str:
    """``"; femur_r, tibia_r are no segments of it"`` when the session's sensors are mapped to
    segment names the protocol does not have (for an error message), else ``""``."""
    mapped = {segment_name(s.segment, s.side) for s in session.sensors.values()} - {""}
    foreign = sorted(mapped - set(protocol.segments))
    if not foreign:
        return ""
    verb = "is no segment" if len(foreign) == 1 else "are no segments"
    return f"; {', '.join(foreign)} {verb} of it"


def check_joints(protocol: Protocol, session: Session, path: object = None) -> None:
    """Raise :class:`InputError` when no joint of ``protocol`` has a sensor on both its segments
    (a protocol of optional segments, as ``walk``, given sensors mapped to other segment names):
    nothing could be calibrated or measured. The message names what each joint needs, the
    segment names of the map that are no segment of the protocol, and the sensors."""
    joints = protocol.joints.values()
    if not joints or any(
        sensor_for_segment(session, j.proximal) and sensor_for_segment(session, j.distal)
        for j in joints
    ):
        return
    needs = "; ".join(f"{name} needs {j.proximal} and {j.distal}"
                      for name, j in protocol.joints.items())  # fmt: skip
    raise InputError(
        f"no joint of the '{protocol.name}' protocol has sensors on both its segments "
        f"({needs}){foreign_segments(protocol, session)} (the sensors: {sensor_list(session)})",
        path,
        remedy="map the sensors to the protocol's segments "
        f"({', '.join(protocol.segments)}) in a sensor map and read the recordings with it, "
        "map_path=map.yaml (docs/ingest.md, 'The map'), or give a protocol for the segments "
        "recorded",
        argument="map_path",
    )


def sensed_protocol(protocol: Protocol, session: Session) -> Protocol:
    """The protocol without the joints that use an optional segment with no sensor (the walk
    protocol's hips when the pelvis sensor is left off) and without the calibration steps that
    name only such segments (a left knee's flexion step when only the right leg was recorded:
    it was asked for and, not found, refused the recording); the protocol itself when nothing
    is dropped. Segments stay (other steps may name them; a missing optional one is skipped
    there as before)."""
    missing = _unsensed(protocol, session)
    if not missing:
        return protocol
    dropped = unsensed_joints(protocol, session)
    joints = {k: j for k, j in protocol.joints.items() if k not in dropped}
    steps = [s for s in protocol.calibration if not (_named(s) and _named(s) <= missing)]
    if len(joints) == len(protocol.joints) and len(steps) == len(protocol.calibration):
        return protocol
    return dataclasses.replace(protocol, joints=joints, calibration=steps)


def _unsensed(protocol: Protocol, session: Session) -> set[str]:
    """The protocol's optional segments with no sensor in the session."""
    return {
        seg
        for seg, spec in protocol.segments.items()
        if not spec.required and sensor_for_segment(session, seg) is None
    }


def unsensed_joints(protocol: Protocol, session: Session) -> dict[str, list[str]]:
    """``{joint: its segments with no sensor}`` of the joints :func:`sensed_protocol` drops
    (the walk protocol's ``{"hip_r": ["pelvis"], "hip_l": ["pelvis"]}`` without a pelvis
    sensor), in protocol order; empty when every joint is measured."""
    missing = _unsensed(protocol, session)
    out = {}
    for name, j in protocol.joints.items():
        segs = [s for s in (j.proximal, j.distal) if s in missing]
        if segs:
            out[name] = segs
    return out


def _named(step) -> set[str]:
    """The segments a calibration step names (its axes, vertical and horizontal, segments)."""
    return {*step.vertical_axis, *step.horizontal_axis, *step.segments, *step.axis}


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
