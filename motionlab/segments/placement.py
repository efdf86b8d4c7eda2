"""Placement from the data: which way each sensor sits, whatever the protocol's hint says.

The protocol's ``sensor_axes`` is a hint. A static pose's gravity gives a measured, signed axis
whatever the mounting. A functional step's rotation axis is measured without a sign, which the
hint supplies (:func:`~motionlab.segments.functional.orient`); so is a hinge axis. Where the data
contradicts the hint (:func:`contradicted`: gravity or a functional axis more than
``CONTRADICTED_DEG`` from where the hint puts it), those signs are taken from the data instead
(:func:`orient_by_data`): from the segment's signed axes (gravity, and the axes fitted from the
movement with their anatomical direction, :mod:`.movement`) where they fix it.

Hinge-like joints (knee, elbow, generic hinges; :func:`hinge_spec`) get their axes from the
movement (:func:`movement_hinges`) when no functional step measures them, or when the hint of
one of their segments is contradicted (then only to orient the steps' axes); hinges without a
twist axis are fitted where a step measures them too, so that a step's axis signed against the
fit's anatomical direction counts as contradicted (:func:`sign_contradicted`). A fit ``not
determined`` still gives them to a segment whose hint says nothing of them (a sensor that may
sit any way round, or a contradicted hint) when the anatomy signed it (:func:`fills_hint`): the
hint's turn about the stand's vertical is arbitrary there, and took a right elbow's flexion axis
165° the wrong way round (flexion 111° RMS off; the fit, 15.2° between its parts, 2.7°).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.clocksync.joint_centre import joint_centre_forces
from motionlab.errors import InputError
from motionlab.kinematics.joint_types import flexion_axis, joint_sequence, joint_type
from motionlab.protocol import Protocol, axis_vector
from motionlab.results import AxisMeasurement, CentreHeading
from motionlab.segments import frames, gait_axes, heading, movement, skin_lag, walk_checks
from motionlab.segments.functional import orient
from motionlab.segments.sensors import Streams, sensor_orientation
from motionlab.segments.steps import reference_step
from motionlab.session import Session

CONTRADICTED_DEG = 60.0


def hinge_spec(joint) -> tuple[str, bool] | None:
    """``(flexion axis in segment coordinates, flexes one way)`` of a hinge-like joint (knee,
    elbow, generic hinge; :mod:`motionlab.kinematics.joint_types`), else ``None``."""
    jt = joint_type(joint.type)
    axis = flexion_axis(joint)
    if not jt.hinge or not axis:
        return None
    return axis, jt.flexes_one_way


def _measured_by_steps(records: dict[str, AxisMeasurement], axis: np.ndarray) -> bool:
    """Whether a functional step already measured this segment axis (either sign)."""
    return any(
        r.kind == "functional" and abs(float(r.segment_axis @ axis)) > 0.99
        for r in records.values()
    )


def movement_hinges(
    session: Session,
    protocol: Protocol,
    streams: Streams,
    steps: dict[str, Any],
    records: dict[str, dict[str, AxisMeasurement]],
    contradicted: set[str] = frozenset(),
) -> dict[str, movement.HingeFit]:
    """Hinge axes from ordinary movement for the hinge-like joints no functional step measures,
    and for those with a segment in ``contradicted`` or without a twist axis (to orient or check
    the sign of the steps' axes, :func:`sign_contradicted`).

    For the first, the axis records (``movement:<joint>:k``, kind ``movement``) are added to
    ``records``: of a fit ``not determined`` only to the segments it fills the hint of
    (:func:`fills_hint`); the fits are returned by joint name.
    """
    fits: dict[str, movement.HingeFit] = {}
    for name, joint in protocol.joints.items():
        spec = hinge_spec(joint)
        p, d = joint.proximal, joint.distal
        if spec is None or p not in streams or d not in streams:
            continue
        seg_axis = axis_vector(spec[0])
        measured = _measured_by_steps(records[d], seg_axis)
        twist = joint_type(joint.type).twist_axis
        if measured and not {p, d} & contradicted and twist:
            continue
        side = {}
        for seg in (p, d):
            label = sensor_for_segment(session, seg)
            t, _, gyr = streams[seg]
            q, s = sensor_orientation(session, label), session.sensors[label]
            if s.acc is None or s.gyr is None:  # as streams_of: rows with an orientation
                q = q[np.isfinite(np.asarray(s.quat, float)).all(axis=1)]
            side[seg] = (t, gyr, q)
        ref_name = reference_step(protocol, p, d)
        reference = steps.get(ref_name) if ref_name else None
        prior_p = protocol.segments[p].nominal_mounting().T @ seg_axis
        prior_d = protocol.segments[d].nominal_mounting().T @ seg_axis
        try:
            if twist:
                fit = movement.fit_two_dof(
                    name, side[p], side[d], prior_p,
                    protocol.segments[d].nominal_mounting().T @ axis_vector(twist), reference,
                    axial_lag=long_axis_vertical(protocol, p, ref_name),
                )  # fmt: skip
                if np.isfinite(fit.axial_follow) and skin_lag.covers(
                    streams.get(skin_lag.TRUNK), reference
                ):
                    fit.lag_anchor = skin_lag.TRUNK
            elif reference and twists_about_long_axis(protocol, joint, ref_name, spec):
                fit = gait_axes.fit_knee(name, side[p], side[d], prior_p, prior_d, reference,
                                         walk_checks.stand_and_walk(protocol))  # fmt: skip
            else:
                fit = movement.fit_hinge(name, side[p], side[d], prior_p, prior_d, reference,
                                         spec[1])  # fmt: skip
        except gait_axes.SwappedSensors as exc:
            raise walk_checks.swapped(session, p, d, exc.ratio) from None
        except InputError as exc:
            fits[name] = movement.failed(name, exc.message)
            continue
        fits[name] = fit
        if measured:
            fit.used_for = "direction"
        if measured:
            continue
        segs = {seg for seg in (p, d) if fills_hint(protocol, seg, fit, contradicted)}
        if fit.verdict == "not determined" and not segs:
            continue
        # a fit not determined weighs as a weak one: it only stands in for the hint
        rho = 0.9 if fit.verdict == "determined" else 0.6
        new = [(p, fit.axis_proximal, seg_axis, True)]
        if twist:  # the distal's long axis, and its flexion axis in the reference pose
            new.append((d, fit.axis_distal, axis_vector(twist), False))
            if np.all(np.isfinite(fit.flexion_distal)):
                new.append((d, fit.flexion_distal, seg_axis, True))
        else:
            new.append((d, fit.axis_distal, seg_axis, True))
        for k, (seg, axis, segment_axis, secondary) in enumerate(new):
            if fit.verdict == "not determined" and seg not in segs:
                continue
            records[seg][f"movement:{name}:{k}"] = AxisMeasurement(
                step=f"movement:{name}",
                kind="movement",
                method="hinge",
                sensor_axis=np.asarray(axis, float),
                segment_axis=segment_axis,
                rho=rho,
                # a static pose's gravity, where there is one, stays exact
                secondary=secondary,
                verdict=fit.verdict,
            )
    return fits


def fills_hint(
    protocol: Protocol, segment: str, fit: movement.HingeFit, contradicted: set[str]
) -> bool:
    """Whether a hinge fit ``not determined`` gives ``segment`` its axes all the same: the
    anatomy told which way it flexes (``sign`` ``anatomy``, the same rule as a determined
    fit's), its axes are finite, it was not refused as no joint of its kind (a flexion axis
    along the upper arm, :data:`.movement.ACROSS_LONG_AXIS_DEG`), and the segment's placement
    hint says nothing of them (its sensor may sit any way round, ``any_orientation``, or the
    data contradict the hint). The hint's turn about a measured axis is then arbitrary (up to
    half a turn off) where the fit's axes are off by about the disagreement of its parts. The
    angles stay ``not determined`` (:mod:`.grades`); they are only not the hint's."""
    if fit.verdict != "not determined" or fit.sign != "anatomy":
        return False
    if float(getattr(fit, "across_deg", np.nan)) > movement.ACROSS_LONG_AXIS_DEG:
        return False
    if not (np.all(np.isfinite(fit.axis_proximal)) and np.all(np.isfinite(fit.axis_distal))):
        return False
    return protocol.segments[segment].any_orientation or segment in contradicted


