"""The one screen ``motionlab run`` prints when it is done (:func:`run_summary`): subject, data,
fusion, clock sync, calibration, the angles' grades, tasks, gait, flexion ranges, validation,
findings, outputs and stage times, from the report's :class:`~motionlab.report.model.SessionView`
as the PDF's pages read it."""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING

import numpy as np

from motionlab.kinematics.gait_course import change_text, walk_courses
from motionlab.report.model import (
    REACH_TOLERANCE_DEG,
    angle_grades,
    calibration_rows,
    gait_profile,
    grade_mark,
    grade_rows,
    quality_rows,
    raised_flags,
    rom_rows,
)
from motionlab.report.sentences import (
    allowance,
    findings,
    missing_lines,
    paced_words,
    short_of_reach,
    span,
    task_name,
)
from motionlab.results import NOT_LINKED, VENDOR_KEPT

if TYPE_CHECKING:
    from motionlab.report import ReportOutput
    from motionlab.report.model import SessionView
    from motionlab.results import Gait


def grade_lines(view: SessionView, width: int = 100) -> list[str]:
    """Summary lines on the angles' grades: how many the recording determined, then the weak
    and not determined ones by column name, grouped by reason (wrapped at ``width``)."""
    rows = grade_rows(view)
    good = sum(r.grade == "determined" for r in rows)
    lines = [f"  angles determined by the recording: {good}/{len(rows)}"]
    groups: dict[tuple[str, str], list[str]] = {}
    for r in rows:
        if r.grade != "determined":
            groups.setdefault((r.grade, r.reason), []).append(r.column)
    for (grade, reason), cols in groups.items():
        text = f"{grade}: {', '.join(cols)}" + (f" - {reason}" if reason else "")
        lines += textwrap.wrap(
            text, width, initial_indent="    ", subsequent_indent="      ", break_on_hyphens=False
        )
    return lines


def run_summary(
    view: SessionView,
    report: ReportOutput,
    times: dict[str, float],
    total_s: float,
    *,
    session_file: str,
    csv_dir: str,
    results_json: str,
) -> str:
    """One screen: subject, data, calibration, tasks, flexion ranges, validation, outputs
    (``report``'s, and the run's ``session_file``, ``csv_dir`` and ``results_json`` names),
    the stage ``times`` (s) and the ``total_s``."""
    ses, proto = view.session, view.protocol
    q = quality_rows(view)
    flagged = sorted({f for flags in raised_flags(view).values() for f in flags})
    rate = q[0].rate_hz if q else float("nan")
    lines = [
        f"motionlab run: {proto.name} ({proto.title}) - subject {view.subject}, {view.date_label}",
        f"  data: {len(ses.sensors)} sensors at {rate:.0f} Hz, {view.angles['time_s'][-1]:.0f} s;"
        f" quality flags: {', '.join(flagged) or 'none'}",
    ]
    fusion = {
        f"{e.name}{'' if e.magnetometer else ' (6-D, no magnetometer)'}"
        for e in ses.results.fusion.values()
    }
    lines.append(f"  fusion: {', '.join(sorted(fusion)) or 'sensor orientations'}")
    synced = ses.results.clock_sync.fits if ses.results.clock_sync is not None else {}
    if synced:
        moved = [f"{k} {1e3 * v.offset_s:+.1f} ms" for k, v in synced.items()
                 if v.status == "applied"]  # fmt: skip
        said = "no correction needed or reliable"
        if all(v.status.startswith(VENDOR_KEPT) for v in synced.values()):
            said = "kept as recorded: the files show one clock"
        # what the corrections do not say: sensors left as recorded, parts on their own clocks
        parts = {k: v for k, v in synced.items() if v.status.startswith(NOT_LINKED)}
        apart = [f"{k}'s clock not linked to {v.reference}'s" for k, v in parts.items()]
        recorded = [k for k, v in synced.items() if not v.timed and k not in parts]
        untimed = ([f"not timed, as recorded: {', '.join(recorded)}"] if recorded else []) + apart
        lines.append(
            f"  clock sync: {', '.join(moved) or said}"
            + "".join(f"; {u}" for u in untimed)
            + f" ({len(synced)} sensor pairs checked)"
        )
    segs = {r.segment: r.segment_ok for r in calibration_rows(view)}
    bad = [s for s, ok in segs.items() if not ok]
    cal = ses.results.calibration
    # where each step was found: a stand after the walk is not where the protocol puts it
    found = [
        f"{name} {span[0]:.0f}-{span[1]:.0f} s"
        for name, span in (cal.steps if cal is not None else {}).items()
        if span is not None and len(span) == 2
    ]
    lines.append(
        f"  calibration: {len(segs) - len(bad)}/{len(segs)} segments ok"
        + (f"; check {', '.join(bad)}" if bad else "")
        + (f" ({', '.join(found)})" if found else "")
    )
    lines += [f"  warning: {w}" for w in (cal.warnings if cal is not None else [])]
    tied = [
        f"{j} by its {h.source.replace('_', ' ')} ({h.range_deg:.1f}° range)"
        for j, h in (ses.results.heading or {}).items()
        if h.anchors and h.source != "steps"
    ]
    if tied:
        lines.append("  heading tied by the joints: " + ", ".join(tied))
    lines += grade_lines(view)
    spans = ", ".join(f"{task_name(k)} {a:.0f}-{b:.0f} s" for k, (a, b) in view.blocks().items())
    if not spans and cal is not None and cal.single_pose:
        spans = "none (the recording is its calibration pose)"
    lines.append("  tasks: " + spans)
    lines.append(_gait_line(view))
    flexion = [r for r in rom_rows(view) if r.angle == "flexion"]
    if flexion:
        lines.append("  flexion range (typical, deg):")
    for r in flexion:
        shown = (  # as the report: a range the recording did not determine is withheld
            span(r.typical_min_deg, r.typical_max_deg) if r.grade != "not determined" else "-"
        )
        normal = (
            f"normal {span(*r.normal)}, {r.status or 'not compared'}"
            + (f", {allowance(r)}" if allowance(r) else "")
            + (f", peak over {REACH_TOLERANCE_DEG:g}° short" if short_of_reach(r) else "")
            + (f", {paced_words(view, r)}" if r.paced else "")
            if r.normal
            else "no normal range"
        )
        lines.append(
            f"    {task_name(r.task):<14} {r.joint:<8} "
            f"{shown:>10}  ({normal})" + (f" {grade_mark(r.grade)}" if grade_mark(r.grade) else "")
        )
    validation = ses.results.validation
    val = validation.angles if validation is not None else None
    grades = angle_grades(view)
    columns = val.columns if val is not None else {}
    rmse = [
        f"{c.removesuffix('_deg')} {v.rmse_deg:.1f}"
        + (f" {grade_mark(grades[c][0])}" if c in grades and grade_mark(grades[c][0]) else "")
        for c, v in columns.items()
        if not v.withheld
    ]
    if rmse:
        lines.append(
            f"  validation RMSE (deg): {', '.join(rmse[:6])}" + (" ..." if len(rmse) > 6 else "")
        )
    withheld = list(dict.fromkeys(v.withheld for v in columns.values() if v.withheld))
    if withheld:  # the validation could not state these: say why, not a number
        n = sum(bool(v.withheld) for v in columns.values())
        lines.append(f"  validation not stated for {n} angle(s): {'; '.join(withheld)}")
    lines.append("  findings (determined numbers only):")
    shown = findings(view, limit=4)
    lines += [f"    - {f}" for f in shown]
    hidden = len(findings(view)) - len(shown)
    if hidden > 0:  # an abnormal range left off the screen must not look like none
        lines.append(
            f"    - and {hidden} more on the report's summary page ({report.pdf_path.name})"
        )
    missing = missing_lines(view)
    if missing:
        lines.append("  weak or not determined in this recording:")
        lines += [f"    - {m}" for m in missing]
    lines.append(f"outputs in {report.pdf_path.parent}:")
    lines.append(
        f"  {session_file}, {report.pdf_path.name} ({len(report.pages)} pages), "
        f"{report.text_path.name}, {csv_dir}/ ({len(report.csv_paths)} tables), {results_json}"
    )
    steps = ", ".join(f"{k} {v:.1f}" for k, v in times.items())
    lines.append(f"time: {total_s:.1f} s ({steps})")
    return "\n".join(lines)


