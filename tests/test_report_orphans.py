"""Report layout: no page left holding one orphan list or note that belonged on the page before."""

import matplotlib
import numpy as np
from test_report import _angle, _graded_view

from motionlab.report.pdf import RC, Document, layout_problems, page_text
from motionlab.results import TaskBlock
from motionlab.session import SensorStream


def test_the_excluded_list_stays_with_the_recording_chart():
    """Real walks and trunk trials (5 and 6 sensors) had a page 'Data quality (continued)'
    holding one line: 'metrics use the task blocks only'. The chart above it gives way (a little
    lower) or takes the list with it onto the next page: whatever the content above it."""
    from motionlab.report.pages_quality import data_quality_page

    view = _graded_view()
    alone = []
    for n in range(3, 9):
        for flagged in range(n + 1):  # each flagged sensor: one more line above the chart
            view.session.sensors = {
                f"s{k}": SensorStream(f"s{k}", time=np.linspace(0.0, 50.0, 501)) for k in range(n)
            }
            for k in range(flagged):
                view.session.sensors[f"s{k}"].qc = {"flags": {"dropped_samples": True}}
            with matplotlib.rc_context(RC):
                doc = Document("motionlab report · test", "subject X")
                data_quality_page(doc, view)
                texts = [page_text(f) for f in doc.pages]
                if n == 5 and flagged == 5:
                    assert [p for f in doc.pages for p in layout_problems(f)] == []
            (page,) = [t for t in texts if "Excluded from the analysis, and why" in t]
            if "The recording, sensor by sensor" not in page:
                alone.append((n, flagged))
    assert alone == []


def test_heading_keeps_a_short_list_when_it_fits():
    """A heading asked for 1.2 in below it: a one-line list that fitted in 0.6 in went alone onto
    a new page."""
    with matplotlib.rc_context(RC):
        doc = Document("t")
        doc.section("S")
        items = ["one short line"]
        doc.space(doc.room() - 0.8)
        doc.heading("A short list", follows=doc.bullets_height(items))
        doc.bullets(items)
        assert len(doc.pages) == 1
        doc.space(doc.room() - 0.8)
        doc.heading("A longer list")  # default: 1.2 in kept with it
        assert len(doc.pages) == 2


def _three_task_joint_pages(view) -> list[str]:
    """The joint pages' texts of ``view`` with a squat and a sit-to-stand added to its gait
    (three tasks, as the demo knee), checked for layout problems."""
    from motionlab.report.pages_joint import joint_pages

    gait = view.metrics.joints["gait"]
    view.metrics.blocks |= {"squat": TaskBlock(20.0, 30.0), "sit_to_stand": TaskBlock(32.0, 45.0)}
    for task in ("squat", "sit_to_stand"):
        view.metrics.joints[task] = {c: _angle(0.0, 90.0, 5) for c in gait}
    with matplotlib.rc_context(RC):
        doc = Document("motionlab report · test", "subject X")
        joint_pages(doc, view)
        assert [p for f in doc.pages for p in layout_problems(f)] == []
        return [page_text(f) for f in doc.pages]


def test_a_long_range_of_motion_table_keeps_its_note_on_its_page():
    """The demo knee (three tasks, nine rows) had 'Right knee (continued)' pages holding only the
    table's note: the time curves now leave room for it."""
    texts = _three_task_joint_pages(_graded_view(graded=False))  # all determined, as the demo
    assert not any("knee (continued)" in t for t in texts)
    tables = [t for t in texts if "Range of motion" in t]
    assert len(tables) == 2
    assert all("Typical range: means of the lowest" in t for t in tables)


def test_a_grade_mark_that_would_leave_the_page_goes_under_its_cycle_title():
    """'sit to stand, rotation (n = 5), not determined', the third column's title, ran off the
    page's right edge."""
    # right knee rotation not determined, adduction weak
    text = "\n".join(_three_task_joint_pages(_graded_view()))
    assert "sit to stand, rotation (n = 5),\nnot determined" in text