def fitted_axes_used(calibration, joint) -> bool:
    """Whether the movement fit of ``joint`` gave either of its segments an axis (a record
    ``movement:<joint>`` in the calibration's segments)."""
    step = f"movement:{joint.name}"
    return any(
        r.step == step
        for seg in (joint.proximal, joint.distal)
        if seg in calibration.segments
        for r in calibration.segments[seg].axes.values()
    )


def fit_in_use(calibration, joint) -> movement.HingeFit | None:
    """The movement fit of ``joint`` when the angles take its axes and, for a two-axis fit, its
    heading ties: fitted for the axes (not only their direction) and not ``not determined``
    unless its axes stood in for a placement hint (:func:`fitted_axes_used`); else ``None``."""
    fit = calibration.hinges.get(joint.name)
    if fit is None or fit.used_for != "axes":
        return None
    if fit.verdict == "not determined" and not fitted_axes_used(calibration, joint):
        return None
    return fit


def long_axis_vertical(protocol: Protocol, segment: str, ref_name: str | None) -> bool:
    """Whether the reference pose ``ref_name`` has ``segment``'s long axis y vertical (the upper
    arm hanging in the stand): then its sensor's up there is the axis its skin lags about
    (:func:`.movement.fit_two_dof`)."""
    step = next((s for s in protocol.calibration if s.name == ref_name), None)
    return step is not None and step.vertical_axis.get(segment, "").strip("+") == "y"


