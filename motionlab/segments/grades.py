"""An honest grade for every joint angle: did the recording determine it?

Each angle of each joint is graded from what its two segments' calibrations actually used:

- ``determined``: every axis the angle depends on was measured — for the angle about a hinge
  axis (flexion of a knee or elbow, a generic hinge's angle) the axis itself, from a functional
  step or from movement with a ``determined`` fit, and its zero: both segment frames measured
  whole (a segment with only the hinge axis measured takes its turn about that axis, hence the
  angle's zero, from the placement hint); for the other angles both segment frames from two
  independent measured axes (a static pose's gravity, a movement's axis) with no quality
  message;
- ``weak``: one measured axis and the nominal placement (the protocol's ``sensor_axes`` hint)
  for the rest, a ``weak`` hinge fit, or a calibration the quality checks flagged;
- ``not determined``: a segment with no measured axis at all, one with a single measured axis
  whose placement hint the data contradict (the hint would give the rest of its frame), or a
  failed or inconsistent fit.

A knee calibrated from a walk (:mod:`.gait_axes`) knows its flexion axis only to within the angle
between its two estimates (the principal axes and the constrained hinge fit), the ``witness``,
and on top of it ``AXIS_FLOOR_DEG``, which both estimates share: they see the plane the leg swings
in, which lies some degrees from the knee's own axis with the foot's progression angle and the
hip's rotation (functional and anatomical knee axes differ by about 5°, Della Croce et al. 2005,
Med Biol Eng Comput 43:275). The two are independent and add in quadrature,
``e = √(witness² + AXIS_FLOOR_DEG²)`` (the larger of the two alone called a short walk's 60° of
flexion with estimates 3° apart ``weak``, 5.2°, where the two together carry 6.1°). An axis
turned by ``e`` moves ``sin(e)`` of the flexion into ab/adduction and rotation, so those two
angles are graded by that cross-talk, ``flexion excursion × sin(e)``: up to ``CROSSTALK_DEG[0]``
determined, up to ``CROSSTALK_DEG[1]`` weak, beyond it not determined. On real walks (estimates
1.5-10° apart, flexion 75-100° over the recording) that is 6.8-19°: a walk alone does not
determine a real knee's ab/adduction and rotation.

A knee whose shank took its flexion axis only from steps that flex the knee itself (the knee
protocol's seated knee flexion, without its optional straight-leg hip flexions) has its
ab/adduction and rotation ``weak``: the tibia turns about its long axis as the knee leaves
extension (screw-home, ``SCREW_HOME_DEG``), and the flexion axis, fixed in the femur, turns with
it as the tibia sees it, so the shank's axis is turned about its long axis by that rotation's
mean over the movement (12-13° on the simulated knee), which carries flexion into the other two
angles (:func:`_coupled_axis_grade`; docs/kinematics.md, "Optional steps whatever the mounting").

A hip whose pelvis took its forward direction from the walk (:mod:`.walk_forward`: the first
steps, about 5-10° off, or the turns, often 5-25°) has its frame turned about the vertical by up
to ``HEADING_BOUND_DEG``. Flexion is about an axis in the horizontal plane: a frame turned by
``e`` about the vertical reads a flexion ``θ`` as ``θ cos(e)`` to first order, an error of at
most ``θ (1 - cos e)`` (ZXY decomposition, checked numerically: 45° at 20° reads 43.2°), while
``θ sin(e)`` goes into ab/adduction and rotation. So hip flexion is graded by
``θ (1 - cos e)`` with ``θ`` how far the thigh tilted from the stand (its knee fit's
``proximal_tilt_deg``), against ``CROSSTALK_DEG``; ab/adduction and rotation stay ``weak``.

An elbow calibrated from free movement (:func:`.movement.fit_two_dof`) whose upper-arm sensor
was found to follow less than ``AXIAL_FOLLOW_DETERMINED`` of the humerus' rotation about its
long axis has its carrying angle and pronation ``weak``: the rotation the skin misses goes into
them to first order, and into flexion only through the carrying angle (:func:`_lag_grade`).

A joint whose heading is tied only where a pose was held (a hip; a seated trunk at its rest) is
graded by the turn the packet-loss gaps after the first pose may together have hidden (each
gap's possible miss, combined as independent errors; ``calibration.gap_turns``,
:func:`motionlab.segments.gap_headings`, :func:`gap_graded`):
``weak`` over ``GAP_TURN_DEG``, ``not determined`` over twice it; in 6-D that turn stays in the
heading, while a knee's hinge ties take it out within seconds. A hip's flexion, about a
horizontal axis, is graded instead by what that turn about the vertical moves it by, as for
the pelvis's forward direction above: ``tilt (1 − cos turn)`` with the thigh's largest tilt over
the recording, against ``CROSSTALK_DEG`` (simulated walks, turns of 20-32° with the thighs
tilting 30-32°: flexion 1.5-2.6° RMSE, where all three angles had been ``not determined``;
the real 16-IMU walk with lost packets, turns of 45-120°: flexion 0.6-6.4° off the unbroken
recording's, still ``not determined``).

Such a joint is graded by time too (:func:`hold_graded`): in 6-D nothing measures its heading
between the poses, where the fusion's heading drifts about the vertical. A 30-min simulated walk
whose stand was its only pose read the right hip's rotation 28° RMS off the truth in its first
5 min and 89-154° in the next, its flexion 4° then 20-36° (the left hip stayed within 1-4°);
walks of 60-95 s lie at most 47 s from their stand. Farther than ``HEADING_HOLD_S`` from every
pose, the joint's other angles are ``not determined`` and its first ``weak``; farther than
three times it, every angle ``not determined``. A joint tied at its protocol's poses and rests
is graded the same way by the drift its anchors measured where the track holds, before its
first anchor and after its last: over ``HEADING_DRIFT_DEG`` at their rate (the harsh preset's
gyroscopes, 15-23°/min, 39 s past the last rest: lumbar lateral bending 5.7-7.4° off), over
three times it every angle ``not determined``.

The reason is kept in plain words with each grade. The grades depend on the calibration only:
the angle table and the report carry them next to every number, and findings are not stated for
an angle that is not determined.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from motionlab.binding import sensor_for_segment
from motionlab.kinematics import joint_types
from motionlab.results import NOT_LINKED, JointGrades
from motionlab.segments.placement import hinge_spec, twists_about_long_axis
from motionlab.segments.steps import reference_step

if TYPE_CHECKING:
    from motionlab.protocol import Joint, Protocol
    from motionlab.results import HingeFit, SegmentCalibration, SegmentRecord

GRADES = ("determined", "weak", "not determined")
NOT_DETERMINED = GRADES[2]
FULL_FRAME = ("procrustes", "primary_secondary")
CROSSTALK_DEG = (3.0, 6.0)  # determined up to, weak up to (deg of flexion in the other planes)
AXIS_FLOOR_DEG = 5.0  # a walk-calibrated knee axis is never known better than this
#: how far (deg) a pelvis forward direction from the walk may be off, by method (walk_forward)
HEADING_BOUND_DEG = {"turns": 20.0, "walk start": 10.0, "walk end": 10.0}
#: how far (deg) the tibia turns about its long axis as the knee leaves extension (the
#: screw-home rotation: 5-15° in passive flexion, Wilson et al. 2000, J Biomech 33:465; the
#: simulated knee's 8° plus 0.03°/°): the shank's flexion axis measured from the knee's own
#: flexion is turned by about its mean over the movement (the simulated knee: 12-13°)
SCREW_HOME_DEG = (5.0, 15.0)
#: a two-axis joint's proximal sensor that follows less of its segment's rotation about the long
#: axis than this leaves the other two angles weak: the humerus' axial rotation in free arm
#: movement spans 60-90° (docs/simulator.md), so 10 % missed is already 6-9° off them at times
AXIAL_FOLLOW_DETERMINED = 0.9
#: packet-loss gaps whose bridges may together have missed a turn over this (deg, total) after
#: the first pose that ties a joint's heading leave its angles weak, over twice it not determined
#: (:func:`motionlab.segments.gap_headings`)
GAP_TURN_DEG = 10.0
#: how far apart (s) the recorded stamps of two sensors the clock sync could not time are taken
#: to be (:func:`clock_graded`): the real x-IMU3 trunk trials' stamps lay 10-18 ms from the
#: data's clocks (bench/real_trunk.py), the simulator's typical clocks up to 30 ms apart
RECORDED_CLOCK_S = 0.020
#: the angle error (deg) that offset may cause before the joint is weak (:func:`clock_graded`)
CLOCK_ERROR_DEG = 2.0
#: the angle error (deg) beyond which the offset the refused fit itself measured (less twice its
#: standard error) makes the joint not determined (:func:`clock_graded`; the cross-talk scale's
#: ``weak`` bound): a simulated harsh arm's forearm, 116 ms from its upper arm (the refused fit
#: said 120 ± 3 ms), read elbow flexion 13.9° RMS off, graded weak
CLOCK_UNDETERMINED_DEG = 6.0
#: a joint tied only at poses holds its heading this long from the nearest pose (s); see
#: :func:`hold_graded`
HEADING_HOLD_S = 120.0
#: the heading drift (deg) a joint tied at poses may gather before its first or after its last
#: anchor, at the rate its anchors measured (:func:`hold_graded`)
HEADING_DRIFT_DEG = 5.0


def _worse(a: str, b: str) -> str:
    return a if GRADES.index(a) >= GRADES.index(b) else b


def _frame_grade(segment: str, cal: SegmentRecord | None) -> tuple[str, str]:
    """Grade of a whole segment frame, with the reason."""
    if cal is None:
        return "not determined", f"{segment} has no calibration"
    method = cal.method
    if method == "nominal":
        return "not determined", f"no axis of {segment} was measured (nominal placement only)"
    if cal.unsigned_steps:
        return "not determined", _unsigned(segment, cal.unsigned_steps)
    if method not in FULL_FRAME and cal.hint_contradicted:
        return "not determined", (
            f"{segment}'s frame has one measured axis, and the data contradict its placement "
            "hint, which would give the rest"
        )
    if method not in FULL_FRAME:
        return "weak", f"{segment}'s frame has one measured axis, the rest is the nominal placement"
    methods = _methods(cal)
    if "turns" in methods:
        return "weak", f"{segment}'s forward direction is from the walk's turns (often 5-25° off)"
    for method, steps in (("walk start", "first"), ("walk end", "last")):
        if method in methods:
            return "weak", (
                f"{segment}'s forward direction is from the {steps} steps of the walk (about "
                "5-10° off)"
            )
    if _flagged(cal):
        return "weak", f"the calibration of {segment} was flagged"
    return "determined", ""


def _flagged(cal: SegmentRecord) -> bool:
    """Whether the segment's quality checks failed (a record without quality passed)."""
    return cal.quality is not None and not cal.quality.ok


