"""Rests that tie two 6-D headings again (:func:`motionlab.segments.heading_anchors`), and the
grade of a joint whose anchors show its headings drifting apart fast (:func:`motionlab.segments.
grades.hold_graded`).

The lumbar protocol's axial-rotation task holds the trunk turned ±35° for 2 s at a time: still,
upright, so a rest in every way but the turn, which 6-D orientations cannot tell from a drift of
the two headings. With the ``harsh`` preset's gyroscopes (2°/s biases, 0.1-0.35°/s about the
vertical left after the fusion) a neutral rest 40 s after the last anchor lay 9-20° off it and
was refused, while holds the drift had brought near the old track were taken: lumbar axial
rotation 21-27° RMS off the truth, graded determined (``bench/real_world.py --protocols lumbar
--preset harsh --duration 200``, seeds 0 and 3). The estimators now find those rests on the rate
less its bias (:func:`motionlab.fusion.rest.fusion_rest`) and the headings no longer drift; the
harsh session here is fused as before, with rests on the raw rate, to keep a fast drift to grade.
"""

import numpy as np
import pytest
from conftest import SHARED, needs_shared

from motionlab import stages
from motionlab.fusion import rest as fusion_rest
from motionlab.io.clock import mark_shared_clock
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.report.model import SessionView
from motionlab.report.sentences import cause_and_remedy
from motionlab.results import JointGrades
from motionlab.segments import POSE_SCATTER_DEG, drift_beyond_anchors, grades, heading
from motionlab.session import SensorStream, Session
from motionlab.simulate import simulate
from motionlab.timebase import take

QMT = SHARED / "datasets" / "human" / "qmt_full_body" / "full_body_example_data.mat"
HELD_DEG = 5.0  # an anchor's rest is the reference pose: the trunk turned less than this


def _calibrated(seed: int, preset: str, uncompensated: bool = False, end_s: float = 200.0):
    """The simulated lumbar session fused and calibrated; ``uncompensated``: the estimators'
    rests found on the raw rate (:data:`motionlab.fusion.rest.FUSION_MAX_BIAS` 0, as before
    they took the bias off), so that the ``harsh`` gyroscopes' biases are left to drift;
    ``end_s``: the recording cut there (s)."""
    lumbar = load_protocol("lumbar")
    session, truth = simulate(lumbar, 200.0, seed, preset=preset, mounting="random")
    for label, stream in session.sensors.items():
        session.sensors[label] = take(stream, np.flatnonzero(stream.time < end_s))
    with pytest.MonkeyPatch.context() as mp:
        if uncompensated:
            mp.setattr(fusion_rest, "FUSION_MAX_BIAS", 0.0)
        stages.prepare(session)
        stages.fuse(session)
    stages.calibrate(session, lumbar)
    return session, truth


@pytest.fixture(scope="module", params=[(0, "harsh"), (1, "skin")])
def lumbar_session(request):
    seed, preset = request.param
    harsh = preset == "harsh"  # cut before its last neutral rest (197-200 s)
    return (*_calibrated(seed, preset, harsh, 195.0 if harsh else 200.0), request.param)


def test_every_rest_that_ties_the_trunk_headings_is_the_reference_pose(lumbar_session):
    """No end-range hold of the axial rotation ties the headings, and the neutral rests
    between the tasks do (with the skin preset's typical gyroscopes the last, at 197-200 s,
    had been refused after the task's 14° of drift: axial rotation 13° off at the end)."""
    session, truth, (seed, preset) = lumbar_session
    tie = session.results.calibration.headings.joints["lumbar"]
    assert tie.source == "steps"
    axial = np.interp(tie.times, truth.time, truth.joint_angles["lumbar_axial_rotation_deg"])
    assert np.all(np.abs(axial) < HELD_DEG), (seed, preset, tie.times, axial)
    task = next(s for s in truth.steps if s["phase"] == "task" and "axial" in s["name"])
    before = [t for t in tie.times if task["start_s"] - 5.0 <= t <= task["start_s"]]
    assert before, (seed, preset, tie.times)  # the neutral rest before the last task
    if preset == "skin":
        assert max(tie.times) > task["end_s"], tie.times  # and the one after it


