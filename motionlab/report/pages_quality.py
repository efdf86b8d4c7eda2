"""Data quality (rates, gaps, saturation, rest, magnetic disturbance, exclusions) and
calibration quality (methods, ρ per movement, residual angles, the grade of every joint angle
with its reason, the hinge axes fitted from movement, what to repeat)."""

from __future__ import annotations

import numpy as np

from motionlab.clocksync import describe
from motionlab.report.model import (
    MAG_FLAGS,
    NOT_DETERMINED,
    CalibrationRow,
    SessionView,
    calibration_rows,
    excluded,
    grade_rows,
    in_order,
    joint_title,
    quality_rows,
    raised_flags,
)
from motionlab.report.pdf import HEADING_H, MUTED, SIZE, Document, label_spans
from motionlab.report.sentences import missing_lines
from motionlab.results import HingeFit, SegmentCalibration
from motionlab.segments import hip_axis, placement
from motionlab.segments.quality import FUNCTIONAL_RHO_MIN, RESIDUAL_MAX_DEG, STATIC_RHO_MIN
from motionlab.segments.steps import unfound_step
from motionlab.timebase import runs

METHODS = {
    "procrustes": "the segment frame is the best fit to two or more measured axes",
    "primary_secondary": "one axis fixed as measured, the rotation about it from the others",
    "single_axis": "one axis measured, the rotation about it from the nominal placement",
    "nominal": "no axis measured: the protocol's placement hint only",
}
GRADE_WORDS = (
    "Determined: every axis the angle depends on was measured. Weak: one axis measured and the "
    "rest taken from the placement the protocol describes, a weak hinge fit, or a calibration "
    "the checks flagged: read it with care. Not determined: no axis of a segment was measured, "
    "or a fit failed: the curves are shown grey and no finding is stated."
)
SIGN_WORDS = {"anatomy": "anatomy (it flexes one way)", "nominal": "the placement hint"}


def _f(x: float, spec: str = ".1f") -> str:
    return format(x, spec) if np.isfinite(x) else "-"


TIMELINE_CAPTION = (
    "Blue: recorded; grey: sensor at rest; orange: magnetic field disturbed; red: gap kept "
    "as missing; green background: task blocks used for the metrics."
)


def _timeline(doc: Document, view: SessionView, follows: float = 0.0) -> None:
    """One lane per sensor: rest, magnetic disturbance and gaps over time, tasks shaded.

    ``follows`` (in) is what must stay with it on its page (a heading and a short list, not
    to be left alone on the next): the chart is drawn up to a quarter lower to make room for
    it, else it goes onto the next page with it."""
    sensors = list(view.session.sensors.values())
    height = 1.3 + 0.28 * len(sensors)
    need = height + doc.paragraph_height(TIMELINE_CAPTION, SIZE["small"]) + follows
    short = need - doc.room()
    if 0 < short <= 0.25 * height:
        height -= short
    elif short > 0:
        doc.ensure(need)
    ax = doc.axes_grid(1, 1, height, left=0.9, bottom=0.5, top=0.25)[0][0]
    fusion = view.session.results.fusion
    for k, s in enumerate(sensors):
        y = len(sensors) - 1 - k
        t = np.asarray(s.time, float)
        ax.broken_barh([(t[0], t[-1] - t[0])], (y - 0.35, 0.7), color="#d9e6f2")
        fz = fusion.get(s.label)
        for key, colour in (("rest", "#9e9e9e"), ("mag_disturbed", "#f4a259")):
            value = getattr(fz, key) if fz is not None else None
            mask = np.asarray(value if value is not None else np.zeros(0), bool)
            if len(mask) == len(t):
                bars = [(t[a], t[b - 1] - t[a]) for a, b in runs(mask)]
                ax.broken_barh(bars, (y - 0.3 + (0.35 if key == "rest" else 0), 0.25), color=colour)
        gaps = [(a, b - a) for a, b in (s.qc or {}).get("gaps", [])]
        if gaps:
            ax.broken_barh(gaps, (y - 0.4, 0.8), color="#b2182b")
    for a, b in view.blocks().values():
        ax.axvspan(a, b, color="#e8f4e8", zorder=0)
    ax.set_yticks(range(len(sensors)), [s.label for s in reversed(sensors)])
    ax.set_ylim(-0.6, len(sensors) + 0.5)
    ax.set_xlim(*ax.get_xlim())
    label_spans(ax, {k.replace("_", " "): v for k, v in view.blocks().items()}, SIZE["small"] - 1)
    ax.set_xlabel("time (s)")
    ax.set_title("The recording, sensor by sensor", loc="left")
    doc.paragraph(TIMELINE_CAPTION, size=SIZE["small"], colour=MUTED)