def twists_about_long_axis(protocol: Protocol, joint, ref_name: str | None, spec) -> bool:
    """Whether a one-way hinge-like joint (the knee) also turns about its distal segment's long
    axis y (its sequence ends in Y, the flexion axis is another) and the reference pose has that
    axis vertical: then its axes come from the walk's principal axes,
    :func:`.gait_axes.fit_knee`."""
    if not spec[1] or ref_name is None or spec[0].strip("+-") == "y":
        return False
    step = next((s for s in protocol.calibration if s.name == ref_name), None)
    vertical = step.vertical_axis.get(joint.distal, "") if step is not None else ""
    return joint_sequence(joint).upper().endswith("Y") and vertical.strip("+") == "y"


def contradicted(protocol: Protocol, records: dict[str, dict[str, AxisMeasurement]]) -> set[str]:
    """Segments whose measured axes (gravity, signed; functional axes, either sign) lie more
    than ``CONTRADICTED_DEG`` from where the nominal placement puts them."""
    out = set()
    for seg, recs in records.items():
        m_nom = protocol.segments[seg].nominal_mounting().T  # segment → sensor
        for r in recs.values():
            if r.method not in ("gravity", "svd", "hinge") or r.kind == "movement":
                continue
            c = float(r.sensor_axis @ (m_nom @ r.segment_axis))
            if r.method != "gravity":
                c = abs(c)
            if c < np.cos(np.radians(CONTRADICTED_DEG)):
                out.add(seg)
    return out


