"""Per joint: angle-time curves, cycle-normalised mean ± SD against normative bands, the
range-of-motion table with normal ranges and flags; and the left-right comparison.

Curves are in degrees against time (s) or the cycle (0-100 %); a normative cycle band (grey) is
drawn behind a determined angle where ``report_data`` has one (a walk: its gait band), else the
protocol's normal range as a hatched band. Every
angle carries its grade: a ``not determined`` angle is not drawn (its axes say why) and its table
rows are greyed; a ``weak`` angle is drawn and labelled, its range described with the reason under
the table; neither is compared with the normal range nor flagged.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Patch

from motionlab.kinematics.joint_types import angle_columns, positive
from motionlab.report.model import (
    NOT_DETERMINED,
    SessionView,
    angle_grades,
    angle_label,
    is_determined,
    joint_title,
    joint_type_title,
    normal_range,
    rom_rows,
    symmetric_type,
    symmetry_rows,
    walking_spans,
    worst_grade,
)
from motionlab.report.normative import band_for
from motionlab.report.pdf import (
    BAND_COLOUR,
    HEADING_H,
    LONG_RECORDING_S,
    MUTED,
    NOT_DETERMINED_COLOUR,
    PAGE_W,
    SIDE_COLOUR,
    SIZE,
    Document,
    label_spans,
    overview_window,
    window_range,
)
from motionlab.report.sentences import STATUS_WORDS, span, task_name, weak_lines
from motionlab.report.widths import text_width

TASKS_PER_PAGE = 3
MIN_SPAN_DEG = 10.0


def _ylabel(joint, angle: str) -> str:
    return f"{angle.replace('_', ' ')} (°)\n{positive(joint, angle)}"


def graded_style(view: SessionView, joint, col: str) -> tuple[str, str]:
    """``(colour, title suffix)`` of an angle's curves: the side's colour, grey and
    ``' · not determined'`` for an angle the recording did not determine, ``' · weak'``."""
    grade = angle_grades(view).get(col, ("determined", ""))[0]
    if grade == NOT_DETERMINED:
        return NOT_DETERMINED_COLOUR, " · not determined"
    colour = SIDE_COLOUR.get(joint.side, SIDE_COLOUR[""])
    return colour, "" if grade == "determined" else f" · {grade}"


#: the excerpt drawn sample by sample next to the overview (s): some 9 strides of a walk
EXCERPT_S = 10.0


def is_long(view: SessionView) -> bool:
    """Whether the angles span more than :data:`~motionlab.report.pdf.LONG_RECORDING_S` (s)."""
    t = np.asarray(view.angles.get("time_s", []), dtype=float)
    return len(t) > 1 and t[-1] - t[0] > LONG_RECORDING_S


def excerpt_span(view: SessionView) -> tuple[float, float]:
    """The :data:`EXCERPT_S` (s) drawn as recorded: the middle of the longest walking span
    (a walk), else of the longest task block, else of the recording."""
    t = view.angles["time_s"]
    spans = [(float(t[0]), float(t[-1]))]
    for task, block in view.blocks().items():
        spans += walking_spans(view, task) or [block]
    a, b = max(spans[1:] or spans, key=lambda ab: ab[1] - ab[0])
    centre = 0.5 * (a + b)
    return centre - 0.5 * EXCERPT_S, centre + 0.5 * EXCERPT_S


def _blocks_and_bands(ax, view: SessionView, blocks: dict, walks: dict, col: str,
                      unit_s: float) -> None:  # fmt: skip
    """The task blocks' grey spans and each task's normal range of ``col`` on a time axis in
    units of ``unit_s`` seconds (1: s, 60: min); a walk's normal range holds while walking, not
    over a rest between its bouts (``walks``: each task's walking spans, None without)."""
    for task, (a, b) in blocks.items():
        ax.axvspan(a / unit_s, b / unit_s, color="#f0f0f0", zorder=0)
        rng = normal_range(view.protocol, task, col)
        for a0, b0 in (walks[task] or [(a, b)]) if rng is not None else []:
            ax.fill_between([a0 / unit_s, b0 / unit_s], rng[0], rng[1], color=BAND_COLOUR,
                            alpha=0.5, lw=0, zorder=1)  # fmt: skip


def _angle_title(ax, joint, angle: str, suffix: str) -> None:
    """An angle's plot title with its grade's suffix (muted when not determined)."""
    muted = suffix == " · not determined"
    ax.set_title(angle_label(joint, angle) + suffix, loc="left", size=SIZE["small"],
                 weight="bold", color=MUTED if muted else "black")  # fmt: skip


def _long_time_page(doc: Document, view: SessionView, joint) -> None:
    """The time curves of a long recording: per angle an overview in minutes (each window's
    lowest to highest angle, :func:`window_range`) and :data:`EXCERPT_S` as recorded."""
    t = np.asarray(view.angles["time_s"], dtype=float)
    minutes = t / 60.0
    window = overview_window(t[-1] - t[0])
    a, b = excerpt_span(view)
    inside = (t >= a) & (t <= b)
    blocks = view.blocks()
    walks = {task: walking_spans(view, task) for task in blocks}
    height = _time_plot_height(doc, view, joint)
    axes = doc.axes_grid(
        3, 2, height, left=0.85, bottom=0.45, hspace=0.45, wspace=0.3, top=0.45, widths=(3, 1)
    )
    for i, ((angle, col), (ax, ex)) in enumerate(zip(angle_columns(joint), axes, strict=True)):
        colour, suffix = graded_style(view, joint, col)
        _blocks_and_bands(ax, view, blocks, walks, col, 60.0)
        if suffix == " · not determined":
            _no_data(ax, "not determined by this recording: not drawn (see the calibration page)")
            _no_data(ex, "not drawn")
        else:
            centre, lo, hi = window_range(t, view.angles[col], window)
            ax.fill_between(centre / 60.0, lo, hi, color=colour, alpha=0.35, lw=0, zorder=2)
            for edge in (lo, hi):
                ax.plot(centre / 60.0, edge, color=colour, lw=0.5, zorder=2)
            ax.axvline(0.5 * (a + b) / 60.0, color=MUTED, lw=0.6, ls="--", zorder=3)
            ex.plot(t[inside], view.angles[col][inside], color=colour, lw=0.6, zorder=2)
        ax.set_ylabel(_ylabel(joint, angle))
        ax.set_xlim(minutes[0], minutes[-1])
        ex.set_xlim(a, b)
        ex.set_xticks(np.arange(np.ceil(a / 5.0) * 5.0, b, 5.0))
        ex.set_ylim(ax.get_ylim())  # the overview's scale: the excerpt's range compares
        ex.tick_params(labelleft=False)
        if i == 0:
            label_spans(ax, {task_name(k): (a0 / 60.0, b0 / 60.0)
                             for k, (a0, b0) in blocks.items()}, SIZE["small"] - 1)  # fmt: skip
        _angle_title(ax, joint, angle, suffix)
        if i == 2:
            ax.set_xlabel("time (min)")
            ex.set_xlabel("time (s)")
        else:
            ax.tick_params(labelbottom=False)
            ex.tick_params(labelbottom=False)
    # the task blocks are named on the axes: two entries, as many as a short recording's
    handles = [Patch(color=SIDE_COLOUR.get(joint.side, SIDE_COLOUR[""]), alpha=0.35,
                     label=f"{window:g}-s range")]  # fmt: skip
    if any(normal_range(view.protocol, task, col) is not None
           for task in blocks for _, col in angle_columns(joint)):  # fmt: skip
        walking = any(spans is not None for spans in walks.values())
        label = "normal range of the task" + (" (a walk: while walking)" if walking else "")
        handles.append(Patch(color=BAND_COLOUR, alpha=0.5, label=label))
    axes[0][1].legend(
        handles=handles, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=2, frameon=False
    )


def _time_page(doc: Document, view: SessionView, joint) -> None:
    if is_long(view):
        _long_time_page(doc, view, joint)
        return
    t = view.angles["time_s"]
    blocks = view.blocks()
    walks = {task: walking_spans(view, task) for task in blocks}  # None: no analysed walk
    height = _time_plot_height(doc, view, joint)
    axes = doc.axes_grid(3, 1, height, left=0.85, bottom=0.45, hspace=0.45, top=0.45)
    for i, ((angle, col), (ax,)) in enumerate(zip(angle_columns(joint), axes, strict=True)):
        colour, suffix = graded_style(view, joint, col)
        _blocks_and_bands(ax, view, blocks, walks, col, 1.0)
        if suffix == " · not determined":
            _no_data(ax, "not determined by this recording: not drawn (see the calibration page)")
        else:
            ax.plot(t, view.angles[col], color=colour, lw=0.6, zorder=2)
        ax.set_ylabel(_ylabel(joint, angle))
        ax.set_xlim(t[0], t[-1])
        if i == 0:
            label_spans(ax, {task_name(k): v for k, v in blocks.items()}, SIZE["small"] - 1)
        _angle_title(ax, joint, angle, suffix)
        if i == 2:
            ax.set_xlabel("time (s)")
        else:
            ax.tick_params(labelbottom=False)
    handles = [Patch(color="#f0f0f0", label="task block")] if blocks else []
    if any(normal_range(view.protocol, task, col) is not None
           for task in blocks for _, col in angle_columns(joint)):  # fmt: skip
        walking = any(spans is not None for spans in walks.values())
        label = "normal range of the task" + (" (a walk: while walking)" if walking else "")
        handles.append(Patch(color=BAND_COLOUR, alpha=0.5, label=label))
    if not handles:
        return
    axes[0][0].legend(
        handles=handles,
        loc="lower right",
        bbox_to_anchor=(1.0, 1.0),
        ncol=2,
        frameon=False,
    )


ROM_HEADER = ["Task", "Movement (plane)", "Typical range", "Full ROM (°)", "Cycles",
              "Normal (°)", "vs normal", "Grade"]  # fmt: skip
ROM_WIDTHS = [0.11, 0.18, 0.12, 0.09, 0.09, 0.1, 0.14, 0.17]
ROM_NOTE = (
    "Typical range: means of the lowest and highest angle of each cycle (a task without "
    "cycles: its lowest and highest angle). Full ROM: highest minus lowest angle over the "
    "whole task (a walk: over the kept strides of the joint's leg). A range is flagged when "
    "it leaves the normal range by more than 5°, or a flexion peak falls 10° short of its "
    "top; not when a walk faster than the norms' walkers (or of a speed not measured, at "
    "their cadence) takes a flexion range above it, or a slower one short of it: marked "
    "'(pace)'. Grade: whether the "
    "recording determined the angle (see the "
    "calibration page); only a determined range is compared."
)
TIME_PLOT_H = (4.2, 5.6)  # in: the time curves' least and usual height


def _rom_cells(view: SessionView, joint) -> tuple[list, list, list]:
    """The range-of-motion table's rows of ``joint``, the cells drawn red and the rows greyed."""
    rows, flagged, muted = [], [], []
    for r in rom_rows(view):
        if r.joint != joint.name:
            continue
        normal = f"{r.normal[0]:g} to {r.normal[1]:g}" if r.normal else "-"
        bad = r.flagged
        hide = r.grade == NOT_DETERMINED  # a number the recording did not determine
        muted.append(hide)
        rows.append(
            [
                task_name(r.task),
                f"{r.angle.replace('_', ' ')} ({r.plane})",
                "-" if hide else span(r.typical_min_deg, r.typical_max_deg),
                "-" if hide else f"{r.rom_deg:.0f}",
                "-" if r.repetitions is None else str(r.repetitions),
                normal,
                STATUS_WORDS.get(r.status, "-") + (" (pace)" if r.paced else "")
                if r.status
                else ("not compared" if r.normal and not is_determined(r.grade) else "-"),
                r.grade,
            ]
        )
        flagged.append([False] * 6 + [bad, False])
    return rows, flagged, muted


def _weak_note(view: SessionView, joint) -> str:
    weak = weak_lines(view, joint.name)
    if not weak:
        return ""
    return "Weak angles (shown, not compared with the normal range, not findings): " + " ".join(
        weak
    )


def _rom_height(view: SessionView, joint) -> float:
    """The height (in) of the range-of-motion table with its heading and notes."""
    weak = _weak_note(view, joint)
    return (
        HEADING_H
        + Document.table_height(ROM_HEADER, _rom_cells(view, joint)[0], ROM_WIDTHS)
        + Document.paragraph_height(ROM_NOTE, SIZE["small"])
        + (Document.paragraph_height(weak, SIZE["small"]) if weak else 0.0)
    )


def _time_plot_height(doc: Document, view: SessionView, joint) -> float:
    """The time curves' height: the usual one, less what keeps the range-of-motion table and
    its notes on the page (a long table left its note alone on the next page), not under
    :data:`TIME_PLOT_H`'s least; 0.15 in spare for the table's own look-ahead."""
    low, usual = TIME_PLOT_H
    spare = doc.room() - usual - _rom_height(view, joint) - 0.15
    return usual if spare >= 0 or usual + spare < low else usual + spare


def _rom_table(doc: Document, view: SessionView, joint) -> None:
    rows, flagged, muted = _rom_cells(view, joint)
    doc.heading("Range of motion")
    doc.table(
        ROM_HEADER,
        rows,
        ROM_WIDTHS,
        flagged,
        align=["l", "l", "r", "r", "r", "r", "r", "r"],
        muted=muted,
    )
    doc.paragraph(ROM_NOTE, size=SIZE["small"], colour=MUTED)
    weak = _weak_note(view, joint)
    if weak:
        doc.paragraph(weak, size=SIZE["small"])


def _fitted(ax: Axes, title: str, grade: str) -> str:
    """``title`` and its ``grade`` mark on one line, or the mark on a second line when the
    line would run past the axes ('sit to stand, rotation (n = 5), not determined' left the
    page from the third column)."""
    width = ax.get_position().width * PAGE_W
    one = title + grade
    if not grade or text_width(one, SIZE["small"]) <= width:
        return one
    return f"{title}{grade[0] if grade[0] == ',' else ''}\n{grade.lstrip(', ')}"


def min_span(ax: Axes, span_deg: float = MIN_SPAN_DEG) -> None:
    """Widen the y axis to at least ``span_deg`` so that small wiggles do not look large."""
    lo, hi = ax.get_ylim()
    if hi - lo < span_deg:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - 0.5 * span_deg, mid + 0.5 * span_deg)