def data_quality_page(doc: Document, view: SessionView) -> None:
    doc.section(
        "Data quality",
        "What the sensors delivered: sampling, missing data, saturation, periods at rest "
        "(used to correct the gyroscope drift) and magnetic disturbance.",
    )
    rows, flagged = [], []
    for q in quality_rows(view):
        rows.append(
            [
                q.sensor,
                _f(q.rate_hz),
                _f(q.jitter_ms, ".2f"),
                _f(q.duration_s),
                str(q.dropped_samples),
                str(q.gaps_filled),
                f"{q.gaps_kept} ({q.gaps_kept_s:.1f} s)",
                str(q.saturated_samples),
                _f(q.rest_pct, ".0f"),
                _f(q.mag_disturbed_pct, ".0f"),
            ]
        )
        flagged.append(
            [False] * 6
            + [q.gaps_kept > 0, q.saturated_samples > 0, False]
            + [bool(np.isfinite(q.mag_disturbed_pct) and q.mag_disturbed_pct > 20)]
        )
    doc.table(
        [
            "Sensor",
            "Rate (Hz)",
            "Jitter (ms)",
            "Length (s)",
            "Missing samples",
            "Gaps filled",
            "Gaps kept",
            "Saturated samples",
            "At rest (%)",
            "Mag. disturbed (%)",
        ],
        rows,
        [0.21, 0.07, 0.08, 0.08, 0.09, 0.07, 0.11, 0.11, 0.08, 0.1],  # a label of 20 characters
        flagged,
    )
    doc.paragraph(
        "Missing samples were counted from the time stamps; gaps up to the ingest limit were "
        "interpolated (filled), longer ones kept as missing. Saturated: samples stuck at the "
        "sensor's measuring range.",
        size=SIZE["small"],
        colour=MUTED,
    )
    raised = raised_flags(view)
    flags = [
        f"{sensor}: {', '.join(f.replace('_', ' ') for f in these)}"
        for sensor, these in raised.items()
    ]
    doc.heading("Quality checks raised")
    doc.bullets(flags or ["none: every sensor's signals passed their checks (the clocks: below)"])
    if _mag_flags_unused(view, raised):
        doc.paragraph(
            "The magnetometers' checks are not raised: the orientations were estimated without "
            "them (6-D).",
            size=SIZE["small"],
            colour=MUTED,
        )
    synced = view.session.results.clock_sync
    if synced is not None and synced.fits:
        doc.heading("Sensor clocks")
        doc.paragraph(
            "Each sensor's clock against its neighbour's, from the acceleration of the joint "
            "centre they share; in gait, every sensor's clock at once from the heel strikes all "
            "sensors feel and those joint centres, a measurement that disagrees with the others "
            "set aside. Corrected where the estimate was reliable and not zero.",
            size=SIZE["small"],
            colour=MUTED,
        )
        doc.bullets([describe(fit) for fit in synced.fits.values()])
    reasons = excluded(view) or ["nothing"]
    follows = doc.bullets_height(reasons)
    _timeline(doc, view, min(1.2, HEADING_H + follows) + 0.05)  # as the heading keeps it
    doc.heading("Excluded from the analysis, and why", follows=follows)
    doc.bullets(reasons)


def _grades_table(doc: Document, view: SessionView) -> None:
    """Each joint's angles with their grade and the reason; a joint's angles that share both
    are one row."""
    groups: list[list] = []
    for r in grade_rows(view):
        key = (r.joint, r.grade, r.reason)
        if groups and groups[-1][0] == key:
            groups[-1][1].append(r.angle)
        else:
            groups.append([key, [r.angle]])
    rows, muted = [], []
    for (joint, grade, reason), angles in groups:
        rows.append(
            [
                joint_title(view.protocol.joints[joint]),
                ", ".join(a.replace("_", " ") for a in angles),
                grade,
                reason or "its axes were measured",
            ]
        )
        muted.append(grade == NOT_DETERMINED)
    doc.heading("What the recording determined: a grade for every angle")
    doc.paragraph(GRADE_WORDS, size=SIZE["small"], colour=MUTED)
    doc.table(
        ["Joint", "Angles", "Grade", "Why"],
        rows,
        [0.2, 0.22, 0.16, 0.42],
        align=["l", "l", "l", "l"],
        muted=muted,
    )