def sign_contradicted(
    protocol: Protocol,
    records: dict[str, dict[str, AxisMeasurement]],
    fits: dict[str, movement.HingeFit],
) -> set[str]:
    """Segments whose functional hinge axis, signed by the placement hint, points against the
    same axis signed by anatomy in the movement (a hinge fit whose ``sign`` is ``anatomy``: a
    knee flexes one way).

    :func:`contradicted` compares a functional axis with the hint without its sign, and gravity
    says nothing of a turn about the vertical: a shank sensor strapped half a turn round its long
    axis from where the hint puts it agrees with the hint in both, and took its flexion axis the
    wrong way round (the knee protocol with sensors strapped any way round: 2 knees of 20 read
    180° less their flexion, 40° RMS, graded determined)."""
    out = set()
    cos = np.cos(np.radians(CONTRADICTED_DEG))
    for name, fit in fits.items():
        if fit.verdict == "not determined" or fit.sign != "anatomy":
            continue
        joint = protocol.joints[name]
        axis = axis_vector(hinge_spec(joint)[0])
        for seg, signed in ((joint.proximal, fit.axis_proximal), (joint.distal, fit.axis_distal)):
            for rec in records[seg].values():
                if rec.kind != "functional" or rec.method not in ("svd", "hinge"):
                    continue
                if abs(float(rec.segment_axis @ axis)) > 0.99 and (
                    float(rec.sensor_axis @ signed) * float(rec.segment_axis @ axis) < -cos
                ):
                    out.add(seg)
    return out


