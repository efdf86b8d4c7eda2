"""Study outputs: every session's metrics in one table, the failures, and a PDF report.

- ``study_metrics.csv``: ``subject, visit``, then the columns of the sessions' metric tables
  (``PipelineResult.metrics`` of :func:`motionlab.pipeline.run_pipeline`: ``block, joint, angle,
  column, metric, value, unit, grade``, the normal range of the row's angle in its task
  ``normal_min_deg, normal_max_deg`` and ``vs_normal`` as the session's ``metrics.csv`` gives
  them, and a ``note``: why the angle is weak, not determined or not measured), one row per
  session and joint metric; a joint of the protocol with no sensor in a session keeps its rows
  there, empty, graded ``not measured`` (``not measured: no pelvis sensor``); sessions in
  manifest order, rows in each session's order, fields copied as text — so the file has the
  same bytes whichever machines ran the sessions.
- ``study_gait.csv``: ``subject, visit``, then the columns of the walks' gait summaries (the
  sessions' ``spatiotemporal_summary.csv``: ``parameter, side, unit, mean, sd, ..., count_n,
  count_of, note``), one row per walk session and parameter, copied as text: a number a session
  withheld stays an empty cell with its ``note``; only the header without a walk.
- ``study_failures.csv``: ``subject, visit, kind, attempts, error`` (a one-line error each).
- ``study_report.pdf``: counts, a table of the ranges of motion across sessions (only the ranges
  each session determined: the others are counted and left out, as from every plot), failures; the
  distribution across subjects of each angle's range of motion per task and joint (boxes, one
  dot per subject: its mean over visits); per subject, the change over visits of the primary
  angle's range of motion (flexion), with the median across subjects.

All four are written atomically and replaced on every run (failed sessions drop out of the
metric and gait tables until they succeed).
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from motionlab import __version__
from motionlab.atomic import atomic_path
from motionlab.batch.manifest import Manifest
from motionlab.batch.state import GAIT, METRICS
from motionlab.kinematics.joint_types import JOINT_TYPES
from motionlab.protocol import load_protocol

METRICS_CSV = "study_metrics.csv"
GAIT_CSV = "study_gait.csv"
FAILURES_CSV = "study_failures.csv"
REPORT_PDF = "study_report.pdf"
MAIN_METRIC = "rom_deg"
_A4 = (8.27, 11.69)
_PANELS = (3, 2)


def write_study_outputs(outdir: Path, manifest: Manifest, outcomes: list) -> dict[str, Path]:
    """Write the four study files into ``outdir``; ``outcomes`` in manifest order."""
    paths = {name: outdir / name for name in (METRICS_CSV, GAIT_CSV, FAILURES_CSV, REPORT_PDF)}
    main = write_metrics(outdir, manifest, outcomes, paths[METRICS_CSV])
    _write_gathered(paths[GAIT_CSV], _finished_tables(outdir, manifest, outcomes, GAIT))
    write_failures(outcomes, paths[FAILURES_CSV])
    write_report(manifest, outcomes, main, paths[REPORT_PDF])
    return paths


def _read_table(path: Path) -> tuple[list[str], list[list[str]]]:
    """Header and rows of a CSV file, fields as text."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return (rows[0], rows[1:]) if rows else ([], [])


def _rom_rows(subject: str, visit: str, head: list[str], rows: list[list[str]]) -> list[tuple]:
    """The scalar ``rom_deg`` rows as ``(subject, visit, block, joint, angle, value, grade)``;
    ``grade`` empty in a table written before it had the column."""
    need = ("block", "joint", "angle", "metric", "value")
    if not set(need) <= set(head):
        return []
    k = {c: head.index(c) for c in head}
    return [
        (
            subject,
            visit,
            r[k["block"]],
            r[k["joint"]],
            r[k["angle"]],
            float(r[k["value"]] or "nan"),  # empty: a range its session did not determine
            r[k["grade"]] if "grade" in k else "",
        )  # fmt: skip
        for r in rows
        if r[k["metric"]] == MAIN_METRIC and ("percent" not in k or r[k["percent"]] == "")
    ]


