"""Expected accuracy (motionlab's own validation results, kept as data) and the methods
appendix (estimator and parameters, calibration, angle conventions, provenance with hashes)."""

from __future__ import annotations

from typing import Any

from motionlab.kinematics.angle_filter import ANGLES_LOWPASS_HZ, metrics_cutoff
from motionlab.kinematics.joint_types import JOINT_TYPES, angle_columns, angle_names, joint_sequence
from motionlab.report.model import (
    DETERMINED,
    NOT_DETERMINED,
    SessionView,
    angle_grades,
    in_order,
    joint_title,
    joint_type_title,
)
from motionlab.report.normative import load_accuracy
from motionlab.report.pdf import MUTED, SIZE, Document
from motionlab.report.sentences import accuracy_sentence, real_accuracy_sentence


def _columns(view: SessionView) -> list[str]:
    return [col for j in view.joints() for _, col in angle_columns(j)]


def _dashed(sequence: str) -> str:
    return "-".join(sequence)


#: the convention each clinical joint type's decomposition follows
_CONVENTION = {"knee": "Grood & Suntay 1983", "elbow": "ISB, Wu et al. 2005",
               "lumbar": "ISB, Wu et al. 2002", "hip": "ISB, Wu et al. 2002"}  # fmt: skip


def decomposition_text(joints: list, gait: bool = False, lowpass_hz: float = 0.0) -> str:
    """The methods paragraph on joint angles, naming the sequence each joint was decomposed
    with; ``gait``: the protocol has a gait task (strides, heel strikes, varus thrust);
    ``lowpass_hz``: the angle table's low-pass (0: as computed)."""
    fc = f"{metrics_cutoff(lowpass_hz):g} Hz"
    listed = "; ".join(
        f"{joint_title(j)}: {j.distal} relative to {j.proximal}, intrinsic "
        f"{_dashed(joint_sequence(j))}"
        + (f" (hinge axis {j.axis})" if JOINT_TYPES[j.type].sequence_rule == "axis" else "")
        for j in joints
    )
    parts = [f"{listed}."]
    clinical = [j for j in joints if JOINT_TYPES[j.type].clinical]
    if clinical:
        types = list(dict.fromkeys(j.type for j in clinical))
        seqs = ", ".join(dict.fromkeys(_dashed(joint_sequence(j)) for j in clinical))
        refs = "; ".join(
            f"{_CONVENTION[t]} for the {JOINT_TYPES[t].display}" for t in types if t in _CONVENTION
        )
        names = ", ".join(JOINT_TYPES[t].display for t in types)
        parts.append(
            f"Decomposition of the {names}: {seqs}" + (f" ({refs})" if refs else "") + ": the "
            "first angle about the proximal segment's axis, the second about the floating axis, "
            "the third about the distal segment's axis; clinical signs as in motionlab's sign "
            "table (the left side mirrored)."
        )
    if any(JOINT_TYPES[j.type].sequence_rule == "axis" for j in joints):
        parts.append(
            "Hinge joints: the angle about the hinge axis (first in the sequence, positive about "
            "the given axis direction), then two off-axis angles (about the floating axis and "
            "the distal third axis) that show how far the joint is from a pure hinge."
        )
    if any(JOINT_TYPES[j.type].sequence_rule == "any" for j in joints):
        parts.append(
            "Ball joints: three angles of the named intrinsic sequence, each named by its axis "
            "(first about the proximal axis, last about the distal one), positive about the "
            "positive segment axis."
        )
    if gait:
        parts.append(
            "Cycles: in a walk, the strides the gait page keeps (heel strike to heel strike, "
            "from the shank's angular velocity; turns, starts and stops left out) for the knees "
            "and hips alike, other tasks the repetitions of the primary angle; each cycle "
            "resampled to 101 points (0-100 %). Metrics (ranges, extremes, cycle curves, "
            f"cross-talk, varus thrust) are taken from the angles low-passed at {fc} (zero-phase "
            "Butterworth, Winter 2009): a sensor's wobble on the skin after a heel strike is not "
            "a peak of the joint."
        )
    else:
        parts.append(
            "Cycles: the repetitions of each task's primary angle, each resampled to 101 points "
            "(0-100 %). Metrics (ranges, extremes, cycle curves, cross-talk) are taken from the "
            f"angles low-passed at {fc} (zero-phase Butterworth, Winter 2009)."
        )
    if lowpass_hz > 0:
        parts.append("The angle curves and tables are low-passed the same way.")
    else:
        parts.append("The angle curves and tables are the angles as computed (not low-passed).")
    return " ".join(parts)


