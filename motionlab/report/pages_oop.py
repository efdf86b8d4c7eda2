"""Out-of-plane metrics: cross-talk, knee varus thrust and stance rotation, the lumbar
out-of-plane offset and trunk compensation, each with what it means in one sentence.

Each number carries the grade of its angle: ``(weak)`` after it, or ``not determined`` in
place of a clinical metric (varus thrust, stance rotation, trunk compensation, offset) whose
plane the recording did not determine (its per-stride dots are not drawn); only a determined
number is flagged; cross-talk rows name the grade of the other angle."""

from __future__ import annotations

import numpy as np
from matplotlib.patches import Patch

from motionlab.report.model import (
    NOT_DETERMINED,
    THORAX,
    SessionView,
    angle_grade,
    grade_rows,
    in_order,
    joint_title,
    segment_grade,
    thrust_above,
    trunk_above,
    worst_grade,
)
from motionlab.report.pdf import (
    LONG_RECORDING_S,
    MUTED,
    SIDE_COLOUR,
    SIZE,
    Document,
    overview_window,
    window_range,
)
from motionlab.report.sentences import MEANING, task_name


def _items(view: SessionView, data: dict) -> list[tuple[str, str, dict]]:
    """``(block, joint, entry)`` of a ``{block: {joint: entry}}`` tree, blocks in time (then
    protocol step) order and joints in protocol order."""
    blocks = list(view.blocks()) + [s.name for s in view.protocol.calibration]
    joints = list(view.protocol.joints)
    return [
        (block, name, data[block][name])
        for block in in_order(data, blocks)
        for name in in_order(data[block], joints)
    ]


def _f(x: float, spec: str = ".1f") -> str:
    """``x`` formatted, ``-`` when missing; never ``-0.0``."""
    if x is None or not np.isfinite(x):
        return "-"
    text = format(x, spec)
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def _mean_sd(mean: float, sd: float) -> str:
    """``'6.8 ± 0.2'``; ``'not computed'`` without a mean (a stride the angles do not cover
    made it NaN: '- ± -' told a reader nothing)."""
    if mean is None or not np.isfinite(mean):
        return "not computed"
    return f"{_f(mean)} ± {_f(sd)}"


def _graded(text: str, grade: str) -> str:
    """A number with its grade: as is, ``'<text> (weak)'``, or ``'not determined'``."""
    if grade == NOT_DETERMINED:
        return "not determined"
    return text if grade == "determined" else f"{text} ({grade})"


def _cross_talk(doc: Document, view: SessionView) -> None:
    data = view.metrics.cross_talk or {}
    if not data:
        return
    doc.heading("Cross-talk during single-plane movements")
    doc.paragraph(
        MEANING["cross_talk"] + " Red: the other angle's range above 20 % of the moving angle's.",
        colour=MUTED,
    )
    rows, flagged, muted = [], [], []
    for block, name, m in _items(view, data):
        joint = view.protocol.joints[name]
        for angle, e in m.off_axis.items():
            grade = angle_grade(view, name, angle)[0]
            muted.append(grade == NOT_DETERMINED)
            on_grade = angle_grade(view, name, m.on_axis)[0]
            on_text = f"{m.on_axis.replace('_', ' ')} {_f(m.on_axis_rom_deg, '.0f')}"
            rows.append(
                [
                    task_name(block),
                    joint_title(joint),
                    on_text if on_grade == "determined" else f"{on_text} ({on_grade})",
                    angle.replace("_", " ") + ("" if grade == "determined" else f" ({grade})"),
                    _f(e.rom_deg),
                    _f(e.ratio_pct),  # one decimal: the red is above 20 %, and 19.6 read 20
                    _f(e.nominal_rom_deg),
                    _f(e.change_pct, "+.0f"),
                ]
            )
            flagged.append([False] * 5 + [grade == "determined" and e.ratio_pct > 20] + [False] * 2)
    doc.table(
        [
            "Movement",
            "Joint",
            "Moving angle, range (°)",
            "Other angle",
            "Range (°)",
            "% of moving",
            "Without calibration (°)",
            "Change (%)",
        ],
        rows,
        [0.17, 0.12, 0.17, 0.13, 0.09, 0.09, 0.13, 0.1],
        flagged,
        align=["l", "l", "l", "l", "r", "r", "r", "r"],
        muted=muted,
    )


