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
- ``not determined``: a segment with no measured axis at all, or a failed or inconsistent fit.

The reason is kept in plain words with each grade. The grades depend on the calibration only:
the angle table and the report carry them next to every number, and findings are not stated for
an angle that is not determined.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from motionlab.results import SegmentCalibration

GRADES = ("determined", "weak", "not determined")
FULL_FRAME = ("procrustes", "primary_secondary")


def _worse(a: str, b: str) -> str:
    return a if GRADES.index(a) >= GRADES.index(b) else b


def _frame_grade(segment: str, cal: dict[str, Any] | None) -> tuple[str, str]:
    """Grade of a whole segment frame, with the reason."""
    if cal is None:
        return "not determined", f"{segment} has no calibration"
    method = cal.get("method", "")
    if method == "nominal":
        return "not determined", f"no axis of {segment} was measured (nominal placement only)"
    if method not in FULL_FRAME:
        return "weak", f"{segment}'s frame has one measured axis, the rest is the nominal placement"
    if any(
        r.get("method") == "turns" and r.get("used", True) for r in cal.get("axes", {}).values()
    ):
        return "weak", f"{segment}'s forward direction is from the walk's turns (about 5-20° off)"
    if not cal.get("quality", {}).get("ok", True):
        return "weak", f"the calibration of {segment} was flagged"
    return "determined", ""


def _axis_grade(joint, calibration: SegmentCalibration) -> tuple[str, str]:
    """Grade of the angle about a hinge axis: the axis measured in both segments."""
    fit = calibration.hinges.get(joint.name)
    if fit is not None and fit.get("used_for", "axes") == "axes":
        reasons = "; ".join(fit.get("reasons", []))
        return fit["verdict"], (f"hinge axis from movement: {reasons}" if reasons else "")
    segs = calibration.segments
    grade, reason = "determined", ""
    for seg in (joint.proximal, joint.distal):
        cal = segs.get(seg)
        if cal is None or cal.get("method") == "nominal":
            return "not determined", f"no axis of {seg} was measured (nominal placement only)"
        measured = [
            r
            for r in cal.get("axes", {}).values()
            if r.get("kind") in ("functional", "movement") and r.get("used", True)
        ]
        if not measured and cal.get("method") not in FULL_FRAME:
            grade, reason = "weak", f"the flexion axis of {seg} is the nominal placement's"
        elif not cal.get("quality", {}).get("ok", True):
            grade, reason = _worse(grade, "weak"), f"the calibration of {seg} was flagged"
    return grade, reason


def _zero_grade(joint, segs: dict[str, Any], grade: str, reason: str) -> tuple[str, str]:
    """The hinge angle's grade made ``weak`` when its zero rests on a placement hint: a segment
    whose frame has one measured axis (the hinge's, with no reference pose) is turned about it
    as the protocol's ``sensor_axes`` say, and the angle's offset follows that turn."""
    if grade != "determined":
        return grade, reason
    for seg in (joint.proximal, joint.distal):
        cal = segs.get(seg)
        if cal is not None and cal.get("method") not in FULL_FRAME:
            return "weak", (
                f"its zero is {seg}'s placement hint (one measured axis, no reference pose): "
                "the curve is measured, its offset is not"
            )
    return grade, reason


def grade_joints(protocol, calibration: SegmentCalibration) -> dict[str, dict[str, list[str]]]:
    """``{joint: {"grades": [3 str], "reasons": [3 str]}}`` for every protocol joint; the first
    angle of a hinge-like joint (knee, elbow, hinge: :func:`.placement.hinge_spec`) is graded by
    its axis and its zero."""
    from motionlab.segments.placement import hinge_spec

    out = {}
    segs = calibration.segments
    for name, joint in protocol.joints.items():
        frames = [_frame_grade(s, segs.get(s)) for s in (joint.proximal, joint.distal)]
        g_frame = _worse(frames[0][0], frames[1][0])
        r_frame = "; ".join(r for _, r in frames if r)
        fit = calibration.hinges.get(name)
        if (
            fit is not None
            and fit.get("used_for", "axes") == "axes"
            and fit["verdict"] != "determined"
        ):
            g_frame = _worse(g_frame, fit["verdict"])
            r_frame = "; ".join(filter(None, [r_frame, "the hinge axis from movement is "
                                              + fit["verdict"]]))  # fmt: skip
        if hinge_spec(joint) is not None:
            g_axis, r_axis = _zero_grade(joint, segs, *_axis_grade(joint, calibration))
            grades = [g_axis, g_frame, g_frame]
            reasons = [r_axis, r_frame, r_frame]
        else:
            grades, reasons = [g_frame] * 3, [r_frame] * 3
        out[name] = {"grades": grades, "reasons": reasons}
    return out