def _methods(cal: SegmentRecord) -> set[str]:
    return {r.method for r in cal.axes.values() if r.in_fit}


def _heading_only(segment: str, cal: SegmentRecord | None) -> float | None:
    """How far (deg) the segment's frame may be turned about the vertical when that is all that
    keeps it from ``determined`` (its forward direction from the walk), else ``None``."""
    if cal is None or cal.method not in FULL_FRAME:
        return None
    if _flagged(cal):
        return None
    bounds = [HEADING_BOUND_DEG[m] for m in _methods(cal) if m in HEADING_BOUND_DEG]
    return max(bounds) if bounds else None


def _unsigned(segment: str, steps: list[str]) -> str:
    """Why a frame with an axis signed by a contradicted hint is not determined."""
    return (
        f"the direction of {segment}'s axis from {', '.join(steps)} follows its placement hint, "
        "which the data contradict, and nothing in the recording signs it: the frame may be "
        "half a turn off"
    )


def _flexion_under_heading(
    joint, protocol, calibration: SegmentCalibration, distal_grade: str
) -> tuple[str, str]:
    """Grade of a hip's flexion (first angle of ZXY) when the only doubt is its pelvis's heading
    (see the module notes) and its distal frame is ``determined``; ``("", "")`` where that does
    not apply."""
    bound = _heading_only(joint.proximal, calibration.segments.get(joint.proximal))
    tilt = distal_tilt(joint, protocol, calibration)
    if bound is None or tilt is None or distal_grade != "determined":
        return "", ""
    error = _flexion_error(tilt, bound)
    if error <= CROSSTALK_DEG[0]:
        return "determined", ""
    return "weak", (
        f"{joint.proximal}'s forward direction from the walk may be {bound:.0f}° off, which "
        f"can move flexion by {error:.0f}° where {joint.distal} tilts {tilt:.0f}°"
    )


