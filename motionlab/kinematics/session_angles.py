"""Joint angles of a whole session: sensor orientations → segment orientations → angle table.

Sensor orientations come from, in this order: the fusion stage's results
(``session.results["fusion"][label]["quat"]``), running the default estimator on the raw
accelerometer and gyroscope (and magnetometer), or the vendor's own ``quat``. Every joint is
resampled onto one time base: the time of the first joint's proximal sensor, cut to the span all
sensors cover.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import joint_angles
from motionlab.protocol import Protocol
from motionlab.segments import segment_orientations, sensor_for_segment
from motionlab.session import Session, estimate_rate


def sensor_orientation(session: Session, label: str, estimator: str = "default") -> np.ndarray:
    """(N, 4) sensor → earth orientation of one sensor (see the module docstring)."""
    fused = session.results.get("fusion", {}).get(label, {})
    if isinstance(fused, dict) and "quat" in fused:
        return np.asarray(fused["quat"], dtype=float)
    s = session.sensors[label]
    if s.acc is not None and s.gyr is not None:
        from motionlab.fusion import estimate

        return estimate(estimator, s.gyr, s.acc, s.mag, rate=estimate_rate(s.time)).quat
    if s.quat is not None:
        return np.asarray(s.quat, dtype=float)
    raise InputError(
        f"sensor '{label}' has neither an orientation nor acc and gyr",
        where=f"sensor {label}",
        remedy="run motionlab fuse or ingest a file with orientation",
    )


def session_angles(
    session: Session,
    protocol: Protocol,
    calibration: dict[str, Any] | None,
    estimator: str = "default",
    align_heading: bool = True,
) -> dict[str, Any]:
    """``{"time_s": (N,), "<joint>_<side>_<angle>_deg": (N,), ...}`` for every protocol joint.

    ``calibration`` is ``session.results["calibration"]`` (``None``: sensor frames are used as
    segment frames, which shows the cross-talk that calibration removes).
    """
    needed = {s for j in protocol.joints.values() for s in (j.proximal, j.distal)}
    quats = {}
    for seg in needed:
        label = sensor_for_segment(session, seg)
        if label is None:
            raise InputError(
                f"no sensor on segment '{seg}'",
                where=f"protocol {protocol.name}",
                remedy="name the sensor after the segment or set its segment at ingest",
            )
        quats[seg] = (session.sensors[label].time, sensor_orientation(session, label, estimator))
    seg_q = segment_orientations(protocol, calibration or {}, quats, align_heading)
    first = next(iter(protocol.joints.values()))
    t = seg_q[first.proximal][0]
    t0 = max(v[0][0] for v in seg_q.values())
    t1 = min(v[0][-1] for v in seg_q.values())
    t = t[(t >= t0) & (t <= t1)]
    out: dict[str, Any] = {"time_s": t}
    for joint in protocol.joints.values():
        qp = rot.resample(*seg_q[joint.proximal], t)
        qd = rot.resample(*seg_q[joint.distal], t)
        out.update(joint_angles(qp, qd, joint))
    return out
