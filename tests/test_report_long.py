"""Long recordings: the time pages as an overview of windows and an excerpt (``pages_joint``,
``pages_oop``)."""

import matplotlib
import numpy as np
import pytest

from motionlab.protocol import load_protocol
from motionlab.report.model import SessionView
from motionlab.report.pages_joint import EXCERPT_S, joint_pages
from motionlab.report.pdf import (
    OVERVIEW_WINDOWS,
    RC,
    Document,
    layout_problems,
    overview_window,
    page_text,
    thin_curves,
    window_range,
)
from motionlab.results import Metrics, TaskBlock
from motionlab.session import Session

RATE = 100.0


def _knee_view(duration_s: float) -> SessionView:
    """A knee session of ``duration_s`` at 100 Hz: a gait block from 5 s to 5 s before the end,
    flexion strides of 1.1 s (0-60°) whose range shrinks by 10° over the recording, a 3-s gap."""
    t = np.arange(int(duration_s * RATE)) / RATE
    fade = 10.0 * t / duration_s
    flexion = (30.0 - 0.5 * fade) + (30.0 - 0.5 * fade) * np.sin(2 * np.pi * t / 1.1)
    flexion[(t > 100.0) & (t < 103.0)] = np.nan
    angles = {"time_s": t}
    for side in "rl":
        angles[f"knee_{side}_flexion_deg"] = flexion
        angles[f"knee_{side}_adduction_deg"] = 2.0 * np.sin(2 * np.pi * t / 1.1)
        angles[f"knee_{side}_rotation_deg"] = 5.0 * np.cos(2 * np.pi * t / 1.1)
    metrics = Metrics("knee", blocks={"gait": TaskBlock(5.0, duration_s - 5.0)})
    return SessionView(Session(), load_protocol("knee"), None, angles, metrics)


def _time_page(view: SessionView):
    with matplotlib.rc_context(RC):
        doc = Document("motionlab report · test", "subject X")
        joint_pages(doc, view)
        fig = doc.pages[0]
        thin_curves(fig)  # as the PDF draws it
        return fig, page_text(fig), layout_problems(fig)


def _points(fig) -> int:
    """The points the page's axes draw: every line's and every filled area's vertices."""
    lines = sum(len(line.get_xdata()) for ax in fig.axes for line in ax.lines)
    areas = sum(len(p.vertices) for ax in fig.axes for c in ax.collections for p in c.get_paths())
    return lines + areas


def test_window_range_is_each_windows_lowest_and_highest_and_a_gap_stays_a_gap():
    rng = np.random.default_rng(3)
    t = np.arange(3000) / RATE  # 30 s
    y = rng.normal(size=len(t))
    y[1000:1600] = np.nan  # windows 2 and 3 of 5 s... 10-16 s: the window 10-15 s is all gap
    centre, lo, hi = window_range(t, y, 5.0)
    np.testing.assert_allclose(centre, [2.5, 7.5, 12.5, 17.5, 22.5, 27.5])
    for k in range(6):
        part = y[(t >= 5.0 * k) & (t < 5.0 * (k + 1))]
        if np.isfinite(part).any():
            assert lo[k] == np.nanmin(part) and hi[k] == np.nanmax(part)
        else:
            assert np.isnan(lo[k]) and np.isnan(hi[k])
    assert np.isnan(lo[2]) and np.isfinite(lo[3])


@pytest.mark.parametrize("minutes, window", [(6, 5.0), (10, 5.0), (30, 15.0), (60, 30.0)])
def test_the_overview_window_cuts_the_recording_into_at_most_its_windows(minutes, window):
    assert overview_window(60.0 * minutes) == window
    assert 60.0 * minutes / window <= OVERVIEW_WINDOWS


def test_a_long_recording_is_drawn_as_windows_and_an_excerpt_with_bounded_points():
    counts: dict[int, int] = {}
    for minutes in (6, 60):
        fig, text, problems = _time_page(_knee_view(60.0 * minutes))
        assert problems == []
        assert f"the whole {minutes} minutes" in text and "time (min)" in text
        overview, excerpt = fig.axes[0], fig.axes[1]
        assert overview.get_xlim()[1] == pytest.approx(minutes, rel=1e-3)  # in minutes
        lo, hi = excerpt.get_xlim()
        assert hi - lo == pytest.approx(EXCERPT_S)
        assert excerpt.get_ylim() == overview.get_ylim()  # one scale: the ranges compare
        # the shrinking range shows: each window's highest flexion, 60° less the fade
        line = overview.lines[1]
        top, at = line.get_ydata(), 60.0 * line.get_xdata()
        seen = np.isfinite(top)
        assert seen.sum() >= len(top) - 1  # the gap's window only (100-103 s: a 5-s window)
        np.testing.assert_allclose(top[seen], 60.0 - 10.0 * at[seen] / (60.0 * minutes), atol=0.3)
        assert len(top) <= OVERVIEW_WINDOWS
        counts[minutes] = _points(fig)
    # 10 × the samples, about the same ink: a few thousand points (the 60-min series: 360 000)
    assert counts[6] <= 4000 and counts[60] <= 4000


def test_a_short_recording_keeps_its_curves_against_seconds():
    fig, text, problems = _time_page(_knee_view(240.0))
    assert problems == [] and "time (s)" in text and "time (min)" not in text
    assert len(fig.axes) == 3  # one column: no excerpt
    assert fig.axes[0].get_xlim() == (0.0, 239.99)


@pytest.mark.parametrize("block_s, unit", [(400.0, "min"), (60.0, "s")])
def test_a_long_tasks_trunk_angles_are_windows_in_minutes(block_s, unit):
    from dataclasses import replace

    from motionlab.report.pages_oop import out_of_plane_page
    from motionlab.results import TrunkAngleStats, TrunkCompensation

    view = _knee_view(block_s + 10.0)
    t = np.arange(int(block_s * RATE)) / RATE
    lean = np.column_stack([8 * np.sin(t), 3 * np.cos(t), 0.01 * t])
    stats = TrunkAngleStats(10.0, 0.0, 10.0, 50.0, 5.0)
    trunk = TrunkCompensation({a: stats for a in ("flexion", "lateral_bending",
                                                  "axial_rotation")}, True, lean)  # fmt: skip
    view.metrics = replace(view.metrics, trunk_compensation={"gait": trunk})
    with matplotlib.rc_context(RC):
        doc = Document("motionlab report · test", "subject X")
        out_of_plane_page(doc, view)
        (ax,) = [a for f in doc.pages for a in f.axes if a.get_ylabel() == "trunk angle (°)"]
        problems = [p for f in doc.pages for p in layout_problems(f)]
    assert problems == [] and ax.get_xlabel() == f"time in task ({unit})"
    sizes = {len(line.get_xdata()) for line in ax.lines}
    if unit == "min":  # each angle's lowest and highest per window: 80 windows of 5 s
        assert len(ax.lines) == 6 and sizes == {80} and len(ax.collections) == 3
        assert np.nanmax(ax.lines[1].get_ydata()) == pytest.approx(8.0, abs=0.01)
    else:  # as recorded
        assert len(ax.lines) == 3 and sizes == {len(t)}