def accuracy_page(doc: Document, view: SessionView) -> None:
    """What error to expect for each angle of this protocol, and where the number comes from."""
    acc = load_accuracy()
    proto = (acc.get("protocols") or {}).get(view.protocol.name) or {}
    doc.section(
        "Expected accuracy",
        "How far the angles in this report may be from the true joint angles, from motionlab's "
        "own validation on recordings with a known truth. Read a range of motion as uncertain "
        "by about these amounts.",
    )
    types = {}  # type → its angle names (of its first joint)
    for j in view.joints():
        types.setdefault(j.type, angle_names(j))
    caveat = _calibration_caveat(view) if proto else ""
    if caveat:
        doc.paragraph(caveat)
    if proto and (note := _lowpass_caveat(view)):
        doc.paragraph(note)
    if not proto:
        doc.paragraph(
            f"motionlab has no validation results on file for the '{view.protocol.name}' "
            "protocol, so no accuracy can be stated. Compare with an optical reference "
            "(motionlab validate) before relying on small differences."
        )
    for jtype, names in types.items():
        items = [
            accuracy_sentence(a, proto[f"{jtype}_{a}"], jtype) + _here(view, jtype, a)
            for a in names
            if f"{jtype}_{a}" in proto
        ]
        if items:
            doc.heading(joint_type_title(jtype))
            doc.bullets(items)
    if proto:
        doc.paragraph(
            "± value: the worst root-mean-square error over the validation runs, rounded up. "
            f"Conditions: {proto.get('conditions') or acc.get('conditions', 'not stated')}. "
            "Source: motionlab "
            f"{acc.get('motionlab', '?')}, {acc.get('generated', '?')}, "
            f"'{acc.get('command', '?')}'.",
            size=SIZE["small"],
            colour=MUTED,
        )
        if acc.get("caveat"):
            doc.paragraph(str(acc["caveat"]), size=SIZE["small"], colour=MUTED)
    _real_figures(doc, view, types, proto.get("real") or {})
    validation = view.session.results.validation
    val = validation.angles if validation is not None else None
    val = val.columns if val is not None else {}
    if val:
        grades = angle_grades(view)  # an uncertainty of a range the report withholds is moot
        rows = [
            [col.removesuffix("_deg").replace("_", " "), f"{v.rmse_deg:.1f}"]
            for col, v in ((c, val[c]) for c in in_order(val, _columns(view)))
            if not v.withheld and grades.get(col, ("",))[0] != NOT_DETERMINED
        ]
        if rows:
            doc.heading("In this session, against the optical reference")
            doc.table(["Angle", "RMSE (°)"], rows, [0.5, 0.2], align=["l", "r"])


