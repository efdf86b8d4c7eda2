"""Page 1: who, when, what was measured with which sensors, the findings in plain language (from
determined numbers only), then one line per joint on what the recording could not determine and
how to fix it (:func:`~motionlab.report.sentences.missing_lines`)."""

from __future__ import annotations

import datetime as _dt

from motionlab import __version__
from motionlab.kinematics.angle_filter import metrics_cutoff
from motionlab.report.model import SessionView, joint_title, segment_title
from motionlab.report.pdf import MUTED, SIZE, Document
from motionlab.report.sentences import (
    PACE_SOURCE,
    findings,
    missing_lines,
    pace_note,
    tasks_analysed,
    zero_words,
)
from motionlab.segments import sensor_for_segment


def _software(view: SessionView) -> str:
    versions = sorted({p.get("software", "") for p in view.session.provenance if p.get("software")})
    used = ", ".join(versions) or "unknown"
    return f"{used} (report: motionlab {__version__})"


def summary_page(doc: Document, view: SessionView) -> None:
    """Identity table, sensor placements and the findings."""
    proto = view.protocol
    doc.section("Summary", proto.title or proto.name)
    tasks = tasks_analysed(view)
    joints = ", ".join(joint_title(j) for j in view.joints())
    identity = [
        ["Subject", view.subject],
        ["Session date", view.date],
        ["Protocol", f"{proto.name}: {proto.title}" if proto.title else proto.name],
        ["Joints", joints],
        ["Tasks analysed", tasks or "none found"],
        ["Software", _software(view)],
        ["Report written", _dt.date.today().isoformat()],
    ]
    if view.session.metadata.get("simulated"):
        identity.append(["Data", "simulated recording (motionlab simulate), not a real subject"])
    doc.table(["", ""], identity, [0.2, 0.8], align=["l", "l"], size=SIZE["body"])

    doc.heading("Findings")
    items = findings(view)
    doc.bullets(items)
    tasks = (view.session.results.gait.tasks or {}) if view.session.results.gait else {}
    paced = any(pace_note(view, task)[0] in items for task in tasks)
    angles = view.session.results.angles
    fc = metrics_cutoff(angles.lowpass_hz if angles is not None else 0.0)
    doc.paragraph(
        "Ranges are the typical lowest and highest angle of the repetitions (means of the "
        f"per-cycle extremes of the angle low-passed at {fc:g} Hz), in degrees; a range counts as "
        "outside normal when it leaves the "
        "protocol's normal range by more than 5°, or a flexion peak falls 10° short of its top. "
        "Normal ranges are approximate, for orientation, "
        "not diagnostic limits. Only numbers the recording determined are findings."
        + zero_words(view)
        + (f" Pace: {PACE_SOURCE}." if paced else ""),
        size=SIZE["small"],
        colour=MUTED,
    )
    missing = missing_lines(view)
    if missing:
        doc.heading("Weak or not determined in this recording")
        doc.bullets(missing)
        doc.paragraph(
            "These angles are not findings: weak ones are shown with their grade on the joint "
            "pages, undetermined ones not at all. The reasons in full are on the calibration "
            "page.",
            size=SIZE["small"],
            colour=MUTED,
        )

    doc.heading("Sensors and placements")
    rows = []
    for seg, spec in proto.segments.items():
        label = sensor_for_segment(view.session, seg)
        sensor = view.session.sensors[label] if label else None
        name = segment_title(proto, seg)
        ident = f"{sensor.label}\n{sensor.serial}" if sensor and sensor.serial else "-"
        if sensor and not sensor.serial:
            ident = sensor.label
        rows.append([name, ident, spec.placement or "-"])
    doc.table(["Segment", "Sensor", "Placement"], rows, [0.13, 0.23, 0.64], align=["l"] * 3)
