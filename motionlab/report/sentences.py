"""Plain-language sentences for the report: findings, meanings of metrics, quality notes.

Numbers are rounded to whole degrees (the accuracy of wearable-sensor joint angles does not
support more) and every sentence names the side, the joint, the movement and the task, so that it
can be read on its own ("Right knee flexion range 5–58° during gait, below the normal 0–65°").

Findings follow the grade of their angle (:func:`~motionlab.report.model.grade_rows`): a
``weak`` angle's finding ends with "(weak: <reason>)"; for a ``not determined`` angle no finding
is stated, one sentence says why instead ("Right knee internal-external rotation is not
reported: no axis of shank_r was measured (nominal placement only).").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.kinematics.joint_types import JOINT_TYPES
from motionlab.report.model import (
    NOT_DETERMINED,
    SIDE_NAMES,
    THORAX,
    WEAK,
    SessionView,
    angle_grade,
    angle_title,
    calibration_rows,
    grade_rows,
    joint_title,
    quality_rows,
    rom_rows,
    segment_grade,
    symmetry_rows,
    worst_grade,
)

#: what each out-of-plane metric means, in one sentence
MEANING = {
    "cross_talk": (
        "Cross-talk is motion the sensors report in the other planes while the joint moves in "
        "one plane only; large values mean the sensor axes were not aligned with the joint, "
        "and the calibration's reduction of it shows how much the calibration corrected."
    ),
    "varus_thrust": (
        "Varus thrust is the sudden increase of knee varus (bow-leg angle) just after the heel "
        "strikes the ground; a thrust of more than a few degrees is linked to progression of "
        "medial knee osteoarthritis."
    ),
    "stance_rotation": (
        "Stance rotation range is how much the shank twists on the thigh while the foot is on "
        "the ground; a larger range than usual suggests rotational laxity of the knee."
    ),
    "out_of_plane_offset": (
        "The out-of-plane offset is how far the trunk leaves the intended plane of a movement "
        "(e.g. twisting while bending forward); large values mean the movement was not performed "
        "in one plane."
    ),
    "trunk_compensation": (
        "Trunk compensation is leaning or twisting the trunk to help the arm reach; it is common "
        "after stroke or with a stiff shoulder or elbow, and healthy adults move the trunk little "
        "when reaching within arm's length."
    ),
}

TRUNK_WORDS = {"flexion": "forward lean", "lateral_bending": "side lean", "axial_rotation": "twist"}
STATUS_WORDS = {"within": "within", "below": "below", "above": "above", "wider": "wider than"}


def deg(x: float) -> str:
    """``'12°'``, ``'-3°'``, or ``'n/a'``."""
    return f"{x:.0f}°" if np.isfinite(x) else "n/a"


def span(low: float, high: float) -> str:
    """``'5–58°'``; ``'-3 to 5°'`` when an end is negative (a dash would read as a minus)."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return "n/a"
    lo, hi = round(low), round(high)
    return f"{lo}–{hi}°" if lo >= 0 and hi >= 0 else f"{lo} to {hi}°"


def task_name(task: str) -> str:
    return task.replace("_", " ")


def _joint_words(row: dict[str, Any]) -> tuple[str, str]:
    """``("right", "knee")`` of a report row; generic joints by name: ``("", "wrist r hinge")``."""
    jt = JOINT_TYPES.get(row["joint_type"])
    if jt is not None and not jt.clinical:
        name = str(row.get("joint", jt.name)).replace("_", " ")
        return "", f"{name} {jt.display}"
    side = SIDE_NAMES.get(row.get("side", ""), "") if jt is None or jt.sided else ""
    return side, jt.display if jt is not None else row["joint_type"]


def rom_sentence(row: dict[str, Any]) -> str:
    """One row of :func:`~motionlab.report.model.rom_rows` as a sentence."""
    side, joint = _joint_words(row)
    angle = angle_title(row["joint_type"], row["angle"])
    text = (
        f"{side} {joint} {angle} range {span(row['typical_min_deg'], row['typical_max_deg'])} "
        f"during {task_name(row['task'])}"
    ).strip()
    text = text[0].upper() + text[1:]
    if row["normal"] is not None and row["status"]:
        lo, hi = row["normal"]
        text += f", {STATUS_WORDS[row['status']]} the normal {span(lo, hi)}"
    return text + "."


def not_reported(what: str, reason: str) -> str:
    """``'<What> is not reported: <reason>.'`` (``what`` capitalised)."""
    why = reason or "the calibration did not determine it"
    return f"{what[0].upper()}{what[1:]} is not reported: {why}."


def angle_words(view: SessionView, joint: str, angle: str) -> str:
    """``'Right knee internal-external rotation'``, ``'Ball12 (ball joint) rotation about z'``."""
    j = view.protocol.joints[joint]
    return f"{joint_title(j)} {angle_title(j.type, angle)}"


def graded(sentence: str, grade: str, reason: str, what: str) -> str:
    """A finding as its grade allows: kept (``determined``), marked ``(weak: <reason>)``, or
    replaced by :func:`not_reported` (``not determined``; ``what`` names the angle)."""
    if grade == NOT_DETERMINED:
        return not_reported(what, reason)
    if grade == WEAK:
        return f"{sentence.removesuffix('.')} (weak{': ' + reason if reason else ''})."
    return sentence