def distal_tilt(joint: Joint, protocol: Protocol, calibration: SegmentCalibration) -> float | None:
    """How far (deg) a ZXY joint's distal segment tilted from the vertical over the recording
    (the thigh of a hip: its knee's determined fit from the walk, ``proximal_tilt_deg``), which
    bounds what a turn of the joint's frame about the vertical moves its flexion by
    (:func:`_flexion_error`); ``None`` for another joint or without such a fit."""
    if joint.sequence != "ZXY":
        return None
    tilts = [
        float(fit.proximal_tilt_deg)
        for name, fit in calibration.hinges.items()
        if name in protocol.joints
        and protocol.joints[name].proximal == joint.distal
        and fit.verdict == "determined"
    ]
    return tilts[0] if tilts and np.isfinite(tilts[0]) else None


def _flexion_error(tilt_deg: float, turn_deg: float) -> float:
    """The most (deg) a turn of ``turn_deg`` about the vertical moves the flexion (first angle of
    ZXY) of a segment tilted ``tilt_deg``: ``tilt (1 − cos turn)`` (module notes), the turn
    capped at 90°."""
    return float(tilt_deg * (1.0 - np.cos(np.radians(min(turn_deg, 90.0)))))


def _axis_grade(joint, calibration: SegmentCalibration) -> tuple[str, str]:
    """Grade of the angle about a hinge axis: the axis measured in both segments."""
    fit = calibration.hinges.get(joint.name)
    if fit is not None and fit.used_for == "axes":
        reasons = "; ".join(fit.reasons)
        return fit.verdict, (f"hinge axis from movement: {reasons}" if reasons else "")
    segs = calibration.segments
    grade, reason = "determined", ""
    for seg in (joint.proximal, joint.distal):
        cal = segs.get(seg)
        if cal is None or cal.method == "nominal":
            return "not determined", f"no axis of {seg} was measured (nominal placement only)"
        if cal.unsigned_steps:
            return "not determined", _unsigned(seg, cal.unsigned_steps)
        measured = [
            r for r in cal.axes.values() if r.kind in ("functional", "movement") and r.in_fit
        ]
        if not measured and cal.method not in FULL_FRAME:
            grade, reason = "weak", f"the flexion axis of {seg} is the nominal placement's"
        elif _flagged(cal):
            grade, reason = _worse(grade, "weak"), f"the calibration of {seg} was flagged"
    return grade, reason


