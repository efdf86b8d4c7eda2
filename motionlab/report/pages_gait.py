"""Gait pages: spatio-temporal parameters against normative bands with the Movement Analysis
Profile (first page), then the pelvis, hip and knee cycle curves against the GPS's normative
curves; and the ``spatiotemporal.csv`` table. Drawn only when ``results.gait`` holds a gait
analysis (:mod:`motionlab.kinematics.gait`).

What is shown obeys the inputs: a side's parameter needs ``MIN_STRIDES`` (3) kept strides ("not
enough steady strides (2 of 3 needed)" instead), the asymmetry as many paired steps; each is
given as mean ± SD (CV) with its median and interquartile range, and is red only when outside
its band by more than its own uncertainty (1.96 standard errors plus the method's timing or
length error bound, :func:`beyond`). The GPS and the MAP's bars come only from determined
variables (:func:`motionlab.report.model.gait_profile`); a curve of a variable the recording did
not determine is not drawn, a weak one is labelled."""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from motionlab.kinematics.gait_course import DIGITS, WalkCourse, change_text, walk_courses
from motionlab.kinematics.gps import VARIABLES, normative, population_gps, variable_grades
from motionlab.kinematics.spatiotemporal import (
    BOTH_LEGS,
    MIN_STRIDES,
    STRIDE_COLUMNS,
    method_error,
    too_few,
)
from motionlab.report.model import SIDE_NAMES, SessionView, gait_profile, gait_result
from motionlab.report.normative import gait_bands
from motionlab.report.pdf import BAND_COLOUR, MUTED, SIDE_COLOUR, SIZE, Document
from motionlab.report.sentences import task_name
from motionlab.results import Gait, GaitSummary, MovementProfile, StrideStats

_LABELS = {
    "cadence_steps_per_min": "cadence (steps/min)",
    "stride_time_s": "stride time (s)",
    "step_time_s": "step time (s)",
    "stance_time_s": "stance time (s)",
    "swing_time_s": "swing time (s)",
    "stance_pct": "stance (% of stride)",
    "swing_pct": "swing (% of stride)",
    "double_support_pct": "double support (% of stride)",
    "step_time_asymmetry_pct": "step-time asymmetry (symmetry index, %)",
    "stride_time_cv_pct": "stride-time variability (CV within bouts, %)",
    "step_length_m": "step length (m)*",
    "stride_length_m": "stride length (m)*",
    "walking_speed_m_s": "walking speed (m/s)*",
}


#: the table's cell of a number that compares the legs when their clocks are not linked
NOT_LINKED_CELL = "withheld: the legs' clocks are not synchronised"

#: the stride-table columns that need the legs' lengths (the leg model)
LENGTH_COLUMNS = ("step_length_m", "stride_length_m", "walking_speed_m_s")

#: the uncertainty a value must exceed a band by to be flagged: 1.96 standard errors (95 %)
Z95 = 1.96


def _fmt(s: StrideStats, digits: int) -> str:
    """``'1.10 ± 0.02 (CV 1.8 %)\\nmedian 1.10 (1.09-1.11); n 9'``, or why not given."""
    n = int(s.strides_n or 0)
    if n < MIN_STRIDES or not np.isfinite(s.mean):
        return too_few(n) if n < MIN_STRIDES else "-"
    d = digits
    return (
        f"{s.mean:.{d}f} ± {s.sd:.{d}f} (CV {s.cv_pct:.1f} %)\n"
        f"median {s.median:.{d}f} ({s.q1:.{d}f}-{s.q3:.{d}f}); n {n}"
    )


def beyond(value: float, se: float, band: list[float] | None, method: float = 0.0) -> bool:
    """Whether ``value`` lies outside ``band`` by more than its own uncertainty: :data:`Z95`
    × its standard error ``se`` plus ``method``, the bound of the method's own error
    (:func:`~motionlab.kinematics.spatiotemporal.method_error`); a NaN ``se`` or ``method``
    counts as unknown: never flagged."""
    if not band or not (np.isfinite(value) and np.isfinite(se) and np.isfinite(method)):
        return False
    margin = Z95 * se + method
    return bool(value - margin > band[1] or value + margin < band[0])


def _both(summ: GaitSummary, c: str, v: float, se: float, n: int, measured: list[str]) -> str:
    """A bilateral number ``c`` (value ``v``, standard error ``se``, from ``n`` step pairs or
    strides of the ``measured`` sides) with its 95 % margin, or why it is not given."""
    if not np.isfinite(v):
        why = summ.withheld.get(c, "-")
        return NOT_LINKED_CELL if why == summ.withheld.get("step_time_s") else why
    what = "step pairs" if c == "step_time_asymmetry_pct" else "strides"
    margin = f" ± {Z95 * se:.1f}" if np.isfinite(se) else ""
    sides = "both sides" if len(measured) != 1 else f"{SIDE_NAMES[measured[0]]} side only"
    return f"{v:.1f}{margin} ({sides}; {n} {what})"