def _real_figures(doc: Document, view: SessionView, types: dict, real: dict[str, Any]) -> None:
    """The protocol's figures from real recordings with an optical reference (``real`` in its
    entry of ``accuracy.yaml``), each angle's grade here as for the simulated ones, and the
    joint's rotation away from the rest pose, which no anatomical frame moves."""
    blocks = {}
    for jtype, names in types.items():
        typed = [
            real_accuracy_sentence(a, real[f"{jtype}_{a}"], jtype) + _here(view, jtype, a)
            for a in names
            if f"{jtype}_{a}" in real
        ]
        whole = real.get(f"{jtype}_rotation_from_rest")
        if typed and whole:
            typed.append(real_accuracy_sentence("rotation_from_rest", whole, jtype))
        if typed:
            blocks[jtype] = typed
    if not blocks:
        return
    doc.heading("On real recordings, against an optical reference")
    doc.paragraph(
        "Where these are larger than the simulated figures above, they are the ones to read: "
        "your recordings are real ones, and a range of motion in them is uncertain by about "
        "these amounts."
    )
    for jtype, typed in blocks.items():
        if len(types) > 1:
            doc.paragraph(joint_type_title(jtype), weight="bold")
        doc.bullets(typed)
    doc.paragraph(
        "± value: the worst offset-free root-mean-square error over the recordings, rounded up "
        "(a range of motion does not depend on the angle's zero). "
        f"Conditions: {real.get('conditions', 'not stated')}.",
        size=SIZE["small"],
        colour=MUTED,
    )


def _here(view: SessionView, jtype: str, angle: str) -> str:
    """What this recording's grade of ``angle`` of the ``jtype`` joints does to the figure on
    file: nothing when determined; a real walk's weak hip ab-adduction (pelvis's forward
    direction 5-10° off) was told ±2° with no word of it."""
    grades = angle_grades(view)
    if not any(g == DETERMINED for g, _ in grades.values()):
        return ""  # none determined: the caveat above the list says it for all
    by_grade: dict[str, list[str]] = {}
    for j in view.joints():
        for a, c in angle_columns(j):
            if j.type == jtype and a == angle and c in grades:
                by_grade.setdefault(grades[c][0], []).append(joint_title(j).lower())
    parts = []
    for grade, words in ((NOT_DETERMINED, "not shown"),
                         ("weak", "it may be further off than this")):  # fmt: skip
        joints = by_grade.pop(grade, [])
        if joints:
            whom = "" if len(by_grade) == 0 and not parts else f" for the {' and '.join(joints)}"
            parts.append(f"{grade}{whom} in this recording: {words}")
    return f" — {'; '.join(parts)} (see the calibration page)" if parts else ""


def _lowpass_caveat(view: SessionView) -> str:
    """Where this session's angle table is low-passed otherwise than the validation runs' (at
    the default cut-off): what that can change; empty where it is the same."""
    angles = view.session.results.angles
    if angles is None or angles.lowpass_hz == ANGLES_LOWPASS_HZ:
        return ""
    if angles.lowpass_hz == 0:
        here = f"as computed, not low-passed (its ranges are taken at {ANGLES_LOWPASS_HZ:g} Hz too)"
    else:
        here = f"low-passed at {angles.lowpass_hz:g} Hz, and so are its ranges"
    return (
        f"These figures are of angles low-passed at {ANGLES_LOWPASS_HZ:g} Hz; this session's "
        f"are {here}, so they may differ from the figures by what lies between the two "
        "cut-offs (a sensor's wobble on the skin after each heel strike, or a fast movement's "
        "own content)."
    )


def _calibration_caveat(view: SessionView) -> str:
    """Why the figures on file do not hold for this recording: a single-pose calibration, or
    no angle determined (the figures come from recordings calibrated as the protocol asks);
    empty when they may hold. Two single-pose recordings were told ±1-2° while one of them
    read its own pose as 20° of lateral bending."""
    cal = view.session.results.calibration
    if cal is not None and cal.single_pose:
        why = (
            f"this recording was calibrated from one pose ('{cal.single_pose}'), its sensors' "
            "headings on their segments taken from the protocol's placement hint"
        )
    elif not any(g == DETERMINED for g, _ in angle_grades(view).values()):
        why = "this recording determined none of its angles (see the calibration page)"
    else:
        return ""
    return (
        "These figures hold for recordings calibrated as the protocol asks; " + why + ", so "
        "its angles may be further off by what the calibration could not measure, and their "
        "accuracy is not known."
    )