def _oop_findings(view: SessionView) -> list[str]:
    out = []
    m = view.metrics
    for task, joints in (m.gait or {}).items():
        for name, g in joints.items():
            joint = view.protocol.joints[name]
            side = SIDE_NAMES.get(joint.side, "").capitalize()
            thrust = g.get("varus_thrust_mean_deg", np.nan)
            if not np.isfinite(thrust):
                continue
            limit = g.get("threshold_deg", 3.0)
            verdict = "above" if thrust > limit else "within"
            sentence = (
                f"{side} knee varus thrust {thrust:.0f}° in stance during {task_name(task)} "
                f"({verdict} the {limit:g}° this protocol flags; {g['strides']} strides)."
            )
            grade, reason = angle_grade(view, name, "adduction")
            what = f"{joint_title(joint)} varus thrust"
            out.append(graded(sentence, grade, reason, what))
    trunk_grade, trunk_reason = segment_grade(view, THORAX)
    for task, t in (m.trunk_compensation or {}).items():
        if trunk_grade == NOT_DETERMINED:
            out.append(not_reported(f"trunk compensation during {task_name(task)}", trunk_reason))
        elif t.get("compensated"):
            parts = [
                f"{TRUNK_WORDS[k]} up to {t[k]['peak_abs_deg']:.0f}°"
                for k in TRUNK_WORDS
                if t[k]["above_pct"] > 0
            ]
            sentence = (
                f"Trunk compensation during {task_name(task)}: {', '.join(parts)} away from the "
                "neutral posture."
            )
            out.append(graded(sentence, trunk_grade, trunk_reason, "trunk compensation"))
    for task, joints in (m.out_of_plane_offset or {}).items():
        for name, o in joints.items():
            grade, reason = worst_grade(
                [(r["grade"], r["reason"]) for r in grade_rows(view) if r["joint"] == name]
            )
            what = f"trunk out-of-plane offset during {task_name(task)}"
            if grade == NOT_DETERMINED:
                out.append(not_reported(what, reason))
            elif o["above_pct"] > 0:
                sentence = (
                    f"Trunk out-of-plane offset during {task_name(task)}: "
                    f"peak {o['peak_deg']:.0f}°, "
                    f"above {o['threshold_deg']:g}° for {o['above_pct']:.0f}% of the movement."
                )
                out.append(graded(sentence, grade, reason, what))
    return out


def findings(view: SessionView, limit: int = 12) -> list[str]:
    """The main findings of one session, most important first, at most ``limit``.

    Ranges outside normal come first, then left-right asymmetries, out-of-plane findings, the
    ranges within normal of the primary (flexion) angles, and data or calibration problems.
    """
    rows = [r for r in rom_rows(view) if r["normal"] is not None]

    def sentence(r: dict[str, Any]) -> str:
        what = angle_words(view, r["joint"], r["angle"])
        return graded(rom_sentence(r), r["grade"], r["reason"], what)

    outside = [sentence(r) for r in rows if r["status"] not in ("within", "")]
    unknown = [sentence(r) for r in rows if r["grade"] == NOT_DETERMINED]
    inside = [sentence(r) for r in rows if r["status"] == "within" and r["angle"] == "flexion"]
    asym = []
    for s in symmetry_rows(view):
        if s["flag"] and s["angle"] == "flexion":  # other planes: see the comparison page
            joint = _joint_words(s)[1]
            angle = angle_title(s["joint_type"], s["angle"])
            text = (
                f"{joint.capitalize()} {angle} range during {task_name(s['task'])} differs "
                f"between sides: right {s['right_rom_deg']:.0f}°, left {s['left_rom_deg']:.0f}° "
                f"(symmetry index {s['symmetry_index_pct']:+.0f}%)."
            )
            asym.append(graded(text, s["grade"], s["reason"], ""))
    problems = quality_notes(view)
    items = list(dict.fromkeys(outside + unknown + asym + _oop_findings(view) + inside))
    if len(items) > limit - len(problems[:2]):
        items = items[: limit - len(problems[:2])]
    if not items:
        items = ["No task with a normal range was found in this recording."]
    return items + problems[:2]


def quality_notes(view: SessionView) -> list[str]:
    """Sentences on data and calibration problems, most important first (calibration,
    saturation, magnetic disturbance, then gaps); empty when all is well."""
    notes, gaps = [], []
    bad = sorted({r["segment"] for r in calibration_rows(view) if not r["segment_ok"]})
    if bad:
        notes.append(
            f"Calibration of {', '.join(bad)} needs attention (see the calibration page); "
            "angles involving it are less certain."
        )
    for q in quality_rows(view):
        if q["gaps_kept"]:
            gaps.append(
                f"Sensor {q['sensor']} lost {q['gaps_kept_s']:.1f} s of data in "
                f"{q['gaps_kept']} gap(s); no angles are reported there."
            )
        if q["saturated_samples"]:
            notes.append(
                f"Sensor {q['sensor']} reached its measuring range on {q['saturated_samples']} "
                "samples; fast movements there may be underestimated."
            )
        if np.isfinite(q["mag_disturbed_pct"]) and q["mag_disturbed_pct"] > 20:
            notes.append(
                f"The magnetic field near sensor {q['sensor']} was disturbed "
                f"{q['mag_disturbed_pct']:.0f}% of the time (metal or electronics nearby)."
            )
    return notes + gaps


def accuracy_sentence(angle: str, entry: dict[str, Any], joint_type: str = "") -> str:
    """``'flexion-extension: ±2° (RMSE 1.4°, worst 1.9°)'``; ``joint_type`` names the angle
    (default: the first clinical type that has it)."""
    rmse = float(entry.get("rmse_deg", np.nan))
    worst = float(entry.get("max_rmse_deg", np.nan))
    bound = max(rmse, worst) if np.isfinite(worst) else rmse
    if not joint_type:
        known = (t.name for t in JOINT_TYPES.values() if t.angle_names and angle in t.angle_names)
        joint_type = next(known, "")
    name = angle_title(joint_type, angle)
    text = f"{name}: ±{np.ceil(bound):.0f}° (RMSE {rmse:.1f}°"
    return text + (f", worst case {worst:.1f}°)" if np.isfinite(worst) else ")")
