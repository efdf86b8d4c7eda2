"""Sensor-to-segment calibration: from a protocol's poses and movements to mounting rotations.

The steps are found in the recording (:mod:`~motionlab.segments.steps`); for every segment, axes
measured in the sensor frame (gravity in static poses, :mod:`~motionlab.segments.static`;
rotation axes of functional movements, :mod:`~motionlab.segments.functional`, or Seel's hinge
fit, :mod:`~motionlab.segments.hinge`) are paired with the segment axes the protocol names and
fitted by ρ-weighted orthogonal Procrustes (:mod:`~motionlab.segments.mounting`,
:mod:`~motionlab.segments.frames`; Ricci 2015 ch. 6).

The mounting ``q_mount`` maps segment coordinates into sensor coordinates, so the segment's
orientation is ``q_segment = q_sensor ⊗ q_mount`` (segment → ENU earth). Without a magnetometer
each sensor has its own, slowly drifting heading; :func:`segment_orientations` turns each distal
segment about the vertical by a heading track through the joint's anchors (movements of both
segments about one axis, the reference pose and later rests in it;
:mod:`~motionlab.segments.heading`).
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.errors import InputError
from motionlab.kinematics.joint_types import flexion_axis, joint_type
from motionlab.protocol import Protocol, axis_vector
from motionlab.results import (
    AxisMeasurement,
    CentreHeading,
    GapTurn,
    HeadingCorrection,
    HeadingTie,
    HeadingTies,
    HipAxis,
    SegmentCalibration,
    SegmentRecord,
    TwoAxisFit,
)
from motionlab.segments import (
    arm_sides,
    grades,
    heading,
    hip_axis,
    mounting,
    placement,
    single_pose,
    skin_lag,
    trunk_axes,
    walk_checks,
    walk_forward,
)
from motionlab.segments.sensors import (
    Streams,
    corrected_acc,
    joint_segments,
    sensor_orientation,
    sensor_quats,
    streams_of,
)
from motionlab.segments.steps import blocks, find_steps, reference_step, task_window
from motionlab.session import Session


def calibrate_segments(
    session: Session, protocol: Protocol, warnings: list[str] | None = None
) -> SegmentCalibration:
    """Sensor-to-segment calibration of every segment (stored in ``results.calibration``).

    Lines about the recording that the user should read (a nominal placement the data
    contradicts) are added to ``warnings`` and kept in the result's ``warnings``.
    """
    if trunk_axes.applies(protocol):  # rest and trunk movement anywhere (lumbar_seated)
        result = trunk_axes.calibrate(session, protocol, warnings)
        result.headings = heading_ties(session, protocol, result)
        result.gap_turns = gap_headings(session, protocol, result.headings, result.centres)
        result.grades = grades.gap_graded(result.grades, result.gap_turns, protocol, result)
        result.grades = grades.clock_graded(result.grades, protocol, session)
        return result
    notes: list[str] = []
    streams = streams_of(session, protocol)
    pose = single_pose.pose_step(session, protocol, streams)
    hinges: dict[str, Any] = {}
    contradicted: set[str] = set()
    unsure: dict[str, list[str]] = {}
    centres: dict[str, CentreHeading] = {}
    forward_from = ""  # what gave the pelvis its forward direction (pelvis_forward)
    if pose is not None:  # orientations too short for more (OpenSense-style)
        steps, records = single_pose.measure(session, protocol, streams, pose, notes)
    else:
        check = walk_checks.pose_check(session, protocol, streams)
        steps = find_steps(streams, protocol, notes, pose_check=check)
        records = mounting.measure(protocol, streams, steps)
        contradicted = placement.contradicted(protocol, records)
        hinges = placement.movement_hinges(session, protocol, streams, steps, records, contradicted)
        contradicted |= placement.sign_contradicted(protocol, records, hinges)
        hinges = {  # a fit that only checked a step's sign, and found it right, is not kept
            name: fit for name, fit in hinges.items() if fit.used_for != "direction"
            or {protocol.joints[name].proximal, protocol.joints[name].distal} & contradicted
        }  # fmt: skip
        signs = placement.data_signs(protocol, streams, steps, records)
        contradicted |= placement.signs_contradicted(signs)
        signed = placement.sign_by_data(records, signs, contradicted)
        unsure = placement.orient_by_data(protocol, records, hinges, contradicted, signed)
        centres = placement.centre_headings(session, protocol, streams)
        forward_from = pelvis_forward(
            session, protocol, streams, steps, records, contradicted, notes
        )
    segments = {}
    for seg in streams:
        res = mounting.fit(seg, protocol, records[seg])
        segments[seg] = replace(
            res,
            sensor=sensor_for_segment(session, seg),
            hint_contradicted=seg in contradicted,
            unsigned_steps=unsure.get(seg),
        )
    if forward_from in ("walk start", "walk end") and "pelvis" in segments:  # legs' sides
        after, before = task_window(streams, protocol, steps)
        walk_checks.sides_check(session, protocol, streams, segments["pelvis"], after, before)
    for seg, names in unsure.items():
        _flag(
            segments,
            seg,
            f"{seg}: the direction of the axis from {', '.join(names)} follows the nominal "
            "placement, which the data contradicts",
        )
    for name, fit in hinges.items():
        if fit.verdict != "determined" and fit.used_for == "axes":
            joint = protocol.joints[name]
            for seg in (joint.proximal, joint.distal):
                # a fit not determined stands in for a hint that says nothing (fills_hint)
                used = any(r.step == f"movement:{name}" for r in segments[seg].axes.values())
                _flag(
                    segments,
                    seg,
                    f"{seg}: the {name} axis from the movement is {fit.verdict}: "
                    + ("; ".join(fit.reasons) or "see the calibration page")
                    + (STANDS_IN if used and fit.verdict == "not determined" else ""),
                )
    if warnings is not None:
        warnings.extend(notes)
    result = SegmentCalibration(
        protocol.name,
        steps={k: (list(v) if v else None) for k, v in steps.items()},
        segments=segments,
        hinges=dict(hinges),
        centres=centres,
        warnings=notes,
        ok=all(s.quality.ok for s in segments.values()),
        single_pose=pose.name if pose is not None else None,
    )
    result.headings = heading_ties(session, protocol, result)  # first: the hip axes reuse them
    result.gap_turns = gap_headings(session, protocol, result.headings, result.centres)
    result.grades = grades.gap_graded(
        grades.grade_joints(protocol, result), result.gap_turns, protocol, result
    )
    result.grades = grades.hold_graded(
        result.grades,
        unheld_headings(session, protocol, result.headings),
        drift_beyond_anchors(session, protocol, result.headings),
    )
    result.grades = grades.clock_graded(result.grades, protocol, session)
    if pose is None:
        result.hip_axes = hip_axes(session, protocol, result)
        if any(joint_type(j.type).name == "elbow" for j in protocol.joints.values()):
            hanging = arm_sides.pose_hanging(session, protocol, result)
            carrying = arm_sides.hanging_only(
                arm_sides.pose_carrying(
                    protocol,
                    result,
                    segment_orientations(protocol, result, sensor_quats(session, protocol)),
                ),
                hanging,
            )
            sides = arm_sides.side_warnings(session, protocol, result.grades, carrying)
            sides += arm_sides.hang_warnings(protocol, result, hanging)
            result.grades = arm_sides.side_graded(result.grades, carrying)
            result.grades = arm_sides.hang_graded(result.grades, hanging)
            result.warnings = [*result.warnings, *sides]
            if warnings is not None:
                warnings.extend(sides)
    return result


#: what a segment's flag adds when a fit not determined gave its frame the axes all the same
STANDS_IN = "; the frame takes it all the same: its placement hint says nothing"
#: heading ties anchored only where a pose was held (the stand, later rests in it, a single
#: pose) or, a hip's, where the walk went straight: the heading drifts freely in between, and a
#: turn about the vertical that a packet-loss gap hid stays until the next anchor
HELD_TIES = ("steps", "single pose", "walk")
#: how far apart (deg) two ties of one held pose may lie with no drift at all: a person stands
#: a little differently each time (the real 16-IMU walk's rests 7 s apart: hip rotation 2.5°
#: and 5° apart), so that much of the change between the first and the last is not drift
POSE_SCATTER_DEG = 5.0
#: a gap with a walk's anchors this close (s) on both sides is taken out by them (one a second)
GAP_BRACKET_S = 5.0


def gap_headings(
    session: Session,
    protocol: Protocol,
    ties: HeadingTies,
    centres: dict[str, CentreHeading] | None = None,
) -> dict[str, GapTurn]:
    """``{joint: GapTurn}``: for each joint whose heading is tied only at poses or straight
    walking (:data:`HELD_TIES` in ``ties``, or a trunk's rest in ``centres``: method ``trunk
    rest``), the turn the packet-loss gaps of either sensor after the first anchor may together
    have hidden (each gap's from the fusion's ``gaps_missed_deg``: what its bridge misses on test
    gaps around it, :func:`motionlab.fusion.timegrid.gap_noise`; combined as independent errors,
    the root of the sum of squares), leaving out a gap whose walk's anchors lie within
    ``GAP_BRACKET_S`` before its first lost sample and after its last; joints with none are left
    out. In 6-D nothing measures such a turn about the vertical where it happens: the hinge ties
    of a knee, and a walk's ties around the gap, take it out within seconds; a pose's hold it
    from the gap on, and a later pose's only spread it over the time between the two (the track
    is linear between anchors), so the turns of several gaps add up. Each gap's figure is the
    root mean square of its test gaps' misses, and one gap in ten misses 1.7 times that or more
    (the real 16-IMU walk with 15 bursts of lost packets per sensor, 10 draws: 660 gaps): the
    largest gap alone had graded a hip `weak` whose rotation then read 35° RMS off the unbroken
    recording's. A stored list that is not finite ``[s, deg]`` pairs is an :class:`InputError`
    naming it."""
    anchored = {name: (tie.times, tie.source) for name, tie in ties.joints.items()
                if tie.source in HELD_TIES}  # fmt: skip
    anchored |= {name: (c.heading_times, "trunk rest") for name, c in (centres or {}).items()
                 if c.method == "trunk rest"}  # fmt: skip
    out = {}
    for name, (times, source) in anchored.items():
        if not len(times) or name not in protocol.joints:
            continue
        times = np.asarray(times, float)
        first = float(np.min(times))
        walking = times if source == "walk" else np.empty(0)
        joint = protocol.joints[name]
        hidden = []  # (deg, sensor, first instant after the gap)
        for seg in (joint.proximal, joint.distal):
            label = sensor_for_segment(session, seg)
            entry = session.results.fusion.get(label) if label is not None else None
            stamps = session.sensors[label].time if label in session.sensors else np.empty(0)
            for t, deg in _gap_turns(entry, label):  # t: the first sample after the gap
                begins = stamps[max(int(np.searchsorted(stamps, t)) - 1, 0)] if len(stamps) else t
                before = np.any((walking < begins) & (walking >= begins - GAP_BRACKET_S))
                after = np.any((walking > t) & (walking <= t + GAP_BRACKET_S))
                if t > first and not (before and after) and deg > 0:
                    hidden.append((float(deg), label, float(t)))
        if hidden:
            deg, label, t = max(hidden)
            total = float(np.sqrt(sum(d**2 for d, _, _ in hidden)))
            out[name] = GapTurn(total, label, t, gaps=len(hidden))
    return out


def _recorded_span(session: Session, joint) -> tuple[float, float] | None:
    """First and last instant (s) either of a joint's sensors recorded; ``None`` without one."""
    labels = [sensor_for_segment(session, s) for s in (joint.proximal, joint.distal)]
    spans = [session.sensors[k].time[[0, -1]] for k in labels if k in session.sensors]
    if not spans:
        return None
    return min(float(a) for a, _ in spans), max(float(b) for _, b in spans)