def _signed_axes(
    protocol: Protocol,
    seg: str,
    records: dict[str, AxisMeasurement],
    fits: dict[str, movement.HingeFit],
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(sensor axis, segment axis)`` pairs of a segment measured with their sign: gravity,
    and the axes fitted from movement with a sign from the data (anatomy, the stand)."""
    out = [(r.sensor_axis, r.segment_axis) for r in records.values()
           if r.method == "gravity"]  # fmt: skip
    for name, fit in fits.items():
        joint = protocol.joints[name]
        if fit.verdict == "not determined" or fit.sign != "anatomy":
            continue
        axis = axis_vector(hinge_spec(joint)[0])
        if seg == joint.proximal:
            out.append((fit.axis_proximal, axis))
        elif seg == joint.distal:
            twist = joint_type(joint.type).twist_axis
            if twist:
                out.append((fit.axis_distal, axis_vector(twist)))
                if np.all(np.isfinite(fit.flexion_distal)):
                    out.append((fit.flexion_distal, axis))
            else:
                out.append((fit.axis_distal, axis))
    return out


#: a functional step moves one way from its start (one-sided) when the larger of its two
#: excursions about the step's axis is at least this large (deg) …
ONE_WAY_MIN_DEG = 15.0
#: … and this many times the other
ONE_WAY_RATIO = 3.0
#: a step starts from the reference pose when every segment it names, and every segment jointed
#: to one of them, sees gravity within this (deg) of where it saw it in that pose, just before
#: the step
START_POSE_DEG = 20.0
START_REST_S = 1.0  # the rest just before a step: this long (s)
#: a segment's long axis (y) within this (deg) of the vertical in the reference pose points up
#: there (limbs hanging, a trunk upright: the forearm's is 10-15° off with the carrying angle)
LONG_AXIS_UP_DEG = 45.0
#: two segments a step names with one axis turn together when their rates about it correlate
#: at least this much (either sign)
CO_ROTATION_MIN = 0.7


def _up(streams: Streams, seg: str, t0: float, t1: float) -> np.ndarray | None:
    """Unit direction of ``seg``'s specific force (up, sensor frame) over ``[t0, t1)`` s;
    ``None`` with fewer than 3 samples or no segment's sensor."""
    if seg not in streams:
        return None
    t, acc, _ = streams[seg]
    sel = (t >= t0) & (t < t1)
    if sel.sum() < 3:
        return None
    g = acc[sel].mean(axis=0)
    return g / max(float(np.linalg.norm(g)), 1e-12)


def _start_pose_kept(
    protocol: Protocol, step, streams: Streams, start: float, ref: tuple[float, float]
) -> bool:
    """Whether every segment ``step`` names, and every segment jointed to one of them, sees
    gravity over ``START_REST_S`` before ``start`` within ``START_POSE_DEG`` of where it saw it
    over the reference pose ``ref`` (a shank hangs as in standing when seated, its thigh does
    not)."""
    for seg in _with_joint_partners(protocol, step):
        a, b = _up(streams, seg, start - START_REST_S, start), _up(streams, seg, *ref)
        if a is None or b is None or float(a @ b) < np.cos(np.radians(START_POSE_DEG)):
            return False
    return True


def _long_axis_line(recs: dict[str, AxisMeasurement]) -> np.ndarray | None:
    """A segment's long axis ``y`` in its sensor (unit, either sign): measured (gravity in a
    pose, or a step about it), else across its measured ``x`` and ``z``; ``None`` without."""
    ys = [r.sensor_axis for r in recs.values() if abs(float(r.segment_axis[1])) > 0.99]
    if ys:
        return ys[0] / np.linalg.norm(ys[0])
    xs = [r.sensor_axis for r in recs.values() if abs(float(r.segment_axis[0])) > 0.99]
    zs = [r.sensor_axis for r in recs.values() if abs(float(r.segment_axis[2])) > 0.99]
    if not xs or not zs:
        return None
    v = np.cross(xs[0], zs[0])
    n = float(np.linalg.norm(v))
    return v / n if n > 0.5 else None


def _upright_start(
    protocol: Protocol,
    step,
    streams: Streams,
    records: dict[str, dict[str, AxisMeasurement]],
    start: float,
) -> bool:
    """Whether every segment ``step`` names, and every segment jointed to one of them, has its
    long axis (:func:`_long_axis_line`) within ``START_POSE_DEG`` of the vertical over
    ``START_REST_S`` before ``start``: standing with the limbs hanging, as a protocol whose
    reference pose is another (the children's, lying supine) starts its arm movements."""
    for seg in _with_joint_partners(protocol, step):
        line = _long_axis_line(records.get(seg, {}))
        up = _up(streams, seg, start - START_REST_S, start)
        if line is None or up is None or abs(float(line @ up)) < np.cos(np.radians(START_POSE_DEG)):
            return False
    return True


def _with_joint_partners(protocol: Protocol, step) -> set[str]:
    """The segments ``step`` names and those jointed to one of them."""
    named = set(step.segments) | set(step.axis)
    for joint in protocol.joints.values():
        if {joint.proximal, joint.distal} & named:
            named |= {joint.proximal, joint.distal}
    return named


def data_signs(
    protocol: Protocol,
    streams: Streams,
    steps: dict[str, Any],
    records: dict[str, dict[str, AxisMeasurement]],
) -> dict[tuple[str, str], int]:
    """Which way the data point the functional axes measured without a sign: ``{(segment,
    step): ±1}``, +1 where the record's sensor axis already points so (the hint signed it
    right), for the records whose step tells it.

    A step that starts from the protocol's reference pose (its first static step: the step's
    segments and those jointed to them see gravity as there, :func:`_start_pose_kept`) and
    turns one way about its axis (the larger excursion, the gyroscope integrated from the
    step's start, at least ``ONE_WAY_MIN_DEG`` and ``ONE_WAY_RATIO`` times the other) turns
    about the axis as the protocol signs it: a shoulder or an elbow flexes forward (``z``), a
    trunk bends forward (``-z``), an arm abducts sideways (``-x`` on the right) from standing.
    The gyroscope is integrated less its mean over the reference pose (its bias: 2°/s, the
    ``harsh`` preset's, turned a 20-s trunk flexion's 50° out and back into 40° one way, and
    both trunk frames half a turn round: lumbar flexion read as extension, r = -0.99).
    A step that goes both ways (pronation, side bending) or starts elsewhere (the knee's seated
    flexion, which starts flexed and extends) tells nothing by its excursion; its axis, where
    it is the segment's long axis ``y`` and lies within ``LONG_AXIS_UP_DEG`` of the vertical in
    the reference pose, points up there (a forearm hanging with its carrying angle: its
    pronation axis). A segment that turns with a segment so signed carries its sign
    (:func:`_co_rotation_signs`: the pelvis in a forward bend, which tilts 8-18° and back).
    """
    ref_step = next((s for s in protocol.calibration if s.kind == "static"), None)
    ref = steps.get(ref_step.name) if ref_step is not None else None
    out: dict[tuple[str, str], int] = {}
    if ref is None:
        return out
    by_name = {s.name: s for s in protocol.calibration}
    for seg, recs in records.items():
        if seg not in streams:
            continue
        t, _, gyr = streams[seg]
        up = _up(streams, seg, *ref)
        up = np.zeros(3) if up is None else up
        still = (t >= ref[0]) & (t < ref[1])
        bias = gyr[still].mean(axis=0) if still.sum() >= 3 else np.zeros(3)
        for rec in recs.values():
            step = by_name.get(rec.step)
            span = steps.get(rec.step)
            if rec.kind != "functional" or rec.method != "svd" or step is None or not span:
                continue
            along = float(rec.segment_axis @ np.array([0.0, 1.0, 0.0]))
            upward = float(rec.sensor_axis @ up)
            if abs(along) > 0.99 and abs(upward) >= np.cos(np.radians(LONG_AXIS_UP_DEG)):
                out[seg, rec.step] = 1 if upward * along > 0 else -1  # up in the pose
                continue
            start = float(span[0])
            if not (
                _start_pose_kept(protocol, step, streams, start, ref)
                or _upright_start(protocol, step, streams, records, start)
            ):
                continue
            sel = (t >= span[0]) & (t <= span[1])
            if sel.sum() < 10:
                continue
            rate = (gyr[sel] - bias) @ rec.sensor_axis
            turned = np.degrees(np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1])
                                                                 * np.diff(t[sel]))]))  # fmt: skip
            pos, neg = float(turned.max()), float(-turned.min())
            if max(pos, neg) >= ONE_WAY_MIN_DEG and max(pos, neg) >= ONE_WAY_RATIO * min(pos, neg):
                out[seg, rec.step] = 1 if pos > neg else -1
    _co_rotation_signs(protocol, streams, steps, records, out)
    return out