def _direction(fit: HingeFit) -> str:
    """How the hinge direction was decided, in words."""
    sign = SIGN_WORDS.get(str(fit.sign), str(fit.sign) or "-")
    rel = str(fit.relative_sign)
    both = {
        "measured": "the data",
        "nominal": "the placement hint",
        "anatomy": "anatomy",  # was shown as "by -"
    }.get(rel, "nothing (not matched)")
    if rel == "anatomy" and str(fit.sign) == "anatomy":
        text = f"positive direction, and its match between the two segments: {sign}"
    else:
        text = f"positive direction: {sign}; matched between the two segments by {both}"
    if fit.used_for == "direction":
        text = (
            "axes measured by the calibration steps, the fit only says which way they point "
            f"(the placement hint was contradicted); {text}"
        )
    return text


def _hinges_table(doc: Document, view: SessionView) -> None:
    """The hinge axes fitted from ordinary movement: verdict, consistency, residual, direction."""
    cal = view.session.results.calibration
    hinges = cal.hinges if cal is not None else {}
    if not hinges:
        return
    rows, flagged = [], []
    for name in in_order(hinges, list(view.protocol.joints)):
        fit = hinges[name]
        joint = view.protocol.joints.get(name)
        verdict = str(fit.verdict)
        reasons = "; ".join(str(r) for r in fit.reasons)
        rows.append(
            [
                joint_title(joint) if joint else name,
                verdict,
                _f(float(fit.consistency_deg)),
                _f(float(fit.relative_residual), ".2f"),
                _direction(fit)
                + (f". {reasons[:1].upper()}{reasons[1:]}" if reasons else "")
                + _skin_lag(fit, joint, cal),
            ]
        )
        flagged.append([False, verdict != "determined"] + [False] * 3)
    doc.heading("Hinge axes from movement")
    doc.paragraph(
        "A hinge's axis fitted to the ordinary movement of its two segments: its axes where no "
        "functional movement measured them, else only which way they point. Consistency: "
        "largest angle between the axes fitted on parts of the movement; residual: RMS misfit "
        "relative to the angular rate off the axis.",
        size=SIZE["small"],
        colour=MUTED,
    )
    doc.table(
        [
            "Joint",
            "Verdict",
            "Consistency (°)",
            "Residual (ratio)",
            "How the direction was decided",
        ],
        rows,
        [0.2, 0.12, 0.13, 0.12, 0.43],
        flagged,
        align=["l", "l", "r", "r", "l"],
    )


def _skin_lag(fit, joint, cal) -> str:
    """What a two-axis fit found of the proximal sensor's skin lag (``axial_follow``) and whether
    the angles give it back (:mod:`motionlab.segments.skin_lag`: where they take the fit's axes
    and heading ties, :func:`~motionlab.segments.placement.fit_in_use`); empty where not
    fitted."""
    follow = float(getattr(fit, "axial_follow", float("nan")))
    if joint is None or not np.isfinite(follow):
        return ""
    share = f"{follow:.2f} of" if follow < 0.995 else "all of"
    if placement.fit_in_use(cal, joint) is None:
        return (
            f". By this fit, which the angles do not use, the {joint.proximal} sensor follows "
            f"{share} its segment's twist about the long axis"
        )
    if follow >= 0.995:
        return f". The {joint.proximal} sensor follows its segment's twist about the long axis"
    back = (
        f"the rest is given back in the angles from its twist against the {fit.lag_anchor}"
        if getattr(fit, "lag_anchor", "")
        else "the rest is not given back (no thorax sensor recording the stand to take its "
        "twist against)"
    )
    return (
        f". The {joint.proximal} sensor follows {share} its segment's twist about the long axis "
        f"(the skin lags); {back}"
    )