def _no_data(ax: Axes, text: str) -> None:
    ax.text(
        0.5,
        0.5,
        text,
        transform=ax.transAxes,
        ha="center",
        va="center",
        size=SIZE["small"],
        color=MUTED,
    )


def cycle_band(view: SessionView, task: str, joint_type: str, angle: str):
    """The normative cycle band of an angle in ``task`` (``report_data``): the task's own, or for
    a walk the gait band whatever the protocol calls its walk (the ``walk`` protocol's knee was
    drawn against a hatched range while the ``knee`` protocol's ``gait`` had the curve)."""
    band = band_for(task, joint_type, angle)
    kind = next((t for t in view.protocol.tasks if t.name == task), None)
    if band is None and kind is not None and kind.is_gait:
        band = band_for("gait", joint_type, angle)
    return band


def draw_cycle(ax: Axes, view: SessionView, joint, task: str, angle: str, col: str) -> str:
    """Mean ± SD over the cycles of one angle in one task, over its normative band (a
    determined angle only: a weak one is not compared, so no normal is drawn behind it). Returns
    what normal it drew: ``band``, ``range`` (the protocol's, hatched) or ``''``."""
    m = view.metrics.joints.get(task, {}).get(col)
    pct = np.arange(101)
    colour, suffix = graded_style(view, joint, col)
    band = cycle_band(view, task, joint.type, angle)
    rng = normal_range(view.protocol, task, col)
    drawn = ""
    if suffix:  # weak or not determined: not compared with the normal
        pass
    elif band is not None:
        ax.fill_between(
            band.percent,
            band.mean - band.sd,
            band.mean + band.sd,
            color=BAND_COLOUR,
            lw=0,
            alpha=0.7,
        )
        drawn = "band"
    elif rng is not None:
        ax.axhspan(rng[0], rng[1], facecolor="none", edgecolor=BAND_COLOUR, hatch="////", lw=0)
        drawn = "range"
    if colour == NOT_DETERMINED_COLOUR:
        _no_data(ax, "not determined:\nnot drawn")
    elif m is None or m.repetitions == 0 or not np.isfinite(m.curve_mean_deg).any():
        _no_data(ax, "no cycles found")
    else:
        mean, sd = np.asarray(m.curve_mean_deg), np.asarray(m.curve_sd_deg)
        ax.fill_between(pct, mean - sd, mean + sd, color=colour, alpha=0.25, lw=0)
        ax.plot(pct, mean, color=colour, lw=1.2)
    min_span(ax)
    n = int(m.repetitions) if m is not None else 0
    title = f"{task_name(task)}, {angle.replace('_', ' ')} (n = {n})"
    ax.set_title(_fitted(ax, title, suffix.replace(" · ", ", ")), loc="left", size=SIZE["small"])
    ax.set_xlim(0, 100)
    ax.set_xlabel("cycle (%)")
    ax.set_ylabel(f"{angle.replace('_', ' ')} (°)")
    return drawn


