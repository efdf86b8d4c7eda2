"""Optical validation pages (when the session holds ``results.validation``): the error
tables, and the overlay, Bland-Altman, sync and alignment figures of
:mod:`motionlab.validation.figures`, placed on the A4 pages."""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.kinematics.joint_types import angle_columns
from motionlab.report.model import NOT_DETERMINED, SessionView, angle_grades, in_order, joint_title
from motionlab.report.pdf import MUTED, SIZE, Document
from motionlab.results import AngleAgreement, OrientationErrors, Validation


def _f(x: Any, spec: str = ".2f") -> str:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return "-"
    return format(x, spec) if np.isfinite(x) else "-"


#: deg: a bias past this (and twice the RMSE without it) is called a difference of zeros
BIAS_ZERO_DEG = 2.0


def zero_offsets(angles: dict[str, AngleAgreement]) -> list[str]:
    """The angles (words) whose bias passes :data:`BIAS_ZERO_DEG` and twice their RMSE without
    it: mostly where the two systems put 0° (a simulated walk's optical hip read 6° flexed in
    the stand: 'RMSE 6.1°' beside the expected ±2°, 0.9° without the bias)."""
    return [col.removesuffix("_deg").replace("_", " ") for col, v in angles.items()
            if not v.withheld
            and abs(v.bias_deg) > max(BIAS_ZERO_DEG, 2 * v.rmse_centred_deg)]  # fmt: skip


def _angle_table(doc: Document, view: SessionView, angles: dict[str, AngleAgreement]) -> None:
    rows, muted = [], []
    grades = angle_grades(view)
    order = [col for j in view.joints() for _, col in angle_columns(j)]
    for col, v in ((c, angles[c]) for c in in_order(angles, order)):
        grade = grades.get(col, ("determined", ""))[0]
        muted.append(grade == NOT_DETERMINED or bool(v.withheld))
        lo, hi = (list(v.loa_deg) + [np.nan, np.nan])[:2]
        rows.append(
            [
                col.removesuffix("_deg").replace("_", " "),
                _f(v.rmse_deg, ".1f"),
                _f(v.bias_deg, "+.1f"),
                f"{_f(lo, '+.1f')} to {_f(hi, '+.1f')}" if np.isfinite([lo, hi]).all() else "-",
                _f(v.rmse_centred_deg, ".1f"),
                _f(v.max_abs_deg, ".1f"),
                _f(v.r, ".3f"),
                _f(v.cmc, ".3f"),
                grade if not v.withheld else "not stated",
            ]
        )
    if not rows:
        return
    doc.heading("Joint angles: IMU against optical")
    doc.table(
        [
            "Angle",
            "RMSE (°)",
            "Bias (°)",
            "95 % limits of agreement (°)",
            "RMSE without bias (°)",
            "Max |error| (°)",
            "r",
            "CMC",
            "Grade",
        ],
        rows,
        [0.18, 0.08, 0.08, 0.15, 0.11, 0.1, 0.07, 0.07, 0.16],
        align=["l"] + ["r"] * 8,
        muted=muted,
    )
    offset = zero_offsets(angles)
    doc.paragraph(
        "Bias: mean IMU minus optical; limits of agreement: bias ± 1.96 SD of the difference "
        "(Bland & Altman); CMC: coefficient of multiple correlation of the two curves (1 = same "
        "shape). Grade: whether the recording determined the angle (calibration page)."
        + (
            f" A bias over twice the RMSE without bias ({', '.join(offset)}) is mostly where the "
            "two systems put 0° (the optical model's segment axes from its markers, the IMU's "
            "from the calibration pose), not an error over the movement: the RMSE without bias "
            "is the one to read against the expected accuracy."
            if offset
            else ""
        ),
        size=SIZE["small"],
        colour=MUTED,
    )
    _not_stated(doc, {c: v.withheld for c, v in angles.items() if v.withheld})


def _not_stated(doc: Document, why: dict[str, str]) -> None:
    """One line per reason the validation could not state an agreement, naming what it left
    out (``why``: ``{angle column or sensor: reason}``)."""
    by_reason: dict[str, list[str]] = {}
    for name, reason in why.items():
        by_reason.setdefault(reason, []).append(name.removesuffix("_deg").replace("_", " "))
    if by_reason:
        doc.bullets(
            [f"Not stated ({', '.join(names)}): {reason}." for reason, names in by_reason.items()]
        )


def _orientation_table(doc: Document, view: SessionView, orientation: OrientationErrors) -> None:
    rows = []
    errors = orientation.sensors
    for label, v in ((k, errors[k]) for k in in_order(errors, list(view.session.sensors))):
        if v.total_rmse_deg is None:  # none compared, or not stated (said under the table)
            continue
        rows.append(
            [
                label,
                _f(v.total_rmse_deg, ".1f"),
                _f(v.heading_rmse_deg, ".1f"),
                _f(v.inclination_rmse_deg, ".1f"),
                _f(v.median_deg, ".1f"),
                _f(v.iqr_deg, ".1f"),
                _f(v.p95_deg, ".1f"),
            ]
        )
    if rows:
        doc.heading("Sensor orientations: IMU against optical")
        doc.table(
            [
                "Sensor",
                "Total RMSE (°)",
                "Heading RMSE (°)",
                "Inclination RMSE (°)",
                "Median (°)",
                "IQR (°)",
                "95th pct (°)",
            ],
            rows,
            [0.2, 0.14, 0.14, 0.16, 0.12, 0.12, 0.12],
        )
    _not_stated(doc, {k: v.withheld for k, v in errors.items() if v.withheld})