def _hip_axes_table(doc: Document, view: SessionView) -> None:
    """The hips' flexion axes from the walk (:mod:`motionlab.segments.hip_axis`)."""
    cal = view.session.results.calibration
    axes = cal.hip_axes if cal is not None else {}
    if not axes:
        return
    rows, flagged = [], []
    for name in in_order(axes, list(view.protocol.joints)):
        fit = axes[name]
        joint = view.protocol.joints.get(name)
        used = bool(fit.used)
        rows.append(
            [
                joint_title(joint) if joint else name,
                "yes" if used else "no",
                _f(float(fit.turn_deg)) if used else "-",  # an axis not used turns nothing
                _f(float(fit.rho), ".2f"),
                str(fit.reason) or "-",
            ]
        )
        flagged.append([False] * 5)  # a refinement not used is no fault: the grades say what is
    doc.heading("Hip flexion axes from the walk")
    doc.paragraph(
        "Each hip is measured about the dominant axis of the thigh's rotation relative to the "
        "pelvis in the recording (the thigh's frame from the knee axis is left to the knee). "
        "Turn: that axis's angle about the pelvis's vertical axis from the pelvis's "
        f"medio-lateral axis; ρ: how dominant it is (1: one axis only; used from "
        f"{hip_axis.MIN_RHO:.2f}). Where it is not used the hip is measured about the pelvis's "
        "medio-lateral axis, as calibrated; the grades above say what that determines.",
        size=SIZE["small"],
        colour=MUTED,
    )
    doc.table(
        ["Joint", "Used", "Turn (°)", "ρ", "Why not used"],
        rows,
        [0.2, 0.1, 0.12, 0.1, 0.48],
        flagged,
        align=["l", "l", "r", "r", "l"],
    )


def calibration_page(doc: Document, view: SessionView) -> None:
    cal = view.session.results.calibration or SegmentCalibration("")
    doc.section(
        "Calibration quality",
        "How each sensor's position on its body segment was found: static poses fix the "
        "vertical axis (gravity), functional movements the joint axes. ρ (reliability, 0-1) says "
        "how clean a pose or movement was; the residual is the angle between a measured axis and "
        "the fitted segment frame.",
    )
    steps = cal.steps
    kinds = {s.name: s.kind for s in view.protocol.calibration}
    rows = [
        [
            name.replace("_", " "),
            kinds.get(name, ""),
            f"{rng[0]:.1f}–{rng[1]:.1f}"
            if rng
            else unfound_step(name, view.protocol, cal.single_pose),
        ]
        for name, rng in ((k, steps[k]) for k in in_order(steps, list(kinds)))
    ]
    doc.heading("Steps found in the recording")
    if rows:
        doc.table(["Step", "Kind", "Time (s)"], rows, [0.4, 0.2, 0.4], align=["l", "l", "l"])
    else:
        doc.paragraph("none: the protocol has no calibration steps", size=SIZE["small"])

    doc.heading("Per segment and step")
    rows, flagged = [], []
    for r in calibration_rows(view):
        cells, flags = calibration_cells(r, view.protocol.joints)
        rows.append(cells)
        flagged.append(flags)
    doc.table(
        ["Segment", "Method", "Step", "ρ", "ρ wanted", "Residual (°)", "In fit", "Segment"],
        rows,
        [0.13, 0.14, 0.19, 0.08, 0.12, 0.13, 0.09, 0.12],
        flagged,
        align=["l", "l", "l", "r", "r", "r", "r", "r"],
    )
    _grades_table(doc, view)
    _hinges_table(doc, view)
    _hip_axes_table(doc, view)
    doc.heading("Warnings and what to repeat next time")
    doc.bullets(repeat_lines(view, cal))
    doc.paragraph(
        f"Limits: ρ ≥ {STATIC_RHO_MIN:.2f} for static poses and ≥ {FUNCTIONAL_RHO_MIN:.2f} for "
        f"functional movements (or within 0.1 of the protocol's reference), residual ≤ "
        f"{RESIDUAL_MAX_DEG:.0f}°. Methods: "
        + "; ".join(f"'{k.replace('_', ' ')}': {v}" for k, v in METHODS.items())
        + ". 'Segment': ok, or check when its quality checks failed or the recording did not "
        "determine its frame (the grades below say which angles that leaves weak or not "
        "determined). 'In fit': no when a joint movement's axis was left out because a step "
        "keeping the "
        "joint still measured the same axis better (its residual is then not the frame's error). "
        "An axis found in the movement itself is judged by its own checks (the grades below), "
        "whose verdict stands in 'ρ wanted', red unless determined; its ρ, where one is shown, "
        "is that method's own measure of how clearly the movement showed the axis, not held to "
        "these limits.",
        size=SIZE["small"],
        colour=MUTED,
    )