def unheld_headings(session: Session, protocol: Protocol, ties: HeadingTies) -> dict[str, float]:
    """``{joint: s}``: for each joint whose heading is tied only at poses or straight walking
    (:data:`HELD_TIES`), how far its recording (both sensors' spans) reaches from those anchors:
    before the first, after the last, half the longest time between two (the heading track is
    linear between anchors, so a steady drift there is taken out and the rest peaks about
    midway)."""
    out = {}
    for name, tie in ties.joints.items():
        if tie.source not in HELD_TIES or name not in protocol.joints or not len(tie.times):
            continue
        span = _recorded_span(session, protocol.joints[name])
        if span is None:
            continue
        anchors = np.sort(np.asarray(tie.times, float))
        reach = max(anchors[0] - span[0], span[1] - anchors[-1], 0.0)
        if len(anchors) > 1:
            reach = max(reach, float(np.max(np.diff(anchors))) / 2)
        out[name] = float(reach)
    return out


def drift_beyond_anchors(
    session: Session, protocol: Protocol, ties: HeadingTies
) -> dict[str, tuple[float, float]]:
    """``{joint: (deg/s, s)}``: for each joint tied at its protocol's poses and rests (source
    ``steps``), the rate its anchors put its two headings drifting apart at (the change from
    the first to the last, :func:`.heading.drift_rate`, less ``POSE_SCATTER_DEG``, over the
    time between them) and how far its recording reaches before the first anchor or after the
    last, where the heading track holds (between anchors it is linear: a steady drift is taken
    out). A walk's ties are left out: they hold the hip's mean rotation in walking as well."""
    out = {}
    for name, tie in ties.joints.items():
        if tie.source != "steps" or name not in protocol.joints or not len(tie.times):
            continue
        span = _recorded_span(session, protocol.joints[name])
        if span is None:
            continue
        first, last = float(min(tie.times)), float(max(tie.times))
        drifted = abs(float(np.degrees(heading.drift_rate(tie.times, tie.deltas)))) * (last - first)
        rate = max(drifted - POSE_SCATTER_DEG, 0.0) / max(last - first, 1e-9)
        out[name] = (rate, max(first - span[0], span[1] - last, 0.0))
    return out