def _crosstalk_grade(fit: HingeFit | None) -> tuple[str, str]:
    """Grade of the angles off a walk-calibrated knee's flexion axis from the axis' uncertainty
    (see the module notes); ``determined`` for any other joint."""
    if fit is None or fit.method != "principal" or fit.used_for != "axes":
        return "determined", ""
    axis_doubt = float(np.hypot(fit.witness_deg, AXIS_FLOOR_DEG))  # independent: in quadrature
    flexion = float(fit.excursion_deg[0])
    crosstalk = abs(flexion) * np.sin(np.radians(axis_doubt))
    if not np.isfinite(crosstalk):
        return "not determined", "the flexion axis's uncertainty is unknown"
    if crosstalk <= CROSSTALK_DEG[0]:
        return "determined", ""
    grade = "weak" if crosstalk <= CROSSTALK_DEG[1] else "not determined"
    return grade, (
        f"the flexion axis from the walk is known to {axis_doubt:.0f}°, which can carry "
        f"{crosstalk:.0f}° of the knee's largest flexion in the recording, "
        f"{abs(flexion):.0f}°, into this angle"
    )


def _flexes_joint(step, joint) -> bool:
    """Whether functional ``step`` flexes ``joint``: it names the distal segment's axis and not
    the proximal's as the same (a straight-leg hip flexion names both: the knee stays still)."""
    return (
        step.kind == "functional"
        and joint.distal in step.axis
        and step.axis.get(joint.proximal) != step.axis[joint.distal]
    )


def _coupled_axis_grade(protocol, joint, segs: dict[str, SegmentRecord]) -> tuple[str, str]:
    """``weak`` (with the reason) for the angles off the flexion axis of a knee whose distal
    segment took that axis only from steps that flex the knee itself (see the module notes:
    the tibia's screw-home rotation turns it); ``("", "")`` otherwise."""
    spec = hinge_spec(joint)
    ref = reference_step(protocol, joint.proximal, joint.distal)
    cal = segs.get(joint.distal)
    if joint_types.joint_type(joint.type).name != "knee" or spec is None or cal is None:
        return "", ""
    if not twists_about_long_axis(protocol, joint, ref, spec):
        return "", ""
    steps = {s.name: s for s in protocol.calibration}
    used = [steps[n] for n, r in cal.axes.items()
            if r.in_fit and r.kind == "functional" and n in steps]  # fmt: skip
    if not used or not all(_flexes_joint(step, joint) for step in used):
        return "", ""
    rigid = [
        s.name
        for s in protocol.calibration
        if s.kind == "functional" and joint.distal in s.axis and not _flexes_joint(s, joint)
    ]
    remedy = f": record '{rigid[0]}' (the leg swung straight) for it" if rigid else ""
    return "weak", (
        f"{joint.distal}'s flexion axis is from the {joint.name}'s own flexion "
        f"('{used[0].name}'), in which the tibia turns about its long axis (screw-home, "
        f"{SCREW_HOME_DEG[0]:g}-{SCREW_HOME_DEG[1]:g}°), which turns that axis{remedy}"
    )


