"""Sensor-to-segment calibration: from a protocol's poses and movements to mounting rotations.

For every segment, axes measured in the sensor frame (gravity in static poses,
:mod:`~motionlab.segments.static`; rotation axes of functional movements,
:mod:`~motionlab.segments.functional`) are paired with the segment axes the protocol names, and
the mounting rotation is their ρ-weighted orthogonal Procrustes fit
(:mod:`~motionlab.segments.frames`; Ricci 2015 ch. 6). A segment with a single axis keeps the
protocol's nominal placement for its heading about that axis.

The mounting ``q_mount`` maps segment coordinates into sensor coordinates, so the segment's
orientation is ``q_segment = q_sensor ⊗ q_mount`` (segment → ENU earth). Without a magnetometer
each sensor has its own heading; :func:`segment_orientations` turns each distal segment about the
vertical so that it shares its proximal segment's heading in the protocol's standing pose
(:mod:`~motionlab.segments.heading`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.protocol import Protocol, axis_vector
from motionlab.segments import frames, heading, quality
from motionlab.segments.functional import functional_axis, orient
from motionlab.segments.static import gravity_axis
from motionlab.segments.steps import find_steps
from motionlab.session import Session

Streams = dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]


def sensor_for_segment(session: Session, segment: str) -> str | None:
    """Label of the sensor on ``segment`` (its ``segment`` attribute, else the same label)."""
    for label, s in session.sensors.items():
        if s.segment == segment:
            return label
    return segment if segment in session.sensors else None


def _window(t: np.ndarray, x: np.ndarray, rng: tuple[float, float]) -> np.ndarray:
    sel = (t >= rng[0]) & (t <= rng[1])
    return x[sel]


def calibrate_segment(
    segment: str,
    protocol: Protocol,
    stream: tuple[np.ndarray, np.ndarray, np.ndarray],
    steps: dict[str, tuple[float, float] | None],
) -> dict[str, Any]:
    """Mounting of one segment from the protocol's steps (time ranges in ``steps``).

    Returns ``{"mounting": q (4,), "method": ..., "axes": {step: record}, "quality": {...}}``;
    each axis record holds the sensor-frame axis, the segment axis, ρ and the residual angle.
    """
    t, acc, gyr = stream
    m_nom = protocol.segments[segment].nominal_mounting().T  # segment → sensor
    v, r, w, records = [], [], [], {}
    for step in protocol.calibration:
        rng = steps.get(step.name)
        if rng is None:
            continue
        if step.kind == "static" and segment in step.vertical_axis:
            seg_axis = axis_vector(step.vertical_axis[segment])
            axis, rho = gravity_axis(_window(t, acc, rng))
        elif step.kind == "functional" and segment in step.axis:
            seg_axis = axis_vector(step.axis[segment])
            axis, rho, _ = functional_axis(_window(t, gyr, rng))
            axis = orient(axis, m_nom @ seg_axis)
        else:
            continue
        v.append(axis)
        r.append(seg_axis)
        w.append(rho)
        records[step.name] = {
            "step": step.name,
            "kind": step.kind,
            "sensor_axis": axis,
            "segment_axis": seg_axis,
            "rho": rho,
            "reference_rho": step.reference_rho.get(segment),
        }
    if not v:
        raise InputError(
            f"no calibration step gives an axis for segment '{segment}'",
            protocol.path,
            f"segments.{segment}",
            "add it to a static step's vertical_axis or a functional step's axis",
        )
    v, r, w = np.array(v), np.array(r), np.array(w)
    distinct = {tuple(np.abs(x).round(6)) for x in r}
    lm_diff = None
    if len(distinct) >= 2:
        m = frames.wahba(v, r, w)
        m_lm, _ = frames.lm_fit(v, r, w)
        lm_diff = float(np.degrees(rot.angle(rot.from_matrix(m.T @ m_lm))))
        method = "procrustes"
        separation = frames.min_axis_separation(r, v)
    else:  # one segment axis only: the heading about it comes from the nominal placement
        m = frames.align_one(np.average(v, axis=0, weights=w), r[0], m_nom)
        method = "single_axis"
        separation = None
    residuals = frames.residual_angles(m, v, r)
    for rec, res in zip(records.values(), residuals, strict=True):
        rec["residual_deg"] = float(res)
    return {
        "mounting": rot.from_matrix(m),
        "method": method,
        "axes": records,
        "quality": quality.assess(segment, list(records.values()), separation, lm_diff),
    }


def streams_of(session: Session, protocol: Protocol) -> Streams:
    """``{segment: (time, acc, gyr)}`` for every protocol segment that has a sensor."""
    out: Streams = {}
    for seg, spec in protocol.segments.items():
        label = sensor_for_segment(session, seg)
        if label is None:
            if spec.required:
                raise InputError(
                    f"no sensor on segment '{seg}'",
                    where=f"protocol {protocol.name}",
                    remedy="name the sensor after the segment or set its segment at ingest",
                )
            continue
        s = session.sensors[label]
        if s.acc is None or s.gyr is None:
            raise InputError(
                f"sensor '{label}' has no accelerometer or gyroscope",
                where=f"sensor {label}",
                remedy="calibration needs raw acc and gyr",
            )
        out[seg] = (s.time, s.acc, s.gyr)
    return out


def calibrate(session: Session, protocol: Protocol) -> dict[str, Any]:
    """Sensor-to-segment calibration of every segment; the tree for ``results["calibration"]``."""
    streams = streams_of(session, protocol)
    steps = find_steps(streams, protocol)
    segments = {}
    for seg in streams:
        res = calibrate_segment(seg, protocol, streams[seg], steps)
        res["sensor"] = sensor_for_segment(session, seg)
        segments[seg] = res
    return {
        "protocol": protocol.name,
        "steps": {k: (list(v) if v else None) for k, v in steps.items()},
        "segments": segments,
        "ok": all(s["quality"]["ok"] for s in segments.values()),
    }


def reference_step(protocol: Protocol, proximal: str, distal: str) -> str | None:
    """First static step in which both segments share the same vertical axis (same pose)."""
    for step in protocol.calibration:
        va = step.vertical_axis
        if step.kind == "static" and proximal in va and va.get(distal) == va[proximal]:
            return step.name
    return None


def segment_orientations(
    protocol: Protocol,
    calibration: dict[str, Any],
    sensor_quats: dict[str, tuple[np.ndarray, np.ndarray]],
    align_heading: bool = True,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{segment: (time, q_segment)}`` from sensor orientations ``{segment: (time, q_sensor)}``.

    With ``align_heading`` each joint's distal segment is turned about the vertical to the
    proximal segment's heading in the reference pose (:func:`reference_step`); without a
    calibration entry for a segment its sensor frame is used as the segment frame.
    """
    out = {}
    for seg, (t, q) in sensor_quats.items():
        cal = calibration.get("segments", {}).get(seg)
        q_mount = np.asarray(cal["mounting"]) if cal else rot.IDENTITY
        out[seg] = (t, rot.make_continuous(rot.mul(q, q_mount)))
    if not align_heading:
        return out
    steps = calibration.get("steps", {})
    for joint in protocol.joints.values():
        p, d = joint.proximal, joint.distal
        name = reference_step(protocol, p, d)
        if p not in out or d not in out or name is None or not steps.get(name):
            continue
        t0, t1 = steps[name]
        tp, qp = out[p]
        td, qd = out[d]
        sel = (tp >= t0) & (tp <= t1)
        if sel.sum() < 2:
            continue
        qd_at = rot.resample(td, qd, tp[sel])
        delta = heading.heading_from_pose(qp[sel], qd_at)
        out[d] = (td, heading.apply_heading(qd, delta))
    return out