def _gap_turns(entry: Any, label: str | None) -> np.ndarray:
    """(K, 2) ``[s, deg]`` of a fusion entry's ``gaps_missed_deg`` (none without one)."""
    missed = getattr(entry, "gaps_missed_deg", None)
    if missed is None:
        return np.zeros((0, 2))
    try:
        pairs = np.asarray(missed, dtype=float)
        ok = pairs.ndim == 2 and pairs.shape[1] == 2 and np.isfinite(pairs).all()
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(
            "is not a list of finite [time s, turn deg] pairs",
            where=f"results/fusion/{label}/gaps_missed_deg",
            remedy="fuse again with force=True",
            argument="force",
        )
    return pairs


def _flag(segments: dict[str, SegmentRecord], seg: str, message: str) -> None:
    """``message`` added to a segment's quality messages, its quality no longer ``ok``."""
    q = segments[seg].quality
    segments[seg] = replace(
        segments[seg], quality=replace(q, ok=False, messages=[*q.messages, message])
    )


def heading_ties(
    session: Session, protocol: Protocol, calibration: SegmentCalibration
) -> HeadingTies:
    """Each joint's heading ties (see :func:`segment_orientations`) from the orientations of the
    sensors on the protocol's joints, joints taken along the chain, with the SHA-256 of each
    segment's orientations (:func:`orientations_sha256`). Stored in the calibration, so the
    angles (and metrics, gait, the hip axes) apply them without finding them again. Ties
    already stored elsewhere in the calibration (a two-axis fit's, a ball joint's centre) are
    not repeated."""
    segs = [s for s in joint_segments(protocol) if sensor_for_segment(session, s) is not None]
    quats = sensor_quats(session, protocol, segs)
    ties: dict[str, HeadingTie] = {}
    segment_orientations(protocol, calibration, quats, ties=ties)
    return HeadingTies(
        sha256={seg: orientations_sha256(*tq) for seg, tq in quats.items()},
        joints={j: v for j, v in ties.items() if v.source not in FITTED_TIES},
    )