def _sync_alignment(doc: Document, val: Validation) -> None:
    sync, al = val.sync, val.alignment
    rows = [
        ["Clock offset", f"{_f(sync.time_offset_s, '.4f')} s"],
        ["Clock drift", sync.drift_words()],
        [
            "Windows agreeing with the clock model",
            f"{round(sync.inlier_ratio * sync.n_windows)} of {sync.n_windows}"
            if sync.n_windows and np.isfinite(sync.inlier_ratio)
            else "- (no window model: one lag over the whole recording)",
        ],
        [
            "Clock standard error at the centre; at the ends, graded",
            f"{_f(1e3 * sync.standard_error_s, '.2f')} ms; "
            f"{_f(1e3 * sync.ends_standard_error_s, '.2f')} ms: {sync.grade or '-'}",
        ]
        if sync.ends_standard_error_s is not None
        else [  # a file written before the grade was of the ends
            "Clock offset standard error, grade",
            f"{_f(1e3 * sync.standard_error_s, '.2f')} ms, {sync.grade or '-'}",
        ],
        ["Reference", str(val.reference.kind or "markers")],
        ["Spatial alignment mode", str(al.mode if al is not None else val.mode)],
        [
            "Optical lab to earth rotation",
            f"{_f(al.lab_to_earth.angle_deg if al is not None else None, '.1f')}°",
        ],
    ]
    for label, e in (al.sensor_to_cluster if al is not None else {}).items():
        rows.append([f"Sensor {label} to its marker cluster", f"{_f(e.angle_deg, '.1f')}°"])
    doc.heading("Synchronisation and alignment")
    doc.table(["", ""], rows, [0.55, 0.3], align=["l", "r"])
    if sync.ends_standard_error_s is None:  # a file written before the grade was of the ends
        return
    doc.paragraph(
        "Grade of the sync: good when the clock's standard error at the recording's ends is "
        "within a tenth of an IMU sample interval, fair within half of one, else poor.",
        size=SIZE["small"],
        colour=MUTED,
    )


def _figure_pages(doc: Document, view: SessionView, val: Validation) -> None:
    """Overlays, Bland-Altman plots (flexion of each joint), sync and alignment figures."""
    from motionlab.validation import figures

    angles = val.angles.columns if val.angles is not None else {}
    cols = [col for j in view.joints() for _, col in angle_columns(j) if col in angles]
    if cols:
        doc.section(
            "Validation: angle curves",
            "Joint angles from the sensors (blue) over those from the cameras (black), with each "
            'angle\'s RMSE and correlation r ("not stated" where the table below says why).',
            figure=figures.angle_overlay(val, cols),
        )
        doc.place_figure(min(9.4, 1.5 * len(cols) + 0.6))
    for joint in view.joints():
        col = angle_columns(joint)[0][1]
        if col not in angles or angles[col].withheld:  # no statistics to draw
            continue
        doc.section(
            f"Validation: {joint_title(joint).lower()} flexion, Bland-Altman",
            "Each sample's difference (sensors minus cameras) against the mean of the two: a "
            "level cloud means a constant bias, a slope an error that grows with the angle.",
            figure=figures.bland_altman(val, col),
        )
        doc.place_figure(4.2)
        _angle_table(doc, view, {c: angles[c] for _, c in angle_columns(joint) if c in angles})
    sync = val.sync
    if len(np.asarray(sync.window_time_s)):
        doc.section(
            "Validation: time synchronisation",
            "The camera clock against the sensor clock: each window's lag (from the "
            "cross-correlation of angular speed) minus the clock model: the fitted offset, and "
            + (
                "the drift, held at 0 (not determined, not corrected)."
                if sync.drift_grade == "not determined"
                else "the fitted drift."
            ),
            figure=figures.sync_figure(val),
        )
        doc.place_figure(3.6)
        _sync_alignment(doc, val)
    labels = list(val.orientation.sensors)
    if labels:
        doc.section(
            "Validation: spatial alignment",
            "Orientation error of each sensor against its marker cluster after the alignment "
            "(total, heading and inclination, degrees).",
            figure=figures.alignment_figure(val),
        )
        doc.place_figure(min(9.4, 1.6 * len(labels) + 0.6))


def validation_pages(doc: Document, view: SessionView) -> None:
    """Tables and figures of the optical validation; nothing when there is none."""
    val = view.session.results.validation
    if val is None:
        return
    doc.section(
        "Validation against optical motion capture",
        f"The same movements measured by the cameras (marker set '{val.marker_set or '?'}'), "
        "synchronised and aligned with the sensors, then compared.",
    )
    _sync_alignment(doc, val)
    _orientation_table(doc, view, val.orientation)
    _angle_table(doc, view, val.angles.columns if val.angles is not None else {})
    notes = val.notes
    if notes:
        doc.heading("Notes")
        doc.bullets([str(n) for n in notes], size=SIZE["small"])
    _figure_pages(doc, view, val)