def merged_messages(messages: list[str]) -> list[str]:
    """Segment messages (``"<segment>: <text>"``) with one line per text: the segments that
    share it named together (a two-axis fit's verdict was said once for each of its segments),
    in the order they first appear."""
    segments: dict[str, list[str]] = {}
    for m in messages:
        seg, sep, text = m.partition(": ")
        key = text if sep else m
        segments.setdefault(key, []).append(seg if sep else "")
    return [f"{', '.join(dict.fromkeys(s))}: {text}" if any(s) else text
            for text, s in segments.items()]  # fmt: skip


def step_words(step: str, joints: dict | None = None) -> str:
    """A calibration row's step as a clinician reads it: a protocol step by its name, an axis
    found in a joint's own movement (``movement:knee_r:0``) as ``movement (right knee)``, the
    pelvis's forward direction from the walk (``movement:turns``) as ``the walk (forward)``."""
    kind, _, rest = step.partition(":")
    if kind != "movement" or not rest:
        return step.replace("_", " ")
    name = rest.split(":")[0]
    if name == "turns":
        return "the walk (forward)"
    joint = (joints or {}).get(name)
    return f"movement ({joint_title(joint).lower() if joint else name.replace('_', ' ')})"


def repeat_lines(view: SessionView, cal: SegmentCalibration) -> list[str]:
    """The calibration page's "Warnings and what to repeat next time": the calibration's
    warnings and segment checks, then each joint an angle of which the recording left weak or
    not determined, with its remedy (the summary's :func:`missing_lines`: 'none' stood beside
    a weak lumbar rotation whose remedy the summary gave)."""
    messages = [str(w) for w in cal.warnings] + merged_messages(
        [m for res in cal.segments.values() for m in (res.quality.messages if res.quality else [])]
    )
    return messages + missing_lines(view) or [
        "none: every segment was calibrated within the quality limits"
    ]


def calibration_cells(
    r: CalibrationRow, joints: dict | None = None
) -> tuple[list[str], list[bool]]:
    """The cells of one row of the table "Per segment and step" and which to draw red.

    A protocol step's ρ is red below its floor (static or functional, or 0.1 under the
    protocol's reference ρ); an axis found in the movement itself is not held to a floor (the
    weight the fit gives it is set by its verdict; a ρ it carries is its method's own measure,
    e.g. the trunk's ``1 − 1/`` its axis's energy ratio): its own check's verdict stands in place
    of the floor, red unless determined. A residual is red above ``RESIDUAL_MAX_DEG`` only for
    an axis that entered the fit (one left out leaves no error in the segment's frame).
    """
    floor = STATIC_RHO_MIN if r.kind == "static" else FUNCTIONAL_RHO_MIN
    if np.isfinite(r.reference_rho):
        floor = r.reference_rho - 0.1
    own_check = r.verdict is not None
    cells = [
        r.segment,
        r.method.replace("_", " "),
        step_words(r.step, joints),
        _f(r.rho, ".3f"),
        str(r.verdict) if own_check else f"≥ {floor:.2f}" if r.step != "none" else "-",
        _f(r.residual_deg),
        "yes" if r.used else "no",
        "ok" if r.segment_ok else "check",
    ]
    weak = own_check and r.verdict != "determined"
    weak_rho = not own_check and bool(r.rho < floor)
    residual = bool(r.used and r.residual_deg > RESIDUAL_MAX_DEG)
    return cells, [False] * 3 + [weak_rho, weak, residual, False, not r.segment_ok]


def _mag_flags_unused(view: SessionView, raised: dict[str, list[str]]) -> bool:
    """Whether a sensor's magnetometer flag was left out of "Quality checks raised"
    (``raised``, :func:`raised_flags`: its orientation 6-D)."""
    return any(
        set(q.flags) & MAG_FLAGS and not MAG_FLAGS & set(raised.get(q.sensor, ()))
        for q in quality_rows(view)
    )
