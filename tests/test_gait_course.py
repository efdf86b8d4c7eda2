"""The course of a long walk part by part (``kinematics.gait_course``): a walker who slows
down is shown slowing down, with an interval that holds the truth, and a short walk has none."""

from __future__ import annotations

import numpy as np
import pytest

from motionlab.kinematics.gait_course import MAX_PARTS, change_text, walk_course, walk_courses
from motionlab.kinematics.spatiotemporal import summary
from motionlab.results import Gait, StrideTable, TaskBlock


def _strides(minutes: float, slowing: float, seed: int = 0) -> StrideTable:
    """Strides of both legs over ``minutes`` whose stride time grows by ``slowing`` s per minute
    from 1.0 s (SD 0.02 s stride to stride); every tenth stride rejected (a turn)."""
    rng = np.random.default_rng(seed)
    starts, times = [], []
    t = 0.0
    while t < 60.0 * minutes:
        stride = 1.0 + slowing * t / 60.0 + rng.normal(0.0, 0.02)
        starts.append(t)
        times.append(stride)
        t += stride / 2  # the other leg's stride starts half a stride later
    n = len(starts)
    stride_time = np.array(times)
    kept = np.arange(n) % 10 != 0
    stance = np.full(n, 60.0) + rng.normal(0.0, 1.0, n)
    nan = np.full(n, np.nan)  # no segment lengths: lengths and speed not measured
    return StrideTable(
        start_s=np.array(starts),
        kept=kept,
        stride_time_s=stride_time,
        step_time_s=stride_time / 2,
        stance_time_s=stride_time * stance / 100,
        swing_time_s=stride_time * (1 - stance / 100),
        stance_pct=stance,
        swing_pct=100 - stance,
        double_support_pct=stance - 50,
        cadence_steps_per_min=120.0 / stride_time,
        step_length_m=nan,
        stride_length_m=nan,
        walking_speed_m_s=nan,
        side=np.array(["r", "l"] * (n // 2) + ["r"] * (n % 2)),
        reason=np.where(kept, "", "turn"),
    )


def _gait(strides: StrideTable, *blocks: tuple[float, float]) -> Gait:
    """A gait analysis of ``strides`` with walking tasks over ``blocks`` (s)."""
    tasks = {f"walk{k or ''}": TaskBlock(a, b) for k, (a, b) in enumerate(blocks)}
    return Gait("ok", tasks=tasks, strides=strides, summary=summary(strides.frame()))


def test_a_walker_who_slows_is_shown_slowing_within_the_interval():
    course = walk_course(_strides(6.0, 0.02))
    assert course is not None and len(course.parts) == 5  # equal parts of at least a minute
    assert all(100 <= p.strides <= 130 for p in course.parts)
    means = [p.mean["stride_time_s"] for p in course.parts]
    assert np.all(np.diff(means) > 0)
    # the parts' centres lie 4/5 of the strides' span apart: 0.02 s/min × 4.8 min
    change, ci = course.change["stride_time_s"], course.change_ci["stride_time_s"]
    assert abs(change - 0.096) < ci and 0.0 < ci < 0.02 and not course.withheld
    assert course.change["cadence_steps_per_min"] < -8.0
    assert np.isnan(course.parts[0].mean["walking_speed_m_s"])  # not measured, not invented
    assert change_text(course, "walking_speed_m_s") == "-"
    steady = walk_course(_strides(6.0, 0.0, seed=1))
    assert abs(steady.change["stride_time_s"]) < steady.change_ci["stride_time_s"]


def test_parts_are_equal_at_least_a_minute_at_most_ten_and_inside_the_walk():
    strides = _strides(31.0, 0.0)
    course = walk_course(strides)
    assert len(course.parts) == MAX_PARTS
    widths = {round(p.end_s - p.start_s, 6) for p in course.parts}
    assert len(widths) == 1 and widths.pop() >= 60.0
    kept = strides.start_s[strides.kept]
    assert course.parts[0].start_s == kept[0] and course.parts[-1].end_s == kept[-1]
    assert sum(p.strides for p in course.parts) == len(kept)  # every kept stride, once
    rows = course.rows()
    assert set(rows["part"].iloc[-4:]) == {"change"} and rows["ci95"].iloc[-4:].notna().any()
    assert list(rows["unit"].iloc[:4]) == ["steps/min", "s", "m/s", "%"]
    assert str(rows["strides"].dtype) == "Int64"
    assert course.parts[0].label == "0:01–3:06"  # m:ss of the recording, from the first kept


def test_a_pause_at_the_end_withholds_the_change_and_says_why():
    strides = _strides(6.0, 0.0)
    late = strides.start_s > 280.0
    strides.kept[late & (strides.start_s < 359.0)] = False  # stood until the last strides
    course = walk_course(strides)
    assert "in the last part" in course.withheld and np.isnan(course.change["stride_time_s"])
    assert change_text(course, "stride_time_s") == "-"


def test_only_walks_of_three_minutes_each_get_a_course_and_a_rest_splits_them():
    strides = _strides(10.0, 0.0)
    for blocks, tasks in ((((0.0, 600.0),), ["walk"]),  # one 10-min walk
                          (((0.0, 170.0),), []),  # under 3 min
                          (((0.0, 200.0), (400.0, 600.0)), ["walk", "walk1"])):  # fmt: skip
        courses = walk_courses(_gait(strides, *blocks))
        assert [c.task for c in courses] == tasks
        for c, (a, b) in zip(courses, blocks, strict=False):
            assert a <= c.parts[0].start_s and c.parts[-1].end_s <= b  # no part across a rest
    assert walk_courses(None) == []
    n = len(strides.kept)
    assert strides.kept.sum() == n - (n + 9) // 10  # every tenth rejected: the table as it was


@pytest.mark.parametrize("minutes", [0.0, 1.0, 1.9])
def test_under_two_minutes_of_strides_has_no_course(minutes):
    strides = _strides(minutes, 0.0) if minutes else StrideTable(np.empty(0), np.empty(0, bool))
    assert walk_course(strides) is None
    assert walk_course(None) is None


def test_a_long_walk_gets_its_course_table_and_csv_a_short_one_does_not():
    from motionlab.protocol import load_protocol
    from motionlab.report.console import _gait_line
    from motionlab.report.csv import gait_frames
    from motionlab.report.model import SessionView
    from motionlab.session import Session

    for minutes, expected in ((6.0, True), (2.0, False)):
        strides = _strides(minutes, 0.02)
        session = Session()
        session.results.gait = _gait(strides, (0.0, 60.0 * minutes))
        view = SessionView(session, load_protocol("walk"), None, {}, None)
        frames = gait_frames(view)
        assert ("spatiotemporal_course.csv" in frames) is expected
        line = _gait_line(view)  # the run's summary line says it too
        assert ("walk, first to last 1.2 min: cadence -" in line) is expected
        if expected:
            course = frames["spatiotemporal_course.csv"]
            change = course[(course["part"] == "change")].set_index("parameter")
            assert change.loc["stride_time_s", "mean"] == pytest.approx(0.096, abs=0.02)