def _has_cycles(view: SessionView, joint, task: str) -> bool:
    """Whether the metrics found repetitions of ``joint`` in ``task`` (a calibration movement
    measured as one block has none, and no cycle page)."""
    per_col = view.metrics.joints.get(task, {})
    return any(per_col[col].repetitions for _, col in angle_columns(joint) if col in per_col)


def _cycle_tasks(view: SessionView, joint) -> list[str]:
    """The tasks with a cycle page of ``joint``, in time order."""
    return [task for task in view.tasks() if _has_cycles(view, joint, task)]


def _cycle_pages(doc: Document, view: SessionView, joint) -> None:
    tasks = _cycle_tasks(view, joint)
    for k in range(0, len(tasks), TASKS_PER_PAGE):
        chunk = tasks[k : k + TASKS_PER_PAGE]
        doc.section(
            f"{joint_title(joint)}: cycles against normal",
            "Each task's repetitions (gait: the kept strides, heel strike to heel strike) "
            "resampled to 0-100 % of the cycle: mean (line) ± 1 SD (shaded). Grey band: normal "
            "mean ± 1 SD; hatched: the protocol's normal range where no normal curve is on "
            "file; behind a determined angle only (a weak one is not compared with normal).",
        )
        grid = doc.axes_grid(3, len(chunk), 7.2, left=0.55, wspace=0.7, hspace=0.75, top=0.4)
        drawn = {
            draw_cycle(grid[i][j], view, joint, task, angle, col)
            for i, (angle, col) in enumerate(angle_columns(joint))
            for j, task in enumerate(chunk)
        }
        colour = SIDE_COLOUR.get(joint.side, SIDE_COLOUR[""])
        normals = {  # the key names what the page draws (it listed both, drawing one)
            "band": Patch(color=BAND_COLOUR, alpha=0.7, label="normal mean ± SD"),
            "range": Patch(
                facecolor="none", edgecolor=BAND_COLOUR, hatch="////", label="normal range"
            ),  # fmt: skip
        }
        doc.fig.legend(
            handles=[Patch(color=colour, alpha=0.4, label=f"{joint_title(joint)} mean ± SD")]
            + [patch for kind, patch in normals.items() if kind in drawn],
            loc="upper left",
            bbox_to_anchor=(0.07, 1 - doc.y / 11.69),
            ncol=3,
            frameon=False,
        )
        doc.space(0.4)
        sources = {
            band.source
            for task in chunk
            for angle, col in angle_columns(joint)
            if (band := cycle_band(view, task, joint.type, angle)) is not None
            and graded_style(view, joint, col)[1] == ""
        }
        for src in sorted(sources):
            doc.paragraph(f"Normal curve: {src}", size=SIZE["small"], colour=MUTED)
        if view.protocol.source:
            doc.paragraph(
                f"Normal ranges: {' '.join(view.protocol.source.split())}",
                size=SIZE["small"],
                colour=MUTED,
            )