def _gait_line(view: SessionView) -> str:
    """One summary line about gait: its main numbers (each only when enough steady strides and
    determined inputs give it, else why not), or why there are no gait pages."""
    gait = view.session.results.gait
    if gait is None:
        return "  gait: none in this recording (the protocol has no gait task); no gait pages"
    if not gait.ok:
        return f"  gait: {gait.status}; no gait pages"
    s = gait.summary

    def number(key: str, v: float, fmt: str) -> str:
        return fmt.format(v) if v == v else s.withheld.get(key, "n/a")

    mp = gait_profile(view)
    gps = mp.gps.get("overall", float("nan")) if mp is not None else float("nan")
    missing = mp.not_computed if mp is not None else None
    gps_text = f"GPS {gps:.1f} deg" if gps == gps else (missing or "GPS n/a")
    speed = s.walking_speed_m_s
    speed_text = f", speed {speed:.2f} m/s (leg model)" if speed == speed else ""
    return (
        f"  gait: {s.strides_kept} strides, cadence "
        f"{number('cadence_steps_per_min', s.cadence_steps_per_min, '{:.1f} steps/min')}, "
        "step-time asymmetry "
        f"{number('step_time_asymmetry_pct', s.step_time_asymmetry_pct, '{:.1f} %')}"
        f"{speed_text}; {gps_text}{_course_text(gait)}"
    )


#: what the summary line says of a long walk's change: (column, name, unit)
_COURSE_SHOWN = (
    ("cadence_steps_per_min", "cadence", "steps/min"),
    ("walking_speed_m_s", "speed", "m/s"),
)


def _course_text(gait: Gait) -> str:
    """For each long walk, its change from the first part to the last
    (:mod:`motionlab.kinematics.gait_course`): cadence, and speed where measured, each ± its
    95 % interval, or why not."""
    out = []
    for course in walk_courses(gait):
        minutes = (course.parts[0].end_s - course.parts[0].start_s) / 60.0
        where = f"; {task_name(course.task)}, first to last {minutes:.1f} min: "
        if course.withheld:
            out.append(where + f"no change given ({course.withheld})")
            continue
        changes = [
            f"{name} {change_text(course, c)} {unit}"
            for c, name, unit in _COURSE_SHOWN
            if np.isfinite(course.change[c])
        ]
        out.append(where + ", ".join(changes))
    return "".join(out)