def _finished_tables(outdir: Path, manifest: Manifest, outcomes: list, name: str) -> list:
    """``[(session, header, rows)]`` of table ``name`` of every finished session that has one."""
    return [
        (spec, *_read_table(outdir / spec.folder / name))
        for spec, o in zip(manifest.sessions, outcomes, strict=True)
        if o.status in ("done", "skipped") and (outdir / spec.folder / name).is_file()
    ]


def _write_gathered(path: Path, tables: list) -> None:
    """The sessions' tables under one header (``subject, visit`` and every column of any),
    fields copied as text; a column a session lacks is empty."""
    columns: list[str] = []
    for _, head, _ in tables:
        columns += [c for c in head if c not in columns]
    with atomic_path(path, force=True) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f, lineterminator="\n")
        out.writerow(["subject", "visit", *columns])
        for spec, head, rows in tables:
            pick = [head.index(c) if c in head else None for c in columns]
            out.writerows(
                [spec.subject, spec.visit, *(r[j] if j is not None else "" for j in pick)]
                for r in rows
            )


def write_metrics(outdir: Path, manifest: Manifest, outcomes: list, path: Path) -> pd.DataFrame:
    """Concatenate the finished sessions' metric tables; return their ROM rows for the report.

    The ROM rows are the scalar ``rom_deg`` rows: ``subject, visit, block, joint, angle, value,
    grade``; a range its session did not determine (``weak``, ``not determined``, ``not
    measured``) has its value NaN: the report's statistics and plots leave it out and count it.
    """
    tables = _finished_tables(outdir, manifest, outcomes, METRICS)
    _write_gathered(path, tables)
    main: list[tuple] = []
    for spec, head, rows in tables:
        main += _rom_rows(spec.subject, spec.visit, head, rows)
    main = pd.DataFrame(
        main, columns=["subject", "visit", "block", "joint", "angle", "value", "grade"]
    )
    main.loc[~main["grade"].isin(("", "determined")), "value"] = np.nan
    return main


def write_failures(outcomes: list, path: Path) -> None:
    """One row per failed session: subject, visit, kind, attempts, one-line error."""
    with atomic_path(path, force=True) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f, lineterminator="\n")
        out.writerow(["subject", "visit", "kind", "attempts", "error"])
        for o in outcomes:
            if o.status == "failed":
                out.writerow([o.subject, o.visit, o.kind, o.attempts, o.error])


# ------------------------------------------------------------------------------ the PDF report


def primary_angle(joint: str, angles: list[str] | None = None) -> str:
    """The first angle of a joint: ``knee_r`` → ``flexion`` (the joint-type table); a generic
    joint (``hinge3``, ``shoulder``) → the first of ``angles`` (its angles in column order)."""
    for jt in JOINT_TYPES.values():
        if jt.clinical and jt.angle_names and (joint == jt.name or joint.startswith(jt.name + "_")):
            return jt.angle_names[0]
    return angles[0] if angles else "flexion"


def _pages(groups: list, title: str) -> Iterator[tuple[Figure, list]]:
    """Figures of up to six panels: yields ``(figure, [(group, axes), ...])``."""
    rows, cols = _PANELS
    for start in range(0, len(groups), rows * cols):
        fig = Figure(figsize=_A4)
        fig.suptitle(title, fontsize=13)
        chunk = groups[start : start + rows * cols]
        axes = [fig.add_subplot(rows, cols, k + 1) for k in range(len(chunk))]
        fig.subplots_adjust(hspace=0.45, wspace=0.3, top=0.92, bottom=0.06)
        yield fig, list(zip(chunk, axes, strict=True))