def _params(view: SessionView) -> list[list[str]]:
    """One row per estimator and parameter set: its name, the sensors it fused, the parameters
    (sorted by name)."""
    seen: dict[tuple[str, str], list[str]] = {}
    for label, entry in view.session.results.fusion.items():
        name = entry.name + ("" if entry.magnetometer else " (6-D)")
        params = ", ".join(f"{k} = {_value(v)}" for k, v in sorted((entry.params or {}).items()))
        seen.setdefault((name, params or "defaults"), []).append(label)
    return [[name, ", ".join(labels), params] for (name, params), labels in seen.items()]


def _value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list) and len(v) > 4:
        return f"[{len(v)} values]"
    return str(v)


def methods_page(doc: Document, view: SessionView) -> None:
    """Estimator, calibration and angle methods, and the provenance log with input hashes."""
    doc.section(
        "Methods appendix",
        "How the numbers in this report were computed, and from which files.",
    )
    doc.heading("Orientation estimation")
    rows = _params(view)
    if rows:
        doc.table(
            ["Estimator", "Sensors", "Parameters"], rows, [0.16, 0.3, 0.54], align=["l", "l", "l"]
        )
    else:
        doc.paragraph("No fusion results stored; the sensors' own orientations were used.")
    vendor_only = not rows or all(r[0].startswith("vendor") for r in rows)
    doc.paragraph(
        "Each sensor's orientation (sensor to east-north-up earth frame, Hamilton quaternions) "
        + (
            "is the one its device or software computed and exported, read as recorded"
            if vendor_only
            else "is estimated from its gyroscope, accelerometer and, where given, "
            "magnetometer; 6-D estimates leave the magnetometer out"
        )
        + " (each segment's heading then comes from the heading alignment with its neighbour).",
        size=SIZE["small"],
        colour=MUTED,
    )
    doc.heading("Sensor-to-segment calibration")
    cal = view.session.results.calibration
    segments = cal.segments if cal is not None else {}
    methods = sorted({r.method for r in segments.values()})
    doc.paragraph(
        f"Protocol '{view.protocol.name}' ({view.protocol.path}); segment frames (ISB: x "
        "anterior, y proximal, z right) fitted from gravity in static poses and from the "
        "rotation axes of functional movements (singular value decomposition, reliability "
        f"ρ = σ1/Σσ), weighted orthogonal Procrustes; methods used: {', '.join(methods)}."
    )
    if view.protocol.source:
        doc.paragraph(" ".join(view.protocol.source.split()), size=SIZE["small"], colour=MUTED)
    doc.heading("Joint angles and metrics")
    angles = view.session.results.angles
    gait = any(t.is_gait for t in view.protocol.tasks)
    doc.paragraph(decomposition_text(view.joints(), gait, angles.lowpass_hz if angles else 0.0))
    doc.heading("Provenance")
    rows = []
    for p in view.session.provenance:
        stage = (p.get("parameters") or {}).get("stage", "")
        rows.append(
            [
                p.get("time", "")[:19].replace("T", " "),
                p.get("software", ""),
                stage,
                p.get("command", ""),
            ]
        )
    doc.table(
        ["Time (UTC)", "Software", "Stage", "Command"],
        rows,
        [0.18, 0.15, 0.1, 0.57],
        align=["l", "l", "l", "l"],
        size=SIZE["small"],
    )
    hashes = {}
    for p in view.session.provenance:
        hashes.update(p.get("inputs", {}) or {})
    if hashes:
        doc.heading("Input files (SHA-256)")
        doc.table(
            ["File", "SHA-256"],
            [[str(k), v] for k, v in hashes.items()],
            [0.3, 0.7],
            align=["l", "l"],
            size=SIZE["small"] - 0.5,
        )
    seed = [p.get("parameters", {}).get("seed") for p in view.session.provenance]
    seed = [s for s in seed if s is not None]
    if seed:
        doc.paragraph(
            f"Random seed(s): {', '.join(map(str, dict.fromkeys(seed)))}.",
            size=SIZE["small"],
            colour=MUTED,
        )