#: tie sources stored with their fit (``calibration.hinges``, ``calibration.centres``)
FITTED_TIES = ("two_axes", "centre")


def orientations_sha256(time: np.ndarray, quat: np.ndarray) -> str:
    """SHA-256 of one segment's sensor orientations: times (s) and quaternions as float64
    bytes."""
    digest = hashlib.sha256()
    for a in (time, quat):
        digest.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return digest.hexdigest()


def pelvis_forward(
    session: Session,
    protocol: Protocol,
    streams: Streams,
    steps: dict[str, Any],
    records: dict[str, dict[str, AxisMeasurement]],
    contradicted: set[str],
    notes: list[str],
) -> str:
    """The hips' proximal segment's forward direction from the walk's first steps (the walk
    begins with the longest movement after the stand, :func:`walk_begins`), or where they do
    not give it (the walk does not start right after the stand, or turns in its first steps)
    from its turns
    (:mod:`.walk_forward`), added
    to its ``records`` (kind ``movement``, method ``turns``, ``walk start`` or ``walk end``: the
    last steps before a stand that ends the walk; secondary: gravity
    keeps the tilt) when the recording measured only its vertical axis and the placement hint is
    contradicted: by the stand (its vertical, :func:`.placement.contradicted`) or by the walk
    (its forward direction further from the hint's than the walk's own bound,
    ``grades.HEADING_BOUND_DEG``, plus a strapped hint's, ``walk_forward.HINT_HEADING_DEG``). The
    single turns may disagree more where the stand refuted the hint
    (``walk_forward.MAX_SPREAD_CONTRADICTED_DEG``). A line goes to ``notes`` when the hint is not
    kept. Returns the method the pelvis frame's forward direction now agrees with (``walk
    start`` or ``turns``: taken from it, or the hint within its bound), ``""`` where none gave
    one."""
    hips = [j for j in protocol.joints.values() if joint_type(j.type).name == "hip"]
    if not hips:
        return ""
    seg = hips[0].proximal
    recs = records.get(seg, {})
    gravity = [r for r in recs.values() if r.method == "gravity" and r.kind == "static"]
    if not gravity or mounting._distinct(list(recs.values())) != 1:
        return ""
    label = sensor_for_segment(session, seg)
    s = session.sensors[label] if label is not None else None
    rng = steps.get(gravity[0].step)
    if s is None or s.acc is None or s.gyr is None or not rng:
        return ""
    up = np.asarray(gravity[0].sensor_axis, float) * float(
        np.sign(gravity[0].segment_axis @ np.array([0.0, 1.0, 0.0])) or 1.0
    )
    q = sensor_orientation(session, label)
    by_stand = seg in contradicted
    spread = walk_forward.MAX_SPREAD_CONTRADICTED_DEG if by_stand else walk_forward.MAX_SPREAD_DEG
    acc = corrected_acc(session, label)
    after, before = task_window(streams, protocol, steps)
    if np.isfinite(before):  # the walk ends with the stand
        found = walk_forward.forward_from_end(s.time, acc, q, up, walk_ends(streams, before))
        method, words = "walk end", "the last steps of the walk"
    else:
        begin = walk_begins(streams, float(rng[1]))
        found = walk_forward.forward_from_start(s.time, acc, q, up, begin)
        method, words = "walk start", "the first steps of the walk"
    if not found.used:
        found = walk_forward.forward_from_turns(
            s.time, acc, q, s.gyr, up, after, spread, before_s=before
        )
        method, words = "turns", f"the walk's turns ({found.turns})"
    if not found.used:
        if by_stand:
            _add_note(
                notes,
                seg,
                f"the walk did not give its forward direction ({found.reason}): the pelvis "
                "angles and the hips use the hint's",
            )
        return ""
    hint = protocol.segments[seg].nominal_mounting().T @ np.array([1.0, 0.0, 0.0])
    off = float(np.degrees(np.arccos(np.clip(found.axis @ hint, -1.0, 1.0))))
    # the walk's forward direction is taken wherever it was found: its bound (10° from the first
    # steps, 20° from the turns) is no wider than a strapped hint's (20°), and a hint kept for
    # agreeing with it left the hips graded by the nominal placement (weak) where a sensor
    # strapped any way round got them determined
    why = "" if by_stand else f"{words} are {off:.0f}° from the hint's forward; "
    _add_note(notes, seg, f"{why}its forward direction is taken from {words}")
    recs["movement:turns"] = AxisMeasurement(
        step="movement:turns",
        kind="movement",
        method=method,
        sensor_axis=found.axis,
        segment_axis=np.array([1.0, 0.0, 0.0]),
        rho=walk_forward.RHO,
        secondary=True,
        verdict="weak",
        turns=found.turns,
        spread_deg=found.spread_deg if found.spread_deg is not None else float("nan"),
    )
    return method