def _lag_grade(joint, fit: HingeFit | None) -> tuple[str, str]:
    """``weak`` (with the reason) for the angles off the flexion axis of a two-axis joint whose
    proximal sensor was found to follow less than ``AXIAL_FOLLOW_DETERMINED`` of its segment's
    rotation about the long axis (:func:`.movement.fit_two_dof`, ``axial_follow``): the rotation
    it misses, ``ε``, is about the humerus' long axis and goes into the carrying angle and the
    pronation to first order (``ε sin θ`` and ``ε cos θ`` at flexion ``θ``), not into flexion
    (``ε tan(c) cos θ`` with the carrying angle ``c``), less what the angles undo of it against
    the trunk (:mod:`.skin_lag`, which the skin's lag does not follow exactly: on the simulated
    arm the twist explains 32-88 % of its variance); ``("", "")`` otherwise."""
    follow = float(getattr(fit, "axial_follow", np.nan)) if fit is not None else np.nan
    if fit is None or fit.used_for != "axes" or not follow < AXIAL_FOLLOW_DETERMINED:
        return "", ""
    undone = (
        f"; the angles add the rest back from its twist against the {fit.lag_anchor}, and what "
        "the skin does otherwise goes into this angle"
        if getattr(fit, "lag_anchor", "")
        else "; the rest goes into this angle"
    )
    return "weak", (
        f"{joint.proximal}'s sensor follows {follow:.2f} of the segment's rotation about its "
        f"long axis (fitted with the axes){undone}"
    )


def _zero_grade(joint, segs: dict[str, SegmentRecord], grade: str, reason: str) -> tuple[str, str]:
    """The hinge angle's grade made ``weak`` when its zero rests on a placement hint: a segment
    whose frame has one measured axis (the hinge's, with no reference pose) is turned about it
    as the protocol's ``sensor_axes`` say, and the angle's offset follows that turn."""
    if grade != "determined":
        return grade, reason
    for seg in (joint.proximal, joint.distal):
        cal = segs.get(seg)
        if cal is not None and cal.method not in FULL_FRAME:
            return "weak", (
                f"its zero is {seg}'s placement hint (one measured axis, no reference pose): "
                "the curve is measured, its offset is not"
            )
    return grade, reason


def grade_joints(protocol, calibration: SegmentCalibration) -> dict[str, JointGrades]:
    """``{joint: JointGrades}`` (three grades and reasons) for every protocol joint; the first
    angle of a hinge-like joint (knee, elbow, hinge: :func:`.placement.hinge_spec`) is graded by
    its axis and its zero."""
    out = {}
    segs = calibration.segments
    for name, joint in protocol.joints.items():
        frames = [_frame_grade(s, segs.get(s)) for s in (joint.proximal, joint.distal)]
        g_frame = _worse(frames[0][0], frames[1][0])
        # the worse segment's reason first: the report names the first as the cause
        ordered = sorted(frames, key=lambda f: -GRADES.index(f[0]))
        r_frame = "; ".join(r for _, r in ordered if r)
        fit = calibration.hinges.get(name)
        if fit is not None and fit.used_for == "axes" and fit.verdict != "determined":
            g_frame = _worse(g_frame, fit.verdict)
            r_frame = "; ".join(filter(None, [r_frame, "the hinge axis from movement is "
                                              + fit.verdict]))  # fmt: skip
        if hinge_spec(joint) is not None:
            g_axis, r_axis = _zero_grade(joint, segs, *_axis_grade(joint, calibration))
            g_cross, r_cross = _crosstalk_grade(fit)
            if g_cross != "determined" and GRADES.index(g_cross) >= GRADES.index(g_frame):
                g_frame, r_frame = g_cross, "; ".join(filter(None, [r_frame, r_cross]))
            grades = [g_axis, g_frame, g_frame]
            reasons = [r_axis, r_frame, r_frame]
            for g_more, r_more in (
                _lag_grade(joint, fit),
                _coupled_axis_grade(protocol, joint, segs),
            ):
                if g_more and GRADES.index(g_more) > GRADES.index(grades[1]):
                    grades[1:] = [g_more] * 2
                    reasons[1:] = ["; ".join(filter(None, [reasons[1], r_more]))] * 2
        else:
            grades, reasons = [g_frame] * 3, [r_frame] * 3
            g_flex, r_flex = _flexion_under_heading(joint, protocol, calibration, frames[1][0])
            if g_flex and g_frame == "weak":
                grades[0], reasons[0] = g_flex, r_flex
        out[name] = JointGrades(grades, reasons)
    return out