def range_summary(values: pd.Series) -> tuple[str, int, int]:
    """``(median [q1, q3], n, left out)`` of the ranges (deg) the sessions determined: the
    summary text (a dash where no session determined it), how many sessions it is of, and how
    many were left out (NaN: weak, not determined, or not measured: no sensor)."""
    n, left = int(values.notna().sum()), int(values.isna().sum())
    if not n:
        return f"{'—':>7} {'':16}", 0, left
    q1, med, q3 = np.nanpercentile(values, [25, 50, 75])
    return f"{med:7.1f} [{q1:6.1f}, {q3:6.1f}]", n, left


#: what the summary page's "left out" counts
RANGE_LEGEND = (
    "left out: the sessions where the angle was weak, not determined or not measured (no "
    "sensor); each one's reason is in study_metrics.csv (note)"
)
#: up to this many subjects, the change-over-visits panels name each subject's line
LEGEND_SUBJECTS = 8
#: rows of the summary page's range table (the rest: study_metrics.csv)
SUMMARY_ROWS = 28


def range_table(main: pd.DataFrame) -> list[str]:
    """The summary page's range table, one monospace line each: a header, a row per block, joint
    and angle (columns as wide as their longest name) and, past :data:`SUMMARY_ROWS`, a line
    saying how many more rows ``study_metrics.csv`` holds."""
    stats = list(main.groupby(["block", "joint", "angle"], sort=False)["value"])
    heads = ("task", "joint", "angle")
    w = [max([len(h)] + [len(k[i]) for k, _ in stats]) for i, h in enumerate(heads)]
    head = (f"{'task':<{w[0]}} {'joint':<{w[1]}} {'angle':<{w[2]}} {'median':>7} "
            f"{'[quartiles]':^16}  {'n':>3}  {'left out':>8}")  # fmt: skip
    lines = [head]
    for (block, joint, angle), v in stats[:SUMMARY_ROWS]:
        text, n, left = range_summary(v)
        lines.append(f"{block:<{w[0]}} {joint:<{w[1]}} {angle:<{w[2]}} {text}  {n:>3}  {left:>8}")
    if len(stats) > SUMMARY_ROWS:
        lines.append(f"… and {len(stats) - SUMMARY_ROWS} more in study_metrics.csv")
    return lines


def _summary_page(manifest: Manifest, outcomes: list, main: pd.DataFrame) -> Figure:
    fig = Figure(figsize=_A4)
    protocol = load_protocol(manifest.protocol)
    counts = {s: sum(o.status == s for o in outcomes) for s in ("done", "skipped", "failed")}
    subjects = list(dict.fromkeys(s.subject for s in manifest.sessions))
    visits = list(dict.fromkeys(s.visit for s in manifest.sessions))
    lines = [
        f"protocol {protocol.name} ({manifest.protocol.name}) — motionlab {__version__}",
        f"{len(outcomes)} sessions of {len(subjects)} subjects; visits: {', '.join(visits)}",
        f"processed now {counts['done']}, up to date (skipped) {counts['skipped']}, "
        f"failed {counts['failed']}",
    ]
    fig.text(0.06, 0.95, f"Study report: {manifest.path.name}", fontsize=15, weight="bold")
    for k, text in enumerate(lines):
        fig.text(0.06, 0.92 - 0.022 * k, text, fontsize=9)
    y = 0.84
    if not main.empty:
        fig.text(
            0.06,
            y,
            "Range of motion across sessions (deg): median [quartiles], n",
            fontsize=11,
            weight="bold",
        )
        lines = range_table(main)
        size = 8 if max(map(len, lines)) <= 110 else 8 * 110 / max(map(len, lines))
        for text in lines:
            y -= 0.018
            fig.text(0.08, y, text, fontsize=size, family="monospace")
        y -= 0.022
        fig.text(0.08, y, RANGE_LEGEND, fontsize=7, wrap=True)
        y -= 0.03
    failed = [o for o in outcomes if o.status == "failed"]
    if failed:
        fig.text(
            0.06,
            y,
            f"Failed sessions ({len(failed)}; all in study_failures.csv)",
            fontsize=11,
            weight="bold",
        )
        for o in failed[: max(0, int((y - 0.05) / 0.017))]:
            y -= 0.017
            text = f"{o.subject}/{o.visit}: {o.error}"
            fig.text(0.08, y, text[:118] + ("…" if len(text) > 118 else ""), fontsize=7)
    return fig