def walk_begins(streams: Streams, after_s: float) -> float:
    """When (s) the walk after a stand that ends at ``after_s`` begins: the start of the longest
    movement block after it (:func:`.steps.blocks`), ``after_s`` itself without one. The
    calibration takes the stand's first rest long enough; a person who shifts, sways or steps
    in place before setting off splits the stand, and the walk's first steps, which give the
    pelvis its forward direction (:func:`.walk_forward.forward_from_start`), then begin at the
    end of its last rest, not of its first (the 16-IMU walk cut to 10.6 s of such a stand and
    14-25 s of walking: the hips went from `not determined` to determined)."""
    moving = [b for b in blocks(streams) if b.moving and b.end > after_s]
    if not moving:
        return after_s
    longest = max(moving, key=lambda b: b.end - b.start)
    return max(after_s, longest.start)


def walk_ends(streams: Streams, before_s: float) -> float:
    """When (s) the walk before a stand that starts at ``before_s`` ends: the end of the
    longest movement block before it, ``before_s`` itself without one (:func:`walk_begins`
    the other way round: a walker who shuffles before standing still)."""
    moving = [b for b in blocks(streams) if b.moving and b.start < before_s]
    if not moving:
        return before_s
    longest = max(moving, key=lambda b: b.end - b.start)
    return min(before_s, longest.end)