def gap_graded(
    graded: dict[str, JointGrades],
    gap_turns: dict,
    protocol: Protocol | None = None,
    calibration: SegmentCalibration | None = None,
) -> dict[str, JointGrades]:
    """``graded`` with each joint of ``gap_turns`` (``{joint: GapTurn}``,
    :func:`motionlab.segments.gap_headings`) graded by the turn packet-loss gaps may together
    have hidden: ``weak`` over ``GAP_TURN_DEG``, ``not determined`` over twice it, the gap's reason
    first where it decides the grade (the summary names the first clause as the cause). The
    turn is about the vertical (the fusion's inclination recovers within seconds), so a hip's
    flexion, about a horizontal axis, is graded by what it moves there (:func:`distal_tilt`
    with ``protocol`` and ``calibration``; :func:`_flexion_error` against ``CROSSTALK_DEG``)."""
    out = dict(graded)
    for name, gap in (gap_turns or {}).items():
        if name not in out or gap.turn_deg <= GAP_TURN_DEG:
            continue
        g_gap = "weak" if gap.turn_deg <= 2 * GAP_TURN_DEG else "not determined"
        turn = f"{gap.turn_deg:.0f}°" if gap.turn_deg <= 180 else "any size (over 180°)"
        which = f"a packet-loss gap in {gap.sensor} at {gap.time_s:.1f} s may have"
        if (gap.gaps or 1) > 1:
            which = (f"{gap.gaps} packet-loss gaps (the largest in {gap.sensor} at "
                     f"{gap.time_s:.1f} s) may together have")  # fmt: skip
        why = (f"{which} hidden a turn of {turn}, which the joint's heading, tied only where a "
               "pose was held or the walk went straight, keeps until its next anchor")  # fmt: skip
        joint = protocol.joints.get(name) if protocol is not None else None
        tilt = distal_tilt(joint, protocol, calibration) if joint and calibration else None
        if tilt is None:
            out[name] = lowered(out[name], [g_gap] * len(out[name].grades), why)
            continue
        error = _flexion_error(tilt, gap.turn_deg)
        g_flex = next(g for g, lim in zip(GRADES, (*CROSSTALK_DEG, np.inf), strict=True)
                      if error <= lim)  # fmt: skip
        flexion = out[name]
        if g_flex != "determined":
            flexion = lowered(flexion, [g_flex], f"{why}: up to {error:.1f}° of flexion where "
                              f"{joint.distal} tilts {tilt:.0f}°")  # fmt: skip
        others = lowered(out[name], [g_gap] * len(out[name].grades), why)
        out[name] = replace(others, grades=[flexion.grades[0], *others.grades[1:]],
                            reasons=[flexion.reasons[0], *others.reasons[1:]])  # fmt: skip
    return out


def clock_graded(graded: dict[str, JointGrades], protocol, session) -> dict[str, JointGrades]:
    """``graded`` with each joint whose two sensors the clock sync could not time against each
    other (:meth:`~motionlab.results.ClockSync.untimed_way`: one kept as recorded against the
    other, or the two in parts of the body it timed each on its own clock) graded ``weak`` at
    best where the sensor whose stamps may be off turns fast enough for recorded stamps
    ``RECORDED_CLOCK_S`` apart to move its angles by over
    ``CLOCK_ERROR_DEG`` (its 95th-percentile angular speed times it): an offset moves a joint's
    angles by the rotation over it of the sensor read at the wrong instants, the other being on
    the session's clock (a simulated harsh walk's left shank, 52 ms from its thigh, read 10°
    more knee flexion in swing, graded determined, and a range 12 % apart from the right
    knee's); a trunk bending at 30°/s over a still pelvis moves 0.6° in 20 ms, and a still
    wheelchair's sensor, however far off its stamps, moves the trunk's lean against it by
    nothing (the faster of the two sensors, used before, had the lean of every still
    wheelchair of a simulated seated session ``weak``).
    Without a clock sync (``--no-clock-sync``, or the vendor's clocks) the recorded clocks are
    taken as one. Where the refused fit itself put the two clocks so far apart (its offset less
    twice its standard error) that that speed moves the angles by over
    ``CLOCK_UNDETERMINED_DEG``, they are ``not determined``."""
    sync = session.results.clock_sync
    out = dict(graded)
    for name, joint in protocol.joints.items():
        labels = [sensor_for_segment(session, seg) for seg in (joint.proximal, joint.distal)]
        found = sync.untimed_way(labels) if sync is not None and None not in labels else None
        if name not in out or found is None:
            continue
        fit, off = found
        speed = max(_speed_p95(session.sensors[lab].gyr) for lab in off)
        if speed * RECORDED_CLOCK_S <= CLOCK_ERROR_DEG:
            continue
        status = fit.status.removeprefix("not reliable: ")
        how = f"{fit.sensor}'s kept as recorded: {status}"
        if fit.status.startswith(NOT_LINKED):  # a part of the body timed on its own clock
            how = f"{fit.sensor}'s clock {status}"
        moved = f"{speed * RECORDED_CLOCK_S:.0f}°" if np.isfinite(speed) else "an unknown angle"
        why = (f"the clocks of {labels[0]} and {labels[1]} were not timed against each other "
               f"({how}); at {' and '.join(off)}'s speed, stamps "
               f"{1e3 * RECORDED_CLOCK_S:.0f} ms apart move the angles by {moved}")  # fmt: skip
        grade = "weak"
        apart = abs(fit.offset_s) - 2.0 * fit.offset_se_s  # what the refused fit measured, at least
        if np.isfinite(apart) and speed * apart > CLOCK_UNDETERMINED_DEG:
            grade = "not determined"
            why += (
                f", and the data put them {1e3 * abs(fit.offset_s):.0f} ± "
                f"{1e3 * fit.offset_se_s:.0f} ms apart: at least {speed * apart:.0f}°"
            )
        out[name] = lowered(out[name], [grade] * len(out[name].grades), why)
    return out


