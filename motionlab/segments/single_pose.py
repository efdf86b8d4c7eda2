"""OpenSense-style single-pose calibration, for recordings of orientations too short for more.

OpenSense's IMU placer calibrates from one frame: the subject is taken to stand in the model's
neutral pose at the first time step, and each sensor's orientation then gives how it sits on
its segment, the heading set by a known axis of a base sensor. A file of orientations a few
samples long (the calibration-pose ``.sto`` OpenSense users keep) is all some users have, and
is far too short for :mod:`~motionlab.segments.steps` to tell rest from movement (under
``MIN_RECORDING_S``). When every sensor of the protocol's segments has an orientation (fused,
else the vendor's: the one the angles take, :func:`~.sensors.sensor_orientation`),
:func:`pose_step` takes the whole recording as the protocol's first static step instead:

- each segment's axis the step names vertical (and its horizontal axes) comes from gravity as
  the orientation implies it (:func:`motionlab.binding.signals_from_orientation`), so the
  sensor's tilt on the segment is measured;
- the rotation about the vertical has no movement to measure it: it is the protocol's
  ``sensor_axes`` hint (:func:`motionlab.segments.mounting.fit` with one axis), and each joint's
  distal segment is turned to face as its proximal segment does in the pose (the neutral pose's
  assumption; ``single pose`` heading anchor in :func:`motionlab.segments.segment_orientations`).

The angles are then graded ``weak`` at best (:mod:`.grades`: one measured axis and the hint),
and one warning line says that the calibration is single-pose and what it assumed.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.binding import sensor_for_segment, signals_from_orientation
from motionlab.protocol import CalibrationStep, Protocol
from motionlab.segments import heading
from motionlab.segments.mounting import static_records
from motionlab.segments.sensors import sensor_orientation
from motionlab.segments.steps import MIN_RECORDING_S, Block, longest_s, placement_warnings
from motionlab.session import Session

Streams = dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]


def pose_step(session: Session, protocol: Protocol, streams: Streams) -> CalibrationStep | None:
    """The protocol's first static step, when the recording is too short to find steps in
    (every stream under ``MIN_RECORDING_S``) and every sensor on its segments carries an
    orientation; else ``None`` (the steps are found as usual)."""
    if not streams or longest_s(streams) >= MIN_RECORDING_S:
        return None
    for seg in streams:
        label = sensor_for_segment(session, seg)
        if label not in session.results.fusion and session.sensors[label].quat is None:
            return None
    return next((s for s in protocol.calibration if s.kind == "static"), None)


def measure(
    session: Session,
    protocol: Protocol,
    streams: Streams,
    step: CalibrationStep,
    warnings: list[str],
) -> tuple[dict[str, tuple[float, float] | None], dict[str, dict[str, dict[str, Any]]]]:
    """``(steps, records)`` of a single-pose calibration (see the module docstring): ``step``
    spans the whole recording (s), the protocol's other steps are ``None``; the records are the
    static step's, from the gravity of each sensor's orientation. Lines for the user (the
    calibration is single-pose; a vertical axis the hint contradicts) go to ``warnings``."""
    pose: Streams = {}
    for seg in streams:  # the orientation the angles take: a pose read from another one (the
        # vendor's, beside a 6-D fusion 10° off it) gave its own pose 20° of lateral bending
        label = sensor_for_segment(session, seg)
        t, q = session.sensors[label].time, sensor_orientation(session, label)
        ok = np.isfinite(q).all(axis=1)
        pose[seg] = signals_from_orientation(t[ok], q[ok])
    rng = (
        float(min(t[0] for t, _, _ in pose.values())),
        float(max(t[-1] for t, _, _ in pose.values())),
    )
    steps: dict[str, tuple[float, float] | None] = {s.name: None for s in protocol.calibration}
    steps[step.name] = rng
    records: dict[str, dict[str, dict[str, Any]]] = {seg: {} for seg in streams}
    static_records(step, pose, rng, records, min_samples=1)
    up = {}
    for seg, (_, acc, _) in pose.items():
        mean = acc.mean(axis=0)
        up[seg] = mean / (np.linalg.norm(mean) or 1.0)
    n = max(len(t) for t, _, _ in pose.values())
    skipped = [s.name for s in protocol.calibration if s.name != step.name]
    warnings.append(
        f"single-pose calibration (OpenSense-style): the recording lasts {rng[1] - rng[0]:.2f} s "
        f"({n} sample{'s' if n != 1 else ''}), too short to find rests and movements, so all "
        f"of it is taken as the '{step.name}' pose; assumed: the subject holds that pose, each "
        "segment's vertical axis is from gravity as the sensor's orientation gives it, the "
        "rotation about the vertical is the protocol's sensor_axes hint and each joint's segments "
        "face the same way in the pose"
        + (f"; steps not used: {', '.join(skipped)}" if skipped else "")
        + "; angles graded weak at best"
    )
    block = Block(start=rng[0], end=rng[1], moving=False, rate={}, up=up, norms={})
    warnings.extend(placement_warnings(step, block, protocol))
    return steps, records


def heading_anchor(
    step_range: tuple[float, float], t: np.ndarray, qp: np.ndarray, qd: np.ndarray
) -> tuple[list[float], list[float]]:
    """One heading anchor ``([time s], [δ rad])`` of a joint in a single-pose calibration: the
    distal segment turned to face as the proximal one over the pose (``step_range``, s; ``qp``
    and ``qd`` the segment orientations on the common time ``t``)."""
    sel = (t >= step_range[0]) & (t <= step_range[1])
    if not sel.any():
        return [], []
    return [float(t[sel].mean())], [heading.heading_from_pose(qp[sel], qd[sel])]