def _add_note(notes: list[str], segment: str, text: str) -> None:
    """``text`` joined to the segment's line in ``notes`` (one line per segment), else a new
    line."""
    for i, line in enumerate(notes):
        if line.startswith(f"{segment}: "):
            notes[i] = f"{line}; {text}"
            return
    notes.append(f"{segment}: {text}")


def _long_axis_measured(cal: SegmentRecord, axis: np.ndarray) -> bool:
    """Whether a calibration movement (a functional step) measured this segment axis."""
    return any(
        r.kind == "functional" and r.in_fit
        and abs(float(np.asarray(r.segment_axis) @ axis)) > 0.99
        for r in cal.axes.values()
    )  # fmt: skip


def hip_axes(
    session: Session, protocol: Protocol, calibration: SegmentCalibration
) -> dict[str, HipAxis]:
    """The hips' flexion axes from the movement (:mod:`.hip_axis`), by joint name, for the hip
    joints whose thigh's flexion axis no functional step measured."""
    out: dict[str, HipAxis] = {}
    for name, joint in protocol.joints.items():
        p, d = joint.proximal, joint.distal
        if joint_type(joint.type).name != "hip" or p not in calibration.segments:
            continue
        cal_d = calibration.segments.get(d)
        if cal_d is None or _long_axis_measured(cal_d, axis_vector(flexion_axis(joint))):
            continue
        quats = sensor_quats(session, protocol, [p, d])
        seg_q = segment_orientations(protocol, calibration, quats)
        t = seg_q[p][0]
        t = t[(t >= seg_q[d][0][0]) & (t <= seg_q[d][0][-1])]
        qp, qd = rot.resample(*seg_q[p], t), rot.resample(*seg_q[d], t)
        out[name] = hip_axis.flexion_turn(t, qp, qd)
    return out


def heading_anchors(
    protocol: Protocol, joint, steps: dict[str, Any], t: np.ndarray, qp: np.ndarray, qd: np.ndarray
) -> tuple[list[float], list[float]]:
    """Times (s) and heading offsets δ (rad) of one joint (see :mod:`.heading`).

    ``qp`` and ``qd`` are the joint's segment orientations on the common time ``t``.
    """
    times, deltas = [], []
    p, d = joint.proximal, joint.distal
    for step in protocol.calibration:  # movements of both segments about one axis
        rng = steps.get(step.name)
        if step.kind == "functional" and rng and step.axis.get(p, "?") == step.axis.get(d):
            sel = (t >= rng[0]) & (t <= rng[1])
            if sel.sum() > 2:
                w_p = heading.earth_rates(t[sel], qp[sel])
                w_d = heading.earth_rates(t[sel], qd[sel])
                times.append(0.5 * (rng[0] + rng[1]))
                deltas.append(heading.heading_from_rates(w_p, w_d))
    name = reference_step(protocol, p, d)
    if name is None:
        return times, deltas
    va = protocol.calibration[[s.name for s in protocol.calibration].index(name)].vertical_axis
    axis_p, axis_d = axis_vector(va[p]), axis_vector(va.get(d, va[p]))
    if times and abs(axis_p[1]) < 0.5:
        return times, deltas  # pose not about the long axis (supine): no pose anchors
    # the reference pose ties first; the movements' ties and later rests join in time order
    # where they keep to its track (a turned trunk's held pose does not; nor does a movement's
    # tie that imperfect gyroscopes threw off: 11-20° on the harsh preset)
    candidates = sorted(zip(times, deltas, strict=True))
    times, deltas = [], []
    rng = steps.get(name)
    if rng:
        w = slice(*np.searchsorted(t, rng))
        if w.stop - w.start > 2:
            times.append(float(t[w].mean()))
            deltas.append(heading.heading_from_pose(qp[w], qd[w]))
    for w in heading.reference_rests(t, qp, qd, axis_p, axis_d, loose_distal=d not in va):
        candidates.append((float(t[w].mean()), heading.heading_from_pose(qp[w], qd[w])))
    turned = np.cumsum(np.abs(heading.earth_rates(t, qp)[:, 2]) * np.gradient(t))
    for at, delta in sorted(candidates):
        if times and not heading.on_track(times, deltas, at, delta, turned, t):
            continue  # a held pose (a turned trunk) or a thrown-off tie
        times.append(at)
        deltas.append(delta)
    return times, deltas