def _gait(doc: Document, view: SessionView) -> None:
    data = view.metrics.gait or {}
    if not data:
        return
    doc.heading("Knee varus thrust and rotation in stance")
    doc.paragraph(MEANING["varus_thrust"] + " " + MEANING["stance_rotation"], colour=MUTED)
    rows, flagged, strides = [], [], []
    for task, name, g in _items(view, data):
        joint = view.protocol.joints[name]
        varus = angle_grade(view, name, "adduction")[0]
        rotation = angle_grade(view, name, "rotation")[0]
        rows.append(
            [
                task_name(task),
                joint_title(joint),
                str(g.strides),
                _graded(_mean_sd(g.varus_thrust_mean_deg, g.varus_thrust_sd_deg), varus),
                _graded(_f(g.varus_thrust_above_pct, ".0f"), varus),
                _graded(
                    _mean_sd(g.stance_rotation_range_mean_deg, g.stance_rotation_range_sd_deg),
                    rotation,
                ),
            ]
        )
        above = varus == "determined" and thrust_above(view, name, g)
        flagged.append([False] * 3 + [above] + [False] * 2)
        label = f"{joint_title(joint)}, {task_name(task)}"
        if varus != "determined":
            label += f" ({varus})"
        strides.append((label, joint.side if varus != NOT_DETERMINED else None, g))
    doc.table(
        [
            "Task",
            "Knee",
            "Strides",
            "Varus thrust (°)",
            "Strides above limit (%)",
            "Stance rotation range (°)",
        ],
        rows,
        [0.15, 0.15, 0.1, 0.2, 0.2, 0.2],
        flagged,
        align=["l", "l", "r", "r", "r", "r"],
    )
    if all(side is None for _, side, _ in strides):  # nothing to draw: no empty chart
        return
    ax = doc.axes_grid(1, 1, 2.2, left=1.9, bottom=0.5, top=0.3)[0][0]
    for k, (_, side, g) in enumerate(strides):
        if side is None:  # a plane the recording did not determine is not drawn
            continue
        x = np.asarray(g.varus_thrust_deg, float)
        ax.plot(
            x,
            np.full(len(x), k) + np.linspace(-0.15, 0.15, len(x)),
            "o",
            ms=3,
            color=SIDE_COLOUR.get(side, SIDE_COLOUR[""]),
        )
    limit = max(g.threshold_deg for _, _, g in strides)
    ax.axvline(limit, color="#b2182b", lw=0.8, ls="--")
    ax.set_yticks(range(len(strides)), [s[0] for s in strides])
    ax.set_ylim(len(strides) - 0.4, -0.6)  # first row on top, as in the table
    ax.set_xlabel("varus thrust per stride (°)")
    ax.set_title(
        f"Each stride's varus thrust; dashed: the protocol's limit ({limit:g}°)", loc="left"
    )


def _offset(doc: Document, view: SessionView) -> None:
    data = view.metrics.out_of_plane_offset or {}
    if not data:
        return
    doc.heading("Lumbar out-of-plane offset")
    doc.paragraph(MEANING["out_of_plane_offset"], colour=MUTED)
    rows, flagged = [], []
    for task, name, o in _items(view, data):
        graded = [(r.grade, "") for r in grade_rows(view) if r.joint == name]
        grade = worst_grade(graded)[0]
        rows.append(
            [
                task_name(task),
                "-".join(o.axes),
                _graded(_f(o.peak_deg), grade),
                _graded(_f(o.mean_deg), grade),
                _graded(f"{_f(o.above_pct, '.0f')} (limit {o.threshold_deg:g}°)", grade),
            ]
        )
        flagged.append([False] * 4 + [grade == "determined" and o.above_pct > 0])
    doc.table(
        ["Task", "Axes compared", "Peak (°)", "Mean (°)", "Time above limit (%)"],
        rows,
        [0.25, 0.15, 0.15, 0.15, 0.3],
        flagged,
        align=["l", "l", "r", "r", "r"],
    )