def _speed_p95(gyr: np.ndarray | None) -> float:
    """95th percentile (deg/s) of a gyroscope's angular speed (``gyr`` (N, 3) rad/s); ``inf``
    without one (an orientation-only sensor: its speed unknown)."""
    if gyr is None or not np.isfinite(gyr).any():
        return float("inf")
    return float(np.degrees(np.nanpercentile(np.linalg.norm(gyr, axis=1), 95)))


def hold_graded(
    graded: dict[str, JointGrades],
    unheld: dict[str, float],
    drift: dict[str, tuple[float, float]] | None = None,
) -> dict[str, JointGrades]:
    """``graded`` with each joint of ``unheld`` (``{joint: s}``: how far the recording reaches
    from the poses that tie its heading, :func:`motionlab.segments.unheld_headings`) graded by
    it: over ``HEADING_HOLD_S`` its angles after the first ``not determined`` and the first
    ``weak``, over three times it all ``not determined`` (module notes). So too by ``drift``
    (``{joint: (deg/s, s)}``, :func:`motionlab.segments.drift_beyond_anchors`: the rate its
    anchors put the two headings drifting apart at, and how far the recording reaches beyond
    its first or last anchor, where the track holds): the drift gathered there against
    ``HEADING_DRIFT_DEG`` (sensors with large gyroscope biases)."""
    out = dict(graded)
    tied = ("its heading is tied only where a pose was held or the walk went straight, and the "
            "recording reaches")  # fmt: skip
    for name, seconds in unheld.items():
        if name not in out or not seconds > HEADING_HOLD_S:
            continue
        why = (f"{tied} {seconds / 60:.0f} min from those (the 6-D fusion's heading drifts "
               "about the vertical in between)")  # fmt: skip
        first = "weak" if seconds <= 3 * HEADING_HOLD_S else "not determined"
        out[name] = lowered(out[name], _first_kept(out[name], first), why)
    for name, (rate, beyond) in (drift or {}).items():
        drifted = rate * beyond
        if name not in out or not drifted > HEADING_DRIFT_DEG:
            continue
        why = (f"{tied} {beyond:.0f} s past those, while its poses put the two sensors' headings "
               f"drifting apart at {rate * 60:.0f}°/min: about {drifted:.0f}° by then")  # fmt: skip
        first = "weak" if drifted <= 3 * HEADING_DRIFT_DEG else "not determined"
        out[name] = lowered(out[name], _first_kept(out[name], first), why)
    return out


def _first_kept(joint: JointGrades, first: str) -> list[str]:
    """The lowest grades of a joint whose heading is unknown: ``first`` for its first angle,
    ``not determined`` for the others."""
    return [first] + [NOT_DETERMINED] * (len(joint.grades) - 1)


def lowered(joint: JointGrades, lowest: list[str], why: str) -> JointGrades:
    """``joint`` with each angle graded at most ``lowest[k]``, ``why`` added to its reason:
    first where it lowers the grade (the summary names the first clause as the cause), last
    where the grade was that already."""
    grades, reasons = list(joint.grades), list(joint.reasons)
    for k, low in enumerate(lowest):
        worse = GRADES.index(low) > GRADES.index(grades[k])
        if worse or low == grades[k]:
            order = [why, reasons[k]] if worse else [reasons[k], why]
            grades[k], reasons[k] = low, "; ".join(filter(None, order))
    return replace(joint, grades=grades, reasons=reasons)


#: what an angle method other than the fused orientations cannot measure, by joint type and
#: angle: ``(grade at best, reason)``. The accelerometer-only elbow (Lee 2012, ch. 5) holds the
#: carrying angle at its value in the stand and reads pronation from gravity alone, held where
#: the forearm hangs vertical. Its flexion is right while the elbow's axis stays horizontal
#: (simulated elbow protocol, seeds 0-2: 2.0-2.3° RMS, 0.8° with the axis within 6° of
#: horizontal) and not in free arm movement (arm protocol: 10-12°; the carrying angle falls
#: with flexion, 2-9° against 10-11° in the stand, and enters flexion as the axis tilts), which
#: the grade cannot tell apart: weak at best.
METHOD_LIMITS = {
    "accel-only": {
        ("elbow", "flexion"): (
            "weak",
            "the accelerometer-only method reads it right only while the elbow's axis stays "
            "horizontal (its model holds the carrying angle at the stand's)",
        ),
        ("elbow", "carrying"): (
            "not determined",
            "the accelerometer-only method does not measure it (its model holds it at the stand's)",
        ),
        ("elbow", "pronation"): (
            "weak",
            "the accelerometer-only method reads it from gravity alone: held where the forearm "
            "hangs vertical, and only while the upper arm keeps its heading",
        ),
    }
}