def chain_order(protocol: Protocol) -> list:
    """The protocol's joints, each after the joint whose distal segment is its proximal one
    (so a segment's heading is final before its distal neighbour is turned to it)."""
    todo = list(protocol.joints.values())
    out: list = []
    while todo:
        distal_of_todo = {j.distal for j in todo}
        ready = [j for j in todo if j.proximal not in distal_of_todo] or todo[:1]  # a loop
        out += ready
        todo = [j for j in todo if j not in ready]
    return out


def segment_orientations(
    protocol: Protocol,
    calibration: SegmentCalibration | None,
    sensor_quats: dict[str, tuple[np.ndarray, np.ndarray]],
    align_heading: bool = True,
    corrections: dict[str, HeadingCorrection] | None = None,
    ties: dict[str, dict[str, Any]] | None = None,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{segment: (time, q_segment)}`` from sensor orientations ``{segment: (time, q_sensor)}``.

    With ``align_heading`` each joint's distal segment is turned about the vertical by the
    heading track ``δ(t)`` of the joint, joints taken along the chain (:func:`chain_order`):
    for a joint calibrated from movement the hinge constraint over the whole recording
    (:func:`.heading.hinge_anchors`), or the headings fitted with a two-axis joint's axes or
    from a ball joint's shared centre (added to the track its proximal segment was turned by);
    a single-pose calibration (:mod:`.single_pose`) its pose; otherwise the anchors of the
    protocol's steps and rests (:func:`heading_anchors`), for a hip with those of the walk's
    straight stretches (:func:`.heading.walk_anchors`). Without a
    calibration (``None``) or its entry for a segment the sensor frame is used as the segment
    frame.
    ``corrections``, when given, receives per joint the heading correction applied
    (:class:`~motionlab.results.HeadingCorrection`). The ties are those stored in
    ``calibration.headings`` (:func:`heading_ties`) for a joint whose sensors, and every
    segment's up the chain, have the orientations they were found from (same SHA-256 per
    segment), else found here; ``ties``, when given, receives them (``{joint: HeadingTie}``,
    before the proximal segment's turn is added to fitted headings).
    """
    calibration = calibration or SegmentCalibration("")
    kept = calibration.headings or HeadingTies()
    hashes = kept.sha256
    stored_ties = kept.joints if align_heading else {}
    same = {seg for seg, tq in sensor_quats.items() if stored_ties
            and seg in hashes and hashes[seg] == orientations_sha256(*tq)}  # fmt: skip
    out = {}
    for seg, (t, q) in sensor_quats.items():
        cal = calibration.segments.get(seg)
        q_mount = np.asarray(cal.mounting) if cal else rot.IDENTITY
        out[seg] = (t, rot.make_continuous(rot.mul(q, q_mount)))
    if not align_heading:
        return out
    turned: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # segment: (time, δ applied)
    lagging: list = []  # joints whose fitted axes and ties are used, their skin lag to undo
    for joint in chain_order(protocol):
        p, d = joint.proximal, joint.distal
        if p not in out or d not in out:
            continue
        tp, qp = out[p]
        td, qd = out[d]
        # stored ties hold when both sensors' orientations are those they were found from and
        # so is every segment up the chain (the proximal's turn is theirs)
        if p not in same:
            same.discard(d)
        stored = stored_ties.get(joint.name) if d in same else None
        if stored is not None:
            source = stored.source
            times = np.asarray(stored.times, float)
            deltas = np.asarray(stored.deltas, float)
        else:
            source, times, deltas = _joint_ties(protocol, calibration, joint, tp, qp, td, qd)
            times, deltas = np.asarray(times, float), np.asarray(deltas, float)
        if ties is not None:
            ties[joint.name] = HeadingTie(source, times, deltas)
        if source in ("two_axes", "centre") and p in turned:
            deltas = deltas + np.interp(times, *turned[p])  # fitted on the proximal's own heading
        if len(times):
            track = heading.heading_track(np.array(times), np.array(deltas), td)
            out[d] = (td, rot.make_continuous(heading.apply_heading(qd, track)))
            turned[d] = (td, track)
        if corrections is not None:
            corrections[joint.name] = _correction(source, times, deltas, td)
        if source == "two_axes":
            lagging.append(joint)
    return _lag_undone(protocol, calibration, lagging, out)


def _lag_undone(protocol: Protocol, calibration: SegmentCalibration, joints: list, out: dict):
    """``out`` with the proximal segment of each of ``joints`` turned about its long axis by
    the part of its twist against the trunk that its sensor's skin did not follow
    (:mod:`.skin_lag`), where the fit measured that part and the trunk has a sensor."""
    for joint in joints:
        fit = calibration.hinges.get(joint.name)
        reference = calibration.steps.get(
            reference_step(protocol, joint.proximal, joint.distal) or ""
        )
        if not skin_lag.lag_undone(fit) or fit.lag_anchor not in out or not reference:
            continue
        t, q = out[joint.proximal]
        out[joint.proximal] = (
            t, skin_lag.undo_lag(t, q, tuple(reference), fit.axial_follow, out[fit.lag_anchor])
        )  # fmt: skip
    return out


def _joint_ties(protocol: Protocol, calibration: SegmentCalibration, joint, tp, qp, td, qd):
    """``(source, times s, δ rad)`` of one joint's heading anchors (see
    :func:`segment_orientations`): the headings stored with a two-axis fit or a ball joint's
    centre, the hinge over the whole recording, the pose of a single-pose calibration, or the
    steps' anchors, joined for a hip in a protocol with a walk by the walk's straight stretches
    away from the poses (:func:`.heading.with_walk_anchors`: source ``walk``)."""
    fit = placement.fit_in_use(calibration, joint)  # None: the steps' anchors
    if isinstance(fit, TwoAxisFit):
        times = np.asarray(fit.heading_times, float)
        return "two_axes", times, np.asarray(fit.heading_deltas, float)
    stored = calibration.centres.get(joint.name) if fit is None else None
    if stored is not None:
        times = np.asarray(stored.heading_times, float)
        return "centre", times, np.asarray(stored.heading_deltas, float)
    qd_on_p = rot.resample(td, qd, tp)
    pose_range = calibration.steps.get(calibration.single_pose or "")
    if pose_range:
        return ("single pose", *single_pose.heading_anchor(tuple(pose_range), tp, qp, qd_on_p))
    if fit is not None:
        axis = axis_vector(placement.hinge_spec(joint)[0])
        ref_name = reference_step(protocol, joint.proximal, joint.distal)
        twists = placement.twists_about_long_axis(
            protocol, joint, ref_name, placement.hinge_spec(joint)
        )
        long_axis = axis_vector("y") if twists else None
        return ("hinge", *heading.hinge_anchors(tp, qp, qd_on_p, axis, axis, long_axis))
    times, deltas = heading_anchors(protocol, joint, calibration.steps, tp, qp, qd_on_p)
    if joint_type(joint.type).name == "hip" and any(task.is_gait for task in protocol.tasks):
        joined = heading.with_walk_anchors(times, deltas, *heading.walk_anchors(tp, qp, qd_on_p))
        if joined is not None:  # the walk's own ties, put on the stand's hip rotation
            return ("walk", *joined)
    return "steps", times, deltas


def _correction(source: str, times, deltas, t: np.ndarray) -> HeadingCorrection:
    """What a joint's heading alignment did, in degrees (see :func:`segment_orientations`)."""
    if not len(times):
        return HeadingCorrection(source, 0)
    track = np.degrees(heading.heading_track(np.array(times), np.array(deltas), t))
    minutes = (t[-1] - t[0]) / 60.0
    return HeadingCorrection(
        source,
        len(times),
        mean_deg=float(np.mean(track)),
        range_deg=float(np.ptp(track)),
        drift_deg_per_min=float((track[-1] - track[0]) / minutes) if minutes > 0 else 0.0,
    )