TRUNK_CURVES = (("forward lean", "#2166ac"), ("side lean", "#1a9850"), ("twist", "#d95f02"))


def _trunk(doc: Document, view: SessionView) -> None:
    data = view.metrics.trunk_compensation or {}
    if not data:
        return
    doc.heading("Trunk compensation")
    doc.paragraph(MEANING["trunk_compensation"], colour=MUTED)
    rows, flagged = [], []
    grade = segment_grade(view, THORAX)[0]
    for task in in_order(data, list(view.blocks())):
        t = data[task]
        for angle in ("flexion", "lateral_bending", "axial_rotation"):
            a = t.per_angle[angle]
            rows.append(
                [
                    task_name(task),
                    {
                        "flexion": "forward lean (forward +)",
                        "lateral_bending": "side lean (right +)",
                        "axial_rotation": "twist (left +)",
                    }[angle],
                    _graded(f"{_f(a.min_deg)} to {_f(a.max_deg)}", grade),
                    _graded(_f(a.peak_abs_deg), grade),
                    _graded(f"{_f(a.above_pct, '.0f')} (limit {a.threshold_deg:g}°)", grade),
                ]
            )
            flagged.append([False] * 3 + [grade == "determined" and trunk_above(a)] * 2)
    doc.table(
        ["Task", "Trunk movement", "Range (°)", "Peak (°)", "Time above limit (%)"],
        rows,
        [0.22, 0.24, 0.18, 0.12, 0.24],
        flagged,
        align=["l", "l", "r", "r", "r"],
    )
    tasks = [k for k in in_order(data, list(view.blocks())) if len(np.asarray(data[k].angles_deg))]
    if not tasks or grade == NOT_DETERMINED:  # an angle not determined is not drawn
        return
    grid = doc.axes_grid(1, len(tasks), 2.3, left=0.55, wspace=0.6, bottom=0.5, top=0.3)[0]
    rate = 1.0 / np.median(np.diff(view.angles["time_s"]))
    handles = []
    for ax, task in zip(grid, tasks, strict=True):
        ang = np.asarray(data[task].angles_deg)
        t = np.arange(len(ang)) / rate
        long = len(t) > 1 and t[-1] > LONG_RECORDING_S  # per window: its lowest to highest
        window = overview_window(t[-1])
        handles = []
        for k, (name, colour) in enumerate(TRUNK_CURVES):
            if long:
                centre, lo, hi = window_range(t, ang[:, k], window)
                ax.fill_between(centre / 60.0, lo, hi, color=colour, alpha=0.25, lw=0)
                for edge in (lo, hi):
                    ax.plot(centre / 60.0, edge, lw=0.6, color=colour)
                handles.append(Patch(color=colour, alpha=0.5, label=name))
            else:
                handles += ax.plot(t, ang[:, k], lw=0.8, color=colour, label=name)
        title = task_name(task) + (f" (each {window:g} s: lowest to highest)" if long else "")
        ax.set_title(title, loc="left", size=SIZE["small"])
        ax.set_xlabel(f"time in task ({'min' if long else 's'})")
        ax.set_ylabel("trunk angle (°)")
    doc.fig.legend(
        handles=handles,
        loc="upper left",
        ncol=3,
        frameon=False,
        bbox_to_anchor=(0.07, 1 - doc.y / 11.69),
    )
    doc.space(0.35)


def out_of_plane_page(doc: Document, view: SessionView) -> None:
    """One section with every out-of-plane metric the protocol computed (none: skipped)."""
    m = view.metrics
    if not any((m.cross_talk, m.gait, m.out_of_plane_offset, m.trunk_compensation)):
        return
    doc.section(
        "Out-of-plane metrics",
        "Movements outside the main plane of a joint: measurement cross-talk, and clinical "
        "signs such as knee thrust and trunk compensation.",
    )
    _gait(doc, view)
    _trunk(doc, view)
    _offset(doc, view)
    _cross_talk(doc, view)