def gait_pages(doc: Document, view: SessionView) -> None:
    """The gait pages of one session (none without a gait analysis)."""
    g = gait_result(view)
    if g is None:
        return
    summ, bands = g.summary, gait_bands()["spatiotemporal"]
    doc.section(
        "Gait: spatio-temporal parameters and profile",
        "Events from the shank gyroscopes (initial contact: the shank stops swinging forward; "
        "final contact: midway between the last minimum before mid-swing and the following zero "
        "crossing); straight, steady strides only. "
        f"Per side mean ± SD (CV), median and interquartile range of at least {MIN_STRIDES} "
        "steady strides; step times only inside one steady bout, the asymmetry from paired "
        "consecutive steps. Red: outside the normal band by more than the value's own "
        "uncertainty (1.96 standard errors plus the method's event-timing error: 10 ms at "
        "initial, 20 ms at final contact, and up to 35 ms by which a walker's shank may stop "
        "swinging before the heel lands in the times from initial to final contact; lengths "
        "12 %). Normal bands are approximate ranges of healthy adults.",
    )
    rows, flags = [], []
    counts = {k: int(summ.sides[k]["stride_time_s"].strides_n or 0) for k in ("r", "l")}
    measured = [k for k in ("r", "l") if k in (g.events or {})]  # a shank sensor on that leg
    few = [f"{SIDE_NAMES[k]}: {too_few(n)}" for k, n in counts.items()
           if n < MIN_STRIDES and k in measured]  # fmt: skip
    if len(measured) == 1:
        other = SIDE_NAMES["l" if measured == ["r"] else "r"]
        doc.paragraph(f"Only the {SIDE_NAMES[measured[0]]} leg carries sensors: the {other} "
                      "column stays empty and the asymmetry needs both legs.")  # fmt: skip
    if few:
        doc.paragraph("No mean is given for a side with too few strides (" + "; ".join(few)
                      + ").", weight="bold")  # fmt: skip
    not_linked = summ.withheld.get("step_time_s", "")  # only withheld when the clocks are not one
    if not_linked:
        doc.paragraph("Step time, double support, step and stride length, walking speed and the "
                      "step-time asymmetry compare one leg's events with the other's; "
                      f"{not_linked.removeprefix('not given: ')}, so none is given.",
                      weight="bold")  # fmt: skip
    times = [summ.sides[k]["stride_time_s"].mean for k in ("r", "l")]
    stride = float(np.nanmean(times)) if np.isfinite(times).any() else np.nan
    # without the legs' lengths (or a sensor) no stride has a length, however many were kept
    lengths_measured = bool(np.isfinite(g.strides.walking_speed_m_s).any())
    for c in STRIDE_COLUMNS:
        digits = 2 if c.endswith(("_s", "_m")) else 1
        r, left = summ.sides["r"][c], summ.sides["l"][c]
        band = bands.get(c)
        cells = [_fmt(x, digits) if counts[k] >= MIN_STRIDES else "-"
                 for k, x in (("r", r), ("l", left))]  # fmt: skip
        if len(measured) == 1 and c in BOTH_LEGS:
            cells = ["needs both legs" if k in measured else "-" for k in ("r", "l")]
        elif not_linked and c in BOTH_LEGS:
            cells = [NOT_LINKED_CELL] * 2
        elif c in LENGTH_COLUMNS and not lengths_measured:  # the note under the table says why
            cells = ["not measured*" if k in measured else "-" for k in ("r", "l")]
        rows.append([_LABELS[c], *cells, f"{band[0]:g}-{band[1]:g}" if band else "-"])
        flags.append([False] + [beyond(x.mean, np.nan if x.se is None else x.se, band,
                                       method_error(c, x.mean, stride)) for x in (r, left)]
                     + [False])  # fmt: skip
    bilateral = (
        ("step_time_asymmetry_pct", summ.step_time_asymmetry_pct,
         summ.step_time_asymmetry_se_pct, summ.step_pairs),
        ("stride_time_cv_pct", summ.stride_time_cv_pct, summ.stride_time_cv_se_pct,
         summ.strides_kept),
    )  # fmt: skip
    for c, value, se, n in bilateral:
        band = bands.get(c)
        rows.append([_LABELS[c], _both(summ, c, value, se, n, measured), "",
                     f"{band[0]:g}-{band[1]:g}" if band else "-"])  # fmt: skip
        flags.append([False, beyond(value, se, band, method_error(c, value, stride)), False,
                      False])  # fmt: skip
    doc.table(["parameter", "right", "left", "normal"], rows, [0.28, 0.29, 0.29, 0.14],
              flagged=flags, align=["l", "r", "r", "r"])  # fmt: skip
    rejected = ", ".join(f"{k} {v}" for k, v in summ.strides_rejected.items()) or "none"
    cadence = summ.cadence_steps_per_min
    cadence_text = (
        f"{cadence:.1f} steps/min"
        if np.isfinite(cadence)
        else summ.withheld.get("cadence_steps_per_min", "-")
    )
    doc.paragraph(
        f"Strides kept: {summ.strides_kept}; rejected: {rejected}. Overall cadence "
        f"{cadence_text}. *Lengths and speed: {length_note(g)}",
        size=SIZE["small"],
    )
    doc.paragraph(
        "Bands: " + gait_bands()["spatiotemporal_source"], size=SIZE["small"], colour=MUTED
    )
    for course in walk_courses(g):
        _course_table(doc, course)
    _map_chart(doc, gait_profile(view) or g.map)


