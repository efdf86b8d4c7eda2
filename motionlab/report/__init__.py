"""The clinician report (multi-page A4 PDF) and the CSV tables of analysed sessions.

Pages, per session (modules ``pages_*``): summary with plain-language findings; data quality;
calibration quality; per joint the angle curves, cycle curves against normative bands and the
range-of-motion table; the left-right comparison for bilateral protocols; out-of-plane metrics;
the optical validation (when the session holds one); expected accuracy; methods appendix.
Several sessions of one subject add a progress page per protocol. The numbers come from the
stages' stored results (:mod:`.model`); normative data from ``motionlab/report_data``
(:mod:`.normative`).

Example::

    from motionlab.report import load_views, write_report
    views = load_views([load_session("visit1.h5"), load_session("visit2.h5")])
    write_report(views, "report.pdf", csv_dir="tables")
"""

from __future__ import annotations

import gc
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib
import pandas as pd

from motionlab.atomic import atomic_path, check_output
from motionlab.errors import InputError
from motionlab.protocol import Protocol
from motionlab.report import widths
from motionlab.report.csv import tables, write_csvs
from motionlab.report.model import SessionView, load_view
from motionlab.report.pages_gait import gait_report_pages
from motionlab.report.pages_joint import joint_pages, symmetry_page
from motionlab.report.pages_methods import accuracy_page, methods_page
from motionlab.report.pages_oop import out_of_plane_page
from motionlab.report.pages_progress import progress_page
from motionlab.report.pages_quality import calibration_page, data_quality_page
from motionlab.report.pages_summary import summary_page
from motionlab.report.pages_validation import validation_pages
from motionlab.report.pdf import RC, Document
from motionlab.session import Session

__all__ = [
    "ReportOutput",
    "SessionView",
    "build_document",
    "load_views",
    "write_report",
    "write_csvs",
]


@dataclass
class ReportOutput:
    """What :func:`write_report` wrote: the PDF, its text copy, the CSVs and each page's text."""

    pdf_path: Path
    text_path: Path
    csv_paths: list[Path] = field(default_factory=list)
    pages: list[str] = field(default_factory=list)
    sections: list[str] = field(default_factory=list)


def load_views(
    sessions: list[Session],
    protocol: Protocol | None = None,
    paths: list[Path | None] | None = None,
) -> list[SessionView]:
    """Views of analysed sessions of one subject, oldest first (see :func:`.model.load_view`)."""
    paths = paths or [None] * len(sessions)
    views = [load_view(s, protocol, p) for s, p in zip(sessions, paths, strict=True)]
    subjects = sorted({v.subject for v in views})
    if len(subjects) > 1:
        raise InputError(
            f"the sessions are of {len(subjects)} subjects ({', '.join(subjects)})",
            remedy="write one report per subject",
        )
    return sorted(views, key=lambda v: v.date)


def session_tables(
    session: Session | SessionView, protocol: Protocol | None = None
) -> dict[str, pd.DataFrame]:
    """The CSV tables of one analysed session as pandas frames, by the file name ``motionlab
    run`` gives them in ``csv/`` (``metrics.csv``: range of motion per task, joint and angle in
    degrees, with the normal range, the comparison and the grade; ``grades.csv``,
    ``quality.csv``, ``calibration.csv``, ``out_of_plane.csv``, ``<joint>_angles.csv`` and, for a
    walk, the spatio-temporal tables). A number the recording did not determine is empty, as
    in the files. ``protocol`` defaults to the calibration's."""
    view = session if isinstance(session, SessionView) else load_view(session, protocol)
    return tables(view)


def _session_pages(doc: Document, view: SessionView) -> None:
    summary_page(doc, view)
    data_quality_page(doc, view)
    calibration_page(doc, view)
    gait_report_pages(doc, view)
    joint_pages(doc, view)
    symmetry_page(doc, view)
    out_of_plane_page(doc, view)
    validation_pages(doc, view)
    accuracy_page(doc, view)
    methods_page(doc, view)


def write_report(
    views: list[SessionView],
    pdf_path: str | Path,
    csv_dir: str | Path | None = None,
    force: bool = False,
) -> ReportOutput:
    """Write the PDF (and its text as ``<pdf>.txt``) and, with ``csv_dir``, the CSV tables.

    Several views give each session's pages in date order, then a progress page per protocol
    with two or more sessions; their CSVs go to one subfolder per session.

    Python's cyclic garbage collector is paused meanwhile and run once afterwards over what was
    made (its youngest generation, which holds everything allocated while paused): the pages'
    hundred thousand objects otherwise set off a full collection of the whole process (0.3 s
    on the demo's reports, docs/performance.md); the figures, which refer to each other in
    cycles, are freed by that one collection.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        return _write_report(views, pdf_path, csv_dir, force)
    finally:
        if enabled:
            gc.enable()
            gc.collect(0)


def _write_report(
    views: list[SessionView], pdf_path: str | Path, csv_dir: str | Path | None, force: bool
) -> ReportOutput:
    if not views:
        raise InputError("no session to report on", remedy="give one or more session files")
    pdf_path = Path(pdf_path)
    text_path = pdf_path.with_suffix(".txt")
    for p in (pdf_path, text_path):
        check_output(p, force)
    with matplotlib.rc_context(RC):
        doc = build_document(views)
        csv_paths: list[Path] = []
        if csv_dir is not None:
            for i, view in enumerate(views):
                sub = Path(csv_dir)
                if len(views) > 1:
                    stem = view.path.stem if view.path else f"session{i + 1}"
                    sub = sub / f"{i + 1:02d}_{stem}"
                csv_paths += write_csvs(view, sub, force)
        with atomic_path(pdf_path, force) as tmp_pdf, atomic_path(text_path, force) as tmp_txt:
            pages = doc.save(tmp_pdf, tmp_txt)
    widths.save()  # the words measured for the first time, for the next process
    return ReportOutput(pdf_path, text_path, csv_paths, pages, list(doc.sections))


def build_document(views: list[SessionView]) -> Document:
    """All pages of the report, drawn (not yet saved)."""
    first = views[-1]
    subtitle = f"subject {first.subject}"
    doc = Document(f"motionlab report · {first.protocol.name}", subtitle)
    for view in views:
        doc.title = f"motionlab report · {view.protocol.name}"
        doc.subtitle = f"subject {view.subject} · {view.date_label}"
        _session_pages(doc, view)
    by_protocol: dict[str, list[SessionView]] = {}
    for view in views:
        by_protocol.setdefault(view.protocol.name, []).append(view)
    doc.subtitle = subtitle
    for group in by_protocol.values():
        progress_page(doc, group)
    return doc