def _determined(view: SessionView, col: str) -> bool:
    """Whether the angle column ``col`` is not ``not determined`` (weak counts: it is drawn)."""
    return angle_grades(view).get(col, ("determined", ""))[0] != NOT_DETERMINED


def _none_determined(view: SessionView, joint) -> bool:
    """Whether the recording determined none of ``joint``'s angles (nothing to draw)."""
    return not any(_determined(view, col) for _, col in angle_columns(joint))


def _time_intro(view: SessionView, joint) -> str:
    """The joint's section text: what its time curves show."""
    head = f"{joint_title(joint)} angles over the recording in the three planes (degrees; signs "
    if not is_long(view):
        return head + "as in the legend of each axis), and the range of motion per task."
    t = view.angles["time_s"]
    a, b = excerpt_span(view)
    return (
        head + f"as in the legend of each axis). Left: the whole {(t[-1] - t[0]) / 60.0:.0f} "
        f"minutes, each {overview_window(t[-1] - t[0]):g}-s window's lowest to highest angle; "
        f"right: {EXCERPT_S:g} s as recorded ({a:.0f}-{b:.0f} s, the dashed line)"
        + ("; the typical cycle on the next pages" if _cycle_tasks(view, joint) else "")
        + ". Then the range of motion per task."
    )