#: the walk's course shown per part (units in the header)
_COURSE_HEADER = {
    "cadence_steps_per_min": "cadence",
    "stride_time_s": "stride (s)",
    "walking_speed_m_s": "speed (m/s)*",
    "stance_pct": "stance (%)",
}


def _course_table(doc: Document, course: WalkCourse) -> None:
    """A long walk part by part (:mod:`motionlab.kinematics.gait_course`), both sides pooled,
    and the change from the first part to the last with its 95 % interval."""
    doc.heading(f"Over the walk: {task_name(course.task)}")
    doc.paragraph(
        "Kept strides of both legs in equal parts from the first to the last (time on the "
        f"recording's clock): mean ± standard error (dash: fewer than {MIN_STRIDES} strides). "
        "Last row: the last part less the first, ± its 95 % interval; a change within its "
        "interval is none the recording can show. Speed is read with the same leg model "
        "throughout, so its change is better known than its level."
        + (f" No change is given: {course.withheld}." if course.withheld else ""),
        size=SIZE["small"],
    )
    rows = []
    for p in course.parts:
        cells = [f"{p.mean[c]:.{DIGITS[c]}f} ± {p.se[c]:.{DIGITS[c]}f}"
                 if np.isfinite(p.mean[c]) else "-" for c in _COURSE_HEADER]  # fmt: skip
        rows.append([p.label, str(p.strides), *cells])
    rows.append(["change", "", *(change_text(course, c) for c in _COURSE_HEADER)])
    header = ["part", "strides", *_COURSE_HEADER.values()]
    doc.table(header, rows, [0.16, 0.1, 0.185, 0.185, 0.185, 0.185])


def length_note(g: Gait) -> str:
    """One sentence on the stride length and speed: the model, its measured error, or why not."""
    speed = g.summary.walking_speed_m_s
    if not np.isfinite(speed):
        return (g.walking_speed or "not measured") + "."
    return (
        f"overall {speed:.2f} m/s; {g.walking_speed}. Measured error on one real walk (Vicon "
        "walking2, 3 strides, with the foot-roll factor taken from it): stride length within "
        "2 % of the heel markers on its steady strides; on a second real walker the speed read "
        "12 % above the one its foot sensors give: an estimate, checked on two walkers only "
        "(docs/kinematics.md)."
    )


def _map_chart(doc: Document, mp: MovementProfile) -> None:
    """The Movement Analysis Profile: GVS per determined variable and side, and the GPS when
    every variable is determined (else which are missing)."""
    missing = mp.not_computed or ""
    names = [v for v in mp.variables if any(v in mp.gvs.get(s, {}) for s in "rl")]
    if names:
        doc.ensure(3.8)  # the heading stays with its chart
    doc.heading("Gait Profile Score and Movement Analysis Profile")
    if names:
        ((ax,),) = doc.axes_grid(1, 1, 3.0, left=0.6, bottom=0.9, top=0.2)
        names = [*names, *([] if missing else ["GPS"])]
        x = np.arange(len(names))
        heights = [np.nan]
        for k, side in enumerate(("r", "l")):
            vals = [mp.gvs.get(side, {}).get(v, np.nan) for v in names if v != "GPS"]
            if not missing:
                vals.append(mp.gps.get(side, np.nan))
            ax.bar(x + (k - 0.5) * 0.38, vals, 0.36, color=SIDE_COLOUR[side],
                   label={"r": "right", "l": "left"}[side])  # fmt: skip
            heights += vals
        # each bar's own reference, a normal subject's expected score (the RMS of the normative
        # SD): a bar read alone had none (the knee's 12.8° against what?)
        expected = [population_gps((v,)) if v != "GPS" else mp.population_gps_deg for v in names]
        ax.hlines(expected, x - 0.42, x + 0.42, colors=MUTED, linestyles="--", lw=0.9,
                  label="expected of a normal subject")  # fmt: skip
        top = np.nanmax([*heights, *expected])
        if np.isfinite(top) and top > 0:  # room above the bars for the legend (it hid a bar's top)
            ax.set_ylim(0, 1.45 * top)
        ax.set_xticks(x, [n.replace("_", " ") for n in names], rotation=30, ha="right")
        ax.set_ylabel("deg (RMS difference)")
        ax.legend(loc="upper left", frameon=False)
    if missing:
        head = (
            f"{missing}; only the determined variables' scores are drawn. "
            if names
            else f"{missing}. "
        )
    else:
        head = (
            f"GPS: right {mp.gps.get('r', np.nan):.1f}°, "
            f"left {mp.gps.get('l', np.nan):.1f}°, overall {mp.gps['overall']:.1f}° "
            f"(Baker et al. 2009, Gait Posture 30:265; {len(mp.variables)} variables per "
            "side, no ankle or foot). "
        )
    doc.paragraph(
        head + "The normative curves are approximate, built from published key values "
        "(report_data/gait_normative.yaml): the score compares shapes, it is not a validated "
        "clinical GPS. The curves change with walking speed: a walk faster or slower than the "
        "norms' walkers (self-selected speed) raises a healthy walker's scores too.",
        size=SIZE["small"],
        colour=MUTED,
    )