def _co_rotation_signs(
    protocol: Protocol,
    streams: Streams,
    steps: dict[str, Any],
    records: dict[str, dict[str, AxisMeasurement]],
    signs: dict[tuple[str, str], int],
) -> None:
    """Add to ``signs`` the axes of segments a step names with the same axis as a segment
    already signed in it (the pelvis with the thorax in a forward bend, the forearm with the
    upper arm in a straight-arm raise): they turn together, so where their rates about their
    axes correlate (``|r|`` at least ``CO_ROTATION_MIN``) the sign carries over with r's."""
    for step in protocol.calibration:
        span = steps.get(step.name)
        if step.kind != "functional" or not span:
            continue
        named = [g for g in step.axis if g in streams and step.name in records.get(g, {})]
        for a in [g for g in named if (g, step.name) in signs]:
            for b in [g for g in named if (g, step.name) not in signs]:
                if step.axis[a] != step.axis[b]:
                    continue
                t, _, gyr_a = streams[a]
                sel = (t >= span[0]) & (t <= span[1])
                if sel.sum() < 10:
                    continue
                tb, _, gyr_b = streams[b]
                r_a = gyr_a[sel] @ records[a][step.name].sensor_axis
                r_b = np.interp(t[sel], tb, gyr_b @ records[b][step.name].sensor_axis)
                if np.std(r_a) == 0 or np.std(r_b) == 0:
                    continue
                r = float(np.corrcoef(r_a, r_b)[0, 1])
                if abs(r) >= CO_ROTATION_MIN:
                    signs[b, step.name] = signs[a, step.name] * (1 if r > 0 else -1)


def signs_contradicted(signs: dict[tuple[str, str], int]) -> set[str]:
    """Segments one of whose functional axes the data point against the hint's sign
    (:func:`data_signs`): a sensor half a turn round from the hint agrees with it in every
    axis compared without its sign (the elbow protocol with sensors strapped any way round: a
    forearm's pronation axis, its frame 180° off and its elbow 'weak' at 66-179° RMS)."""
    return {seg for (seg, _), sign in signs.items() if sign < 0}