def method_grade(method: str, joint_type: str, angle: str, grade: str, reason: str):
    """``(grade, reason)`` of an angle computed by angle ``method`` (``imu``,
    ``accel-only``): the calibration's, or worse where the method cannot measure the angle
    (:data:`METHOD_LIMITS`)."""
    limit = METHOD_LIMITS.get(method, {}).get((joint_type, angle))
    if limit is None or GRADES.index(limit[0]) <= GRADES.index(grade):
        return grade, reason
    return limit


def method_column_grade(method: str, column: str, grade: str, reason: str):
    """:func:`method_grade` of an angle known by its column only (``elbow_r_carrying_deg``:
    a clinical joint type's columns name the type and the angle)."""
    from motionlab.kinematics.joint_types import column_name

    for joint_type, angle in METHOD_LIMITS.get(method, {}):
        if column in {column_name(joint_type, side, angle) for side in ("r", "l", "")}:
            return method_grade(method, joint_type, angle, grade, reason)
    return grade, reason


def graded_angles(
    joints, calibration: SegmentCalibration | None, method: str = "imu"
) -> list[tuple[str, ...]]:
    """``(joint, angle, column, grade, reason)`` of every angle column of ``joints`` (protocol
    joints, in order) from ``calibration.grades``, as angle ``method`` allows
    (:func:`method_grade`); a joint without grades (a session calibrated before they existed)
    has every angle ``determined`` with an empty reason."""
    from motionlab.kinematics.joint_types import angle_columns

    graded = calibration.grades if calibration is not None else {}
    rows = []
    for joint in joints:
        entry = graded.get(joint.name) or JointGrades()
        grades, reasons = [str(g) for g in entry.grades], [str(r) for r in entry.reasons]
        for k, (angle, col) in enumerate(angle_columns(joint)):
            grade = grades[k] if k < len(grades) and grades[k] in GRADES else GRADES[0]
            reason = reasons[k] if k < len(reasons) and grade != GRADES[0] else ""
            grade, reason = method_grade(method, joint.type, angle, grade, reason)
            rows.append((joint.name, angle, col, grade, reason))
    return rows


def column_grades(
    protocol, calibration: SegmentCalibration | None, method: str = "imu"
) -> dict[str, str]:
    """``{angle column: grade}`` of every ``protocol`` joint (:func:`graded_angles`):
    ``{"knee_r_flexion_deg": "determined", …}``."""
    joints = protocol.joints.values()
    return {row[2]: row[3] for row in graded_angles(joints, calibration, method)}


def with_grades(table, protocol, calibration: SegmentCalibration | None, method: str = "imu"):
    """A metrics table (:func:`motionlab.kinematics.metrics.metrics_table`) graded by
    :func:`graded_table` with the protocol's column grades (:func:`column_grades`), as
    ``run``'s and the ``metrics`` command's tables carry it."""
    grades = column_grades(protocol, calibration, method)
    return graded_table(table, grades, trunk_grade(calibration))


def trunk_grade(calibration: SegmentCalibration | None) -> str:
    """The thorax frame's grade (the trunk's own metrics); ``""`` for an ungraded calibration."""
    if calibration is None or not calibration.grades:
        return ""
    return _frame_grade("thorax", calibration.segments.get("thorax"))[0]


def graded_table(table, grades: dict[str, str], trunk: str = ""):
    """A metrics table (rows with ``joint``, ``angle``, ``value``, ``unit`` and, where it has
    one, the row's angle ``column``) with each row's angle grade in a ``grade`` column
    (``grades`` by angle column; the trunk's rows ``trunk``;
    empty for a row of no angle). A measured value of an angle ``not determined`` is withheld
    (NaN; counts, unit ``1``, stay): the report does not print it, and a table read without its
    grade must not show it either."""
    columns = table["column"] if "column" in table else [""] * len(table)
    graded = [
        trunk if j == "trunk" and a else grades.get(c or f"{j}_{a}_deg", "")
        for j, a, c in zip(table["joint"], table["angle"], columns, strict=True)
    ]
    withheld = (np.asarray(graded) == NOT_DETERMINED) & (table["unit"] != "1").to_numpy()
    return table.assign(grade=graded, value=table["value"].where(~withheld))