def curve_page(doc: Document, view: SessionView) -> None:
    """Mean ± SD cycle curves per side against the normative mean ± SD."""
    g = gait_result(view)
    if g is None:
        return
    curves = g.curves
    used = [v for v in VARIABLES if any(v in curves.get(s, {}) for s in "rl")]
    if not used:
        return
    doc.section("Gait: pelvis, hip and knee over the stride",
                "Mean ± SD over kept strides (0 % = initial contact) against the normative "
                "mean ± SD used by the GPS; a curve the recording did not determine is not "
                "drawn, a weak one is labelled.")  # fmt: skip
    grades = variable_grades(view.protocol, view.session.results.calibration)
    nrows = (len(used) + 1) // 2
    even = len(used) % 2 == 0  # no spare cell for the key: it goes below the last row
    grid = doc.axes_grid(nrows, 2, 2.2 * nrows + 0.55 + 0.3 * even, left=0.6, hspace=0.75,
                         top=0.35, bottom=0.55 + 0.3 * even)  # fmt: skip
    pct = np.linspace(0, 100, 101)
    for i, v in enumerate(used):
        ax = grid[i // 2][i % 2]
        mean, sd = normative(v, pct)
        ax.fill_between(pct, mean - sd, mean + sd, color=BAND_COLOUR, alpha=0.6, lw=0)
        marks = []
        for side in ("r", "l"):
            c = curves.get(side, {})
            grade = grades.get(side, {}).get(v, ("determined", ""))[0]
            if v in c and grade != "determined":
                marks.append(f"{'right' if side == 'r' else 'left'} {grade}")
            if v in c and grade != "not determined":
                m, s = np.asarray(c[v]), np.asarray(c[f"{v}_sd"])
                ax.plot(pct, m, color=SIDE_COLOUR[side], lw=1.2)
                ax.fill_between(pct, m - s, m + s, color=SIDE_COLOUR[side], alpha=0.15, lw=0)
        if marks and all("not determined" in m for m in marks):
            ax.text(0.5, 0.5, "not determined: not drawn", transform=ax.transAxes,
                    ha="center", va="center", size=SIZE["small"], color=MUTED)  # fmt: skip
        ax.set_title(v.replace("_", " ") + (f" ({', '.join(marks)})" if marks else ""))
        ax.set_xlim(0, 100)
        ax.set_ylabel("deg")
        ax.set_xlabel("% of stride", size=SIZE["small"])
    for j in range(len(used), nrows * 2):
        grid[j // 2][j % 2].set_visible(False)
    key = [Line2D([], [], color=SIDE_COLOUR["r"], lw=1.2, label="right (mean ± SD)"),
           Line2D([], [], color=SIDE_COLOUR["l"], lw=1.2, label="left (mean ± SD)"),
           Patch(color=BAND_COLOUR, alpha=0.6, label="normative mean ± SD")]  # fmt: skip
    if not even:  # the empty cell beside the last curve holds the key
        spare = grid[nrows - 1][1]
        spare.set_visible(True)
        spare.axis("off")
        spare.legend(handles=key, loc="center", frameon=False)
    else:
        grid[nrows - 1][1].legend(handles=key, loc="upper right", bbox_to_anchor=(1.0, -0.32),
                                  ncol=3, frameon=False, fontsize=SIZE["small"])  # fmt: skip


def gait_report_pages(doc: Document, view: SessionView) -> None:
    """Both gait pages."""
    gait_pages(doc, view)
    curve_page(doc, view)