def sign_by_data(
    records: dict[str, dict[str, AxisMeasurement]],
    signs: dict[tuple[str, str], int],
    contradicted: set[str],
) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """The functional axes of ``contradicted`` segments turned the way the data point them
    (:func:`data_signs`), in place; per segment, the ``(sensor axis, segment axis)`` pairs so
    signed (:func:`orient_by_data`)."""
    out: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for (seg, step), sign in signs.items():
        if seg in contradicted:
            rec = records[seg][step]
            rec.sensor_axis = sign * rec.sensor_axis
            out.setdefault(seg, []).append((rec.sensor_axis, rec.segment_axis))
    return out


def orient_by_data(
    protocol: Protocol,
    records: dict[str, dict[str, AxisMeasurement]],
    fits: dict[str, movement.HingeFit],
    contradicted: set[str],
    signed: dict[str, list[tuple[np.ndarray, np.ndarray]]] | None = None,
) -> dict[str, list[str]]:
    """Give the functional axes of ``contradicted`` segments their sign from the data.

    The segment's signed axes (:func:`_signed_axes`, and those the data signed, ``signed``:
    :func:`sign_by_data`) fix its frame when two of them differ (a Procrustes fit), or the sign
    of a parallel axis when there is one. Returns, per segment, the steps whose axis still
    follows the hint.
    """
    unsure: dict[str, list[str]] = {}
    for seg in contradicted:
        pairs = _signed_axes(protocol, seg, records[seg], fits) + (signed or {}).get(seg, [])
        v = np.array([s for s, _ in pairs]) if pairs else np.empty((0, 3))
        r = np.array([a for _, a in pairs]) if pairs else np.empty((0, 3))
        distinct = {tuple(np.abs(a).round(6)) for a in r}
        m = frames.wahba(v, r) if len(distinct) >= 2 else None
        for rec in records[seg].values():
            if rec.kind != "functional" or rec.method not in ("svd", "hinge"):
                continue
            if m is not None:
                rec.sensor_axis = orient(rec.sensor_axis, m @ rec.segment_axis)
                continue
            par = [k for k in range(len(r)) if abs(float(r[k] @ rec.segment_axis)) > 0.99]
            if par:
                k = par[0]
                rec.sensor_axis = orient(rec.sensor_axis, v[k] * float(r[k] @ rec.segment_axis))
            else:
                unsure.setdefault(seg, []).append(rec.step)
    return unsure


def centre_headings(
    session: Session, protocol: Protocol, streams: Streams
) -> dict[str, CentreHeading]:
    """Heading ties of the joints without a hinge from their shared centre, by joint name.

    ``{joint: CentreHeading}`` (``heading_times`` (K,) s, ``heading_deltas`` (K,) rad and
    ``anchors`` K) for the
    joints whose type ties headings by the centre (ball, hip; ``JointType.centre_heading``) and
    whose two sensors share enough movement
    (:func:`motionlab.clocksync.joint_centre.joint_centre_forces`, :func:`.heading.centre_anchors`).
    """

    out = {}
    for name, joint in protocol.joints.items():
        if not joint_type(joint.type).centre_heading:
            continue
        if joint.proximal not in streams or joint.distal not in streams:
            continue
        labels = [sensor_for_segment(session, s) for s in (joint.proximal, joint.distal)]
        forces = joint_centre_forces(*(session.sensors[k] for k in labels))
        if forces is None:
            continue
        t, f_p, f_d = forces
        q_p, q_d = (
            rot.resample(session.sensors[k].time, sensor_orientation(session, k), t) for k in labels
        )
        times, deltas = heading.centre_anchors(t, q_p, q_d, f_p, f_d)
        if len(times):
            out[name] = CentreHeading(times, deltas, anchors=len(times))
    return out