def test_headings_drifting_apart_fast_past_the_last_anchor_are_graded(lumbar_session):
    """Seed 0's anchors put the two headings 17°/min apart and its recording, cut at 195 s
    before its last neutral rest, runs on 34 s past the last: about 9°, so lateral bending and
    axial rotation (measured 2.4° and 2.8° RMS off, 5.9° over the last 40 s) are not determined
    and flexion weak. The skin preset's (under 1°/min, ending on a neutral rest) keep their
    grades. (Uncut, the smoother's accelerometer pre-filter now ties the rest at 198 s:
    0.9 / 2.4 / 1.3° off, rightly determined.)"""
    session, _, (seed, preset) = lumbar_session
    cal = session.results.calibration
    tie = cal.headings.joints["lumbar"]
    rate = np.degrees(heading.drift_rate(tie.times, tie.deltas)) * 60.0
    graded = cal.grades["lumbar"]
    if (seed, preset) == (0, "harsh"):
        assert rate > 10.0
        assert graded.grades == ["weak", "not determined", "not determined"]
        assert "drifting apart at" in graded.reasons[2]
    else:
        assert graded.grades == ["determined"] * 3, graded.reasons


def test_hold_graded_by_the_drift_beyond_the_anchors():
    base = {"lumbar": JointGrades(["determined"] * 3, [""] * 3)}
    assert grades.hold_graded(base, {"lumbar": 39.0}) == base  # under HEADING_HOLD_S
    assert grades.hold_graded(base, {}, {"lumbar": (0.05, 39.0)}) == base  # 2° by then
    fast = grades.hold_graded(base, {}, {"lumbar": (0.33, 39.0)})
    assert fast["lumbar"].grades == ["weak", "not determined", "not determined"]
    assert "drifting apart at 20°/min: about 13° by then" in fast["lumbar"].reasons[1]
    far = grades.hold_graded(base, {}, {"lumbar": (0.33, 60.0)})  # 20°: over 3 × 5°
    assert far["lumbar"].grades == ["not determined"] * 3
    view = SessionView(Session(), load_protocol("lumbar"), None, {}, None)
    cause, remedy = cause_and_remedy(view, "lumbar", fast["lumbar"].reasons[0])
    assert cause == "the sensors' headings drift apart fast between poses"
    assert "before and after every task" in remedy and "sensorcal" in remedy


def test_a_drift_rate_needs_anchors_spanning_time():
    assert heading.drift_rate([], []) == 0.0
    assert heading.drift_rate([10.0, 20.0], [0.0, 0.1]) == 0.0  # 10 s: their own scatter
    assert heading.drift_rate([40.0, 10.0], [np.radians(-9.0), 0.0]) == pytest.approx(
        np.radians(-0.3)
    )
    # unwrapped: 359° → 1° is 2° of drift, not 358°
    assert heading.drift_rate([0.0, 100.0], [np.radians(359.0), np.radians(1.0)]) == (
        pytest.approx(np.radians(0.02))
    )


@needs_shared
@pytest.mark.skipif(not QMT.is_file(), reason="the qmt full-body recording is not in ../shared")
def test_a_real_persons_rests_differ_by_stance_not_only_drift():
    """The real 16-IMU walk: the left hip's ties at the stand and at the rests after 46 and
    53 s differ by 2.5-6° (a person stands a little differently each time; the right hip's two
    rests 7 s apart differ by 5°). Read as drift they had graded the left hip's flexion weak
    and its other angles not determined, 46 s past its last rest; less POSE_SCATTER_DEG they
    are not."""
    import scipy.io as sio

    m = sio.loadmat(QMT, squeeze_me=True, struct_as_record=False)
    t = np.asarray(m["t"], float) - float(m["t"][0])
    names = {"hip": "pelvis", "upper_leg_right": "thigh_r", "lower_leg_right": "shank_r",
             "upper_leg_left": "thigh_l", "lower_leg_left": "shank_l"}  # fmt: skip
    session = Session()
    for name, seg in names.items():
        session.sensors[seg] = SensorStream(
            label=seg, time=t, acc=np.asarray(m[name].acc, float),
            gyr=np.asarray(m[name].gyr, float), segment=seg, vendor="Xsens",
            source_units={"acc": "m/s^2", "gyr": "rad/s"},
        )  # fmt: skip
    mark_shared_clock(list(session.sensors.values()), "one time vector t in the .mat file")
    prepare_sensors(session)
    analyse(session, PipelineOptions("walk", progress=False))
    cal = session.results.calibration
    drift = drift_beyond_anchors(session, load_protocol("walk"), cal.headings)
    tie = cal.headings.joints["hip_l"]
    assert tie.source == "steps" and np.ptp(np.degrees(tie.deltas)) > POSE_SCATTER_DEG
    rate, beyond = drift["hip_l"]
    assert beyond > 40.0 and rate * beyond < grades.HEADING_DRIFT_DEG
    for hip in ("hip_r", "hip_l"):
        assert cal.grades[hip].grades[0] == "determined"
        assert not any("drifting apart" in r for r in cal.grades[hip].reasons)
