"""Mounting of one segment: axes measured in the protocol's steps → ρ-weighted frame fit.

Each step gives axis records per segment (sensor-frame axis ↔ segment axis, with reliability ρ):

- static pose: gravity ("up") for the step's ``vertical_axis`` (:mod:`.static`); a segment axis
  the step names in ``horizontal_axis`` (e.g. the forearm's anterior axis in standing, elbow
  straight, palm forward: flexion and pronation at zero while the carrying angle keeps its long
  axis off the vertical) is laid horizontal after the fit by the smallest rotation
  (:func:`~motionlab.segments.frames.level`). That is the pose's definition of zero, as a
  vertical axis is, and it ties the segment's tilt to the same accelerometer whose gravity the
  orientation filter follows, where the fit alone would rely on gyroscope axes only;
- functional movement: the rotation axis by uncentred SVD of the gyroscope (:mod:`.functional`),
  or, with the step option ``axis_method: hinge``, Seel's hinge axes from the gyroscopes of the
  moving knee or elbow's two segments (:mod:`.hinge`): the distal segment's axis, and, when the
  proximal segment moved too (else the constraint leaves its axis free), the same axis in the
  proximal segment (the flexion axis belongs to both in the reference pose).
  For a knee or elbow flexion the hinge fit is run in any case and the angle between its axis and
  the SVD axis is kept as a check (``hinge_check_deg``).

A movement of the joint itself (the step names the distal segment's axis and not the
proximal's, e.g. seated knee flexion) turns the distal segment about an axis that couples with
the other joint angles (the knee's screw-home rotation, the elbow's carrying angle), so its axis
is only approximately a segment axis. When another step measures the same segment axis while
keeping the joint still (a static pose, or a movement of the whole limb such as a straight-leg
hip flexion), the joint movement's record is left out of the fit (``used: false``). The fit
itself is the weighted orthogonal Procrustes of :mod:`.frames`; with one distinct segment axis
the heading about it stays as the nominal placement says.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.dsp import butter, sosfiltfilt
from motionlab.kinematics.joint_types import JOINT_TYPES, flexion_axis
from motionlab.protocol import CalibrationStep, Protocol, axis_vector
from motionlab.results import AxisMeasurement, SegmentQuality, SegmentRecord
from motionlab.segments import frames, quality
from motionlab.segments.functional import functional_axis, orient
from motionlab.segments.hinge import hinge_axes
from motionlab.segments.static import gravity_axis
from motionlab.session import estimate_rate
from motionlab.timebase import interp_columns

HINGE_MIN_MOTION = 0.2
GYR_LOWPASS_HZ = 4.0  # functional movements are slower; soft-tissue wobble is 10-20 Hz
Stream = tuple[np.ndarray, np.ndarray, np.ndarray]  # time (s), acc (m/s²), gyr (rad/s)


def _window(t: np.ndarray, x: np.ndarray, rng: tuple[float, float]) -> np.ndarray:
    return x[(t >= rng[0]) & (t <= rng[1])]


def _smooth_gyr(t: np.ndarray, gyr: np.ndarray, rng: tuple[float, float]) -> np.ndarray:
    """Gyroscope over the window, low-passed at ``GYR_LOWPASS_HZ`` (zero phase)."""
    sel = (t >= rng[0]) & (t <= rng[1])
    g = gyr[sel]
    rate = estimate_rate(t[sel])
    if len(g) < 30 or not rate > 2.5 * GYR_LOWPASS_HZ:
        return g
    return sosfiltfilt(butter(2, GYR_LOWPASS_HZ, fs=rate), g, axis=0)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(float(a @ b)), 0.0, 1.0))))


def moved_joints(protocol: Protocol, step: CalibrationStep) -> list:
    """Joints the step moves: their distal segment's axis is named, the proximal's is not."""
    return [
        j for j in protocol.joints.values() if j.distal in step.axis and j.proximal not in step.axis
    ]


def _record(
    step: CalibrationStep,
    segment: str,
    seg_axis,
    axis,
    rho,
    method: str,
    moves: bool,
    secondary: bool = False,
):
    return AxisMeasurement(
        step=step.name,
        kind=step.kind,
        method=method,
        sensor_axis=np.asarray(axis, float),
        segment_axis=np.asarray(seg_axis, float),
        rho=float(rho),
        reference_rho=step.reference_rho.get(segment),
        joint_movement=moves,
        secondary=secondary,
    )


def _hinge(protocol, step, joint, streams, rng) -> tuple[np.ndarray | None, np.ndarray, float]:
    """Seel's axes of ``joint`` over the step window (proximal, distal sensor frames).

    The proximal axis is ``None`` when the proximal segment hardly moved (its angular velocity
    RMS below ``HINGE_MIN_MOTION`` of the distal's): the constraint does not fix it then.
    """
    tp, _, gp = streams[joint.proximal]
    td, _, gd = streams[joint.distal]
    sel = (tp >= rng[0]) & (tp <= rng[1])
    gd_at = interp_columns(tp[sel], td, gd)
    seg_axis = axis_vector(step.axis[joint.distal])
    prior_p = protocol.segments[joint.proximal].nominal_mounting().T @ seg_axis
    prior_d = protocol.segments[joint.distal].nominal_mounting().T @ seg_axis
    j_p, j_d, residual = hinge_axes(gp[sel], gd_at, prior_p, prior_d)
    moved = np.sqrt(np.mean(gp[sel] ** 2)) >= HINGE_MIN_MOTION * np.sqrt(np.mean(gd_at**2))
    return (j_p if moved else None), j_d, residual


def static_records(
    step: CalibrationStep,
    streams: dict[str, Stream],
    rng: tuple[float, float],
    out: dict[str, dict[str, AxisMeasurement]],
    min_samples: int = 3,
) -> None:
    """Add to ``out`` the records of a static step over ``rng`` (s): gravity for each segment
    the step names a ``vertical_axis`` of, and the axes it lays horizontal (``min_samples``: see
    :func:`~motionlab.segments.static.gravity_axis`)."""
    for seg, axis_name in step.vertical_axis.items():
        if seg in streams:
            t, acc, _ = streams[seg]
            axis, rho = gravity_axis(_window(t, acc, rng), min_samples)
            out[seg][step.name] = _record(
                step, seg, axis_vector(axis_name), axis, rho, "gravity", False
            )
    for seg, axis_name in step.horizontal_axis.items():
        if seg in streams:
            t, acc, _ = streams[seg]
            up, rho = gravity_axis(_window(t, acc, rng), min_samples)
            out[seg][f"{step.name}:horizontal"] = _record(
                step, seg, axis_vector(axis_name), up, rho, "horizontal", False
            )


def measure(
    protocol: Protocol, streams: dict[str, Stream], steps: dict[str, tuple[float, float] | None]
) -> dict[str, dict[str, AxisMeasurement]]:
    """Axis records ``{segment: {record name: record}}`` of every step found in ``steps``."""
    out: dict[str, dict[str, AxisMeasurement]] = {seg: {} for seg in streams}
    joints = list(protocol.joints.values())
    for step in protocol.calibration:
        rng = steps.get(step.name)
        if rng is None:
            continue
        if step.kind == "static":
            static_records(step, streams, rng, out)
            continue
        moved = moved_joints(protocol, step)
        for seg, axis_name in step.axis.items():
            if seg not in streams:
                continue
            t, _, gyr = streams[seg]
            seg_axis = axis_vector(axis_name)
            axis, rho, _ = functional_axis(_smooth_gyr(t, gyr, rng))
            axis = orient(axis, protocol.segments[seg].nominal_mounting().T @ seg_axis)
            moves = any(j.distal == seg for j in moved)
            carried = any(j.distal == seg and j.proximal in step.axis for j in joints)
            out[seg][step.name] = _record(step, seg, seg_axis, axis, rho, "svd", moves, carried)
        for joint in moved:
            axis = flexion_axis(joint)
            hinge_like = (
                JOINT_TYPES[joint.type].hinge
                and axis is not None
                and step.axis[joint.distal][-1] == axis[-1]
            )
            if not hinge_like or joint.proximal not in streams or joint.distal not in streams:
                continue
            j_p, j_d, residual = _hinge(protocol, step, joint, streams, rng)
            rec = out[joint.distal][step.name]
            rec.hinge_check_deg = _angle_deg(rec.sensor_axis, j_d)
            rec.hinge_residual_rad_s = residual
            if step.axis_method == "hinge":
                rec.sensor_axis, rec.method = j_d, "hinge"
                if j_p is not None:
                    out[joint.proximal][f"{step.name}:hinge"] = _record(
                        step, joint.proximal, rec.segment_axis, j_p, rec.rho, "hinge", True
                    )
    return out


def _mark_used(records: list[AxisMeasurement]) -> None:
    """Leave out joint-movement axes measured better by a step that keeps the joint still."""
    for rec in records:
        key = tuple(np.abs(rec.segment_axis))
        better = any(not o.joint_movement and tuple(np.abs(o.segment_axis)) == key for o in records)
        rec.used = not (rec.joint_movement and better)


def _distinct(recs: list[AxisMeasurement]) -> int:
    return len({tuple(np.abs(r.segment_axis).round(6)) for r in recs})


def _arrays(recs: list[AxisMeasurement]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = np.array([r.sensor_axis for r in recs])
    return v, np.array([r.segment_axis for r in recs]), np.array([r.rho for r in recs])


def nominal(segment: str, protocol: Protocol) -> SegmentRecord:
    """The nominal placement (the protocol's ``sensor_axes`` hint) of a segment the recording
    gives no axis for, with a quality message saying so."""
    m_nom = protocol.segments[segment].nominal_mounting().T
    return SegmentRecord(
        mounting=rot.from_matrix(m_nom),
        method="nominal",
        axes={},
        quality=SegmentQuality(
            ok=False,
            messages=[
                f"{segment}: no axis of it was measured (no calibration step of the protocol "
                "measured one in this recording, and no hinge fit from the movement held); its "
                "frame is the protocol's nominal placement"
            ],
            min_rho=float("nan"),
            separation_deg=None,
            lm_difference_deg=None,
            hinge_check_deg={},
        ),
    )


def fit(segment: str, protocol: Protocol, records: dict[str, AxisMeasurement]) -> SegmentRecord:
    """Mounting (segment → sensor quaternion), method, the records and the quality.

    Primary records (static poses, movements of the segment itself) fix the frame: with two or
    more distinct segment axes by weighted Procrustes (LM as a check). *Secondary* records come
    from a movement that carries the segment along with its proximal segment (the axis measured
    is the proximal segment's, equal to this segment's only up to the joint's resting angles,
    e.g. the carrying angle); they only fix the rotation about a single primary axis
    (:func:`~motionlab.segments.frames.turn_about`), or stand in when there are no primaries.
    """
    if not records:
        return nominal(segment, protocol)
    level = [r for r in records.values() if r.method == "horizontal"]
    recs = [r for r in records.values() if r.method != "horizontal"]
    if not recs:  # a horizontal axis alone fixes no direction of the frame
        return nominal(segment, protocol)
    _mark_used(recs)
    used = [r for r in recs if r.used]
    primary = [r for r in used if not r.secondary]
    secondary = [r for r in used if r.secondary]
    if _distinct(primary) == 0:
        primary, secondary = secondary, []
    m_nom = protocol.segments[segment].nominal_mounting().T  # segment → sensor
    lm_diff = separation = None
    v, r_, w = _arrays(primary)
    if _distinct(primary) >= 2:
        m = frames.wahba(v, r_, w)
        m_lm, _ = frames.lm_fit(v, r_, w, q0=rot.from_matrix(m_nom.T), tol=1e-10)
        lm_diff = float(np.degrees(rot.angle(rot.from_matrix(m.T @ m_lm))))
        method = "procrustes"
        separation = frames.min_axis_separation(r_, v)
    else:  # one primary axis: the rotation about it from the secondaries, else nominal
        # records of one axis may name it with either sign (y, -y); measured signs are kept
        axis = np.average(v * np.sign(r_ @ r_[0])[:, None], axis=0, weights=w)
        m = frames.align_one(axis / np.linalg.norm(axis), r_[0], m_nom)
        vs, rs, ws = _arrays(secondary) if secondary else (None, None, None)
        if secondary and _distinct(secondary + primary[:1]) >= 2:
            m = frames.turn_about(m, m @ r_[0], vs, rs, ws)
            method = "primary_secondary"
            separation = frames.min_axis_separation(np.vstack([r_, rs]), np.vstack([v, vs]))
        else:
            method = "single_axis"
    for rec in level:
        m = frames.level(m, rec.sensor_axis, rec.segment_axis)
    residuals = frames.residual_angles(m, *_arrays(recs)[:2])
    for rec, res in zip(recs, residuals, strict=True):
        rec.residual_deg = float(res)
    for rec in level:  # off the horizontal, 0 unless two poses disagree
        rec.used = True
        tilt = float(rec.sensor_axis @ (m @ rec.segment_axis))
        rec.residual_deg = float(np.degrees(np.arcsin(min(abs(tilt), 1.0))))
    return SegmentRecord(
        mounting=rot.from_matrix(m),
        method=method,
        axes=records,
        quality=quality.assess(segment, recs + level, separation, lm_diff),
    )
