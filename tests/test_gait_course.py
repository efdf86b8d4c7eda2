"""The course of a long walk part by part (``kinematics.gait_course``): a walker who slows
down is shown slowing down, with an interval that holds the truth, and a short walk has none."""

from __future__ import annotations

import numpy as np
import pytest

from motionlab.kinematics.gait_course import MAX_PARTS, MIN_SPAN_S, walk_course
from motionlab.results import StrideTable


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


def test_a_walker_who_slows_is_shown_slowing_within_the_interval():
    course = walk_course(_strides(6.0, 0.02))
    assert course is not None and len(course.parts) == 6  # whole minutes
    assert all(90 <= p.strides <= 110 for p in course.parts[:-1])
    means = [p.mean["stride_time_s"] for p in course.parts]
    assert np.all(np.diff(means) > 0)
    # minute 1 centred on 0.5 min, minute 6 on 5.5 min: 5 min × 0.02 s/min
    change, ci = course.change["stride_time_s"], course.change_ci["stride_time_s"]
    assert abs(change - 0.10) < ci and 0.0 < ci < 0.02
    assert course.change["cadence_steps_per_min"] < -8.0
    assert np.isnan(course.parts[0].mean["walking_speed_m_s"])  # not measured, not invented
    assert np.isnan(course.change["walking_speed_m_s"])
    steady = walk_course(_strides(6.0, 0.0, seed=1))
    assert abs(steady.change["stride_time_s"]) < steady.change_ci["stride_time_s"]


def test_parts_are_whole_minutes_and_at_most_ten():
    course = walk_course(_strides(31.0, 0.0))
    assert len(course.parts) <= MAX_PARTS
    widths = {round(p.end_s - p.start_s) for p in course.parts[:-1]}
    assert widths == {240}  # 31 min in parts of 4 min
    rows = course.rows()
    assert set(rows["part"].iloc[-4:]) == {"change"} and rows["ci95"].iloc[-4:].notna().any()
    assert list(rows["unit"].iloc[:4]) == ["steps/min", "s", "m/s", "%"]


@pytest.mark.parametrize("minutes", [0.0, 1.0, MIN_SPAN_S / 60.0 - 0.1])
def test_a_short_walk_has_no_course(minutes):
    strides = _strides(minutes, 0.0) if minutes else StrideTable(np.empty(0), np.empty(0, bool))
    assert walk_course(strides) is None
    assert walk_course(None) is None


def test_a_long_walk_gets_its_course_table_and_csv_a_short_one_does_not():
    from motionlab.kinematics.spatiotemporal import summary
    from motionlab.protocol import load_protocol
    from motionlab.report.console import _gait_line
    from motionlab.report.csv import gait_frames
    from motionlab.report.model import SessionView
    from motionlab.results import Gait
    from motionlab.session import Session

    for minutes, expected in ((6.0, True), (2.0, False)):
        strides = _strides(minutes, 0.02)
        session = Session()
        session.results.gait = Gait("ok", strides=strides, summary=summary(strides.frame()))
        view = SessionView(session, load_protocol("walk"), None, {}, None)
        frames = gait_frames(view)
        assert ("spatiotemporal_course.csv" in frames) is expected
        line = _gait_line(view)  # the run's summary line says it too
        assert ("first to last 1 min of the walk: cadence -" in line) is expected
        if expected:
            course = frames["spatiotemporal_course.csv"]
            change = course[(course["part"] == "change")].set_index("parameter")
            assert change.loc["stride_time_s", "mean"] == pytest.approx(0.10, abs=0.02)
