"""Progress over visits: range of motion per joint and task across sessions of one subject."""

from __future__ import annotations

import numpy as np

from motionlab.report.model import (
    SessionView,
    grade_mark,
    is_determined,
    joint_title,
    rom_rows,
    visit_labels,
)
from motionlab.report.pdf import BAND_COLOUR, MUTED, SIDE_COLOUR, SIZE, Document
from motionlab.report.sentences import span, task_name

PLOTS_PER_ROW = 2
WEAK_ALPHA = 0.35  # a weak range's bar, paler than a determined one's


def progress_page(doc: Document, views: list[SessionView]) -> None:
    """Typical range of each joint's primary angle per task over the visits (≥ 2 sessions)."""
    if len(views) < 2:
        return
    proto = views[-1].protocol
    doc.section(
        f"Progress over {len(views)} visits ({proto.name})",
        "Typical range (bar: mean lowest to mean highest angle of the cycles) of each joint's "
        "flexion per task and visit; grey band: the protocol's normal range.",
    )
    per_visit = [{(r.task, r.joint, r.angle): r for r in rom_rows(v)} for v in views]
    keys = [k for k in per_visit[-1] if k[2] == "flexion"]
    keys = [k for k in keys if sum(k in pv for pv in per_visit) >= 2]
    if not keys:
        doc.paragraph("The visits share no joint and task with flexion results to compare.")
        return
    ncols = min(PLOTS_PER_ROW, len(keys))
    nrows = int(np.ceil(len(keys) / ncols))
    grid = doc.axes_grid(
        nrows,
        ncols,
        min(2.2 * nrows + 0.3, 7.0),
        left=0.6,
        wspace=0.8,
        hspace=0.9,
        bottom=0.55,
        top=0.35,
    )
    labels = visit_labels(views)
    for n, key in enumerate(keys):
        ax = grid[n // ncols][n % ncols]
        task, joint_name, _ = key
        joint = proto.joints.get(joint_name)
        side = joint.side if joint else ""
        normal = next((pv[key].normal for pv in per_visit if key in pv and pv[key].normal), None)
        if normal:
            ax.axhspan(normal[0], normal[1], color=BAND_COLOUR, alpha=0.45, lw=0)
        for i, pv in enumerate(per_visit):
            r = pv.get(key)
            if r is None or r.grade == "not determined":  # an undetermined range is not drawn
                continue
            ax.plot(
                [i, i],
                [r.typical_min_deg, r.typical_max_deg],
                lw=6,
                color=SIDE_COLOUR.get(side, SIDE_COLOUR[""]),
                alpha=1.0 if is_determined(r.grade) else WEAK_ALPHA,  # a weak one: paler
                solid_capstyle="butt",
            )
        ax.set_xticks(range(len(views)), labels, rotation=20, ha="right")
        ax.set_xlim(-0.6, len(views) - 0.4)
        ax.set_ylabel("flexion (°)")
        title = joint_title(joint) if joint else joint_name
        ax.set_title(f"{title}, {task_name(task)}", loc="left", size=SIZE["small"])
    for n in range(len(keys), nrows * ncols):
        grid[n // ncols][n % ncols].set_visible(False)
    rows = []
    for key in keys:
        task, joint_name, _ = key
        joint = proto.joints.get(joint_name)
        cells = [task_name(task), joint_title(joint) if joint else joint_name]
        for pv in per_visit:
            r = pv.get(key)
            if r is None or r.grade == "not determined":
                cells.append(grade_mark(r.grade) if r else "-")
            else:
                mark = grade_mark(r.grade)
                cells.append(
                    span(r.typical_min_deg, r.typical_max_deg) + (f" {mark}" if mark else "")
                )
        rows.append(cells)
    width = 0.64 / len(views)
    doc.table(
        ["Task", "Joint", *labels],
        rows,
        [0.18, 0.18] + [width] * len(views),
        align=["l", "l"] + ["r"] * len(views),
    )
    unnamed = "not recorded" in {v.subject for v in views}
    weak = any(pv[k].grade == "weak" for pv in per_visit for k in keys if k in pv)
    doc.paragraph(
        "Differences between visits smaller than the expected accuracy (see that page) may be "
        "measurement error rather than change."
        + (
            " Pale bars, '(weak)': ranges the recording determined only weakly (see each "
            "session's calibration page), not to be compared."
            if weak
            else ""
        )
        + (
            " No subject is recorded in these sessions: motionlab cannot tell that they are one "
            "person's visits (give subject: {id: ...} in the sensor map)."
            if unnamed
            else ""
        ),
        size=SIZE["small"],
        colour=MUTED,
    )