def joint_pages(doc: Document, view: SessionView) -> None:
    """The time and cycle pages of every joint of the protocol; a joint whose angles are all
    not determined gets its range-of-motion table (every row saying so) and no empty plots."""
    for joint in view.joints():
        if _none_determined(view, joint):
            doc.section(
                joint_title(joint),
                f"No angle of the {joint_title(joint).lower()} was determined by this recording: "
                "none is drawn (why, and what to record next time: the calibration page).",
            )
            _rom_table(doc, view, joint)
            continue
        doc.section(joint_title(joint), _time_intro(view, joint))
        _time_page(doc, view, joint)
        _rom_table(doc, view, joint)
        _cycle_pages(doc, view, joint)


def symmetry_page(doc: Document, view: SessionView) -> None:
    """Left-right comparison of the cycle curves and the symmetry index, for bilateral joints."""
    rows = symmetry_rows(view)
    if not rows:
        return
    pairs = {}
    for j in view.joints():
        if symmetric_type(j.type):
            pairs.setdefault(j.type, {})[j.side] = j
    for jtype, sides in pairs.items():
        if "r" not in sides or "l" not in sides:
            continue
        pairs = zip(angle_columns(sides["r"]), angle_columns(sides["l"]), strict=True)
        if not any(_determined(view, r) and _determined(view, l) for (_, r), (_, l) in pairs):
            continue  # no angle determined on both sides: nothing to compare
        doc.section(
            f"{joint_type_title(jtype)}: left-right comparison",
            "Mean cycle curves of both sides. Symmetry index SI = 100 × (right − left) / mean of "
            "the two ranges (Robinson et al. 1987); |SI| above 10 % is flagged; it is not given "
            "when the mean range is under 10° (a ratio of two small ranges is mostly noise).",
        )
        tasks = view.tasks()[:TASKS_PER_PAGE]
        grid = doc.axes_grid(3, len(tasks), 5.6, left=0.55, wspace=0.7, hspace=0.7, top=0.4)
        for i, (angle, _) in enumerate(angle_columns(sides["r"])):
            for j, task in enumerate(tasks):
                ax = grid[i][j]
                hidden = []
                for side in ("r", "l"):
                    col = angle_columns(sides[side])[i][1]
                    m = view.metrics.joints[task].get(col)
                    if angle_grades(view).get(col, ("determined", ""))[0] == NOT_DETERMINED:
                        hidden.append({"r": "right", "l": "left"}[side])
                        continue
                    if m is None or m.repetitions == 0:
                        continue
                    mean, sd = np.asarray(m.curve_mean_deg), np.asarray(m.curve_sd_deg)
                    ax.fill_between(
                        np.arange(101),
                        mean - sd,
                        mean + sd,
                        color=SIDE_COLOUR[side],
                        alpha=0.15,
                        lw=0,
                    )
                    ax.plot(np.arange(101), mean, color=SIDE_COLOUR[side], lw=1.1)
                if hidden:
                    _no_data(ax, f"{' and '.join(hidden)}: not determined")
                min_span(ax)
                grade = worst_grade(
                    [angle_grades(view).get(angle_columns(sides[x])[i][1], ("determined", ""))
                     for x in ("r", "l")]
                )[0]  # fmt: skip
                mark = "" if is_determined(grade) else f" ({grade})"
                title = f"{task_name(task)}, {angle.replace('_', ' ')}"
                ax.set_title(_fitted(ax, title, mark), loc="left", size=SIZE["small"])
                ax.set_xlim(0, 100)
                ax.set_xlabel("cycle (%)")
                ax.set_ylabel(f"{angle.replace('_', ' ')} (°)")
        doc.fig.legend(
            handles=[
                Patch(color=SIDE_COLOUR["r"], label="right"),
                Patch(color=SIDE_COLOUR["l"], label="left"),
            ],
            loc="upper left",
            bbox_to_anchor=(0.07, 1 - doc.y / 11.69),
            ncol=2,
            frameon=False,
        )
        doc.space(0.4)
        table, flagged, muted = [], [], []
        for r in rows:
            if r.joint_type != jtype:
                continue
            muted.append(r.grade == NOT_DETERMINED)
            si = r.symmetry_index_pct
            table.append(
                [
                    task_name(r.task),
                    f"{r.angle.replace('_', ' ')} ({r.plane})",
                    "-" if r.grade == NOT_DETERMINED else f"{r.right_rom_deg:.0f}",
                    "-" if r.grade == NOT_DETERMINED else f"{r.left_rom_deg:.0f}",
                    f"{0.0 if round(si) == 0 else si:+.0f}"
                    if np.isfinite(si)
                    else ("n/a (range < 10°)" if is_determined(r.grade) else "not compared"),
                    r.grade,
                ]
            )
            flagged.append([False] * 4 + [r.flag, False])
        doc.table(
            ["Task", "Movement (plane)", "Right range (°)", "Left range (°)", "SI (%)", "Grade"],
            table,
            [0.17, 0.26, 0.13, 0.13, 0.15, 0.16],
            flagged,
            align=["l", "l", "r", "r", "r", "r"],
            muted=muted,
        )