def _distributions(pdf: PdfPages, main: pd.DataFrame) -> None:
    """One box per angle of the subjects' ranges of motion (each the mean over its visits)."""
    groups = list(main.groupby(["block", "joint"], sort=False))
    rng = np.random.default_rng(0)
    title = "Range of motion across subjects (each dot: a subject's mean over visits)"
    for fig, panels in _pages(groups, title):
        for ((block, joint), g), ax in panels:
            per_subject = g.groupby(["angle", "subject"], sort=False)["value"].mean()
            angles = list(dict.fromkeys(g["angle"]))
            values = [per_subject[a].dropna().to_numpy() for a in angles]
            ax.boxplot(values, showfliers=False)
            labels = [f"{a}\nn={len(v)}" for a, v in zip(angles, values, strict=True)]
            ax.set_xticks(range(1, len(angles) + 1), labels)
            for k, v in enumerate(values):
                ax.plot(k + 1 + rng.uniform(-0.15, 0.15, len(v)), v, ".", ms=3, alpha=0.5)
            ax.set_title(f"{block} — {joint}", fontsize=10)
            ax.set_ylabel("ROM (deg)")
            ax.tick_params(labelsize=8)
        pdf.savefig(fig)


def _changes(pdf: PdfPages, main: pd.DataFrame, visits: list[str]) -> None:
    first = {j: primary_angle(j, list(dict.fromkeys(g["angle"]))) for j, g in main.groupby("joint")}
    primary = main[[a == first[j] for j, a in zip(main["joint"], main["angle"], strict=True)]]
    groups = list(primary.groupby(["block", "joint"], sort=False))
    x_of = {v: k for k, v in enumerate(visits)}
    for fig, panels in _pages(groups, "Change over visits, per subject"):
        for ((block, joint), g), ax in panels:
            subjects = list(g.groupby("subject", sort=False))
            for subject, s in subjects:
                ax.plot([x_of[v] for v in s["visit"]], s["value"], "o-", lw=0.8, ms=3, alpha=0.6,
                        label=subject if len(subjects) <= LEGEND_SUBJECTS else None)  # fmt: skip
            n = g.groupby("visit", sort=False)["value"].count().reindex(visits, fill_value=0)
            median = g.groupby("visit", sort=False)["value"].median()[n[n >= 2].index]
            if len(median):  # of two subjects or more: one subject's value is no median
                ax.plot([x_of[v] for v in median.index], median.to_numpy(), "k-", lw=2.5,
                        marker="_", ms=12, label="median (visits of 2+ subjects)")  # fmt: skip
            if ax.get_legend_handles_labels()[1]:
                ax.legend(fontsize=7)
            labels = [f"{v}\nn={n[v]}" for v in visits]
            ax.set_xticks(range(len(visits)), labels, fontsize=8, rotation=30, ha="right")
            ax.set_title(f"{block} — {joint}: {first[joint]} ROM", fontsize=10)
            ax.set_ylabel("ROM (deg)")
        pdf.savefig(fig)


def write_report(manifest: Manifest, outcomes: list, main: pd.DataFrame, path: Path) -> None:
    """The study PDF: summary, ROM distributions, per-subject change over visits."""
    visits = list(dict.fromkeys(s.visit for s in manifest.sessions))
    metadata = {
        "Title": f"Study report {manifest.path.name}",
        "Creator": f"motionlab {__version__}",
    }
    with atomic_path(path, force=True) as tmp, PdfPages(tmp, metadata=metadata) as pdf:
        pdf.savefig(_summary_page(manifest, outcomes, main))
        if not main.empty:
            _distributions(pdf, main)
            if len(visits) > 1:
                _changes(pdf, main, visits)
