"""Functional axes signed by the data (:func:`motionlab.segments.placement.data_signs`).

A functional step's axis is measured without a sign; the placement hint gave it one. With the
sensors strapped any way round the hint is as often wrong as right, and a sensor half a turn
round from it agrees with it in every axis compared without its sign: the elbow protocol so
simulated (``mounting="random"``, seeds 0-5) read elbow flexion 61-179° RMS off on 8 of 12
elbows, graded ``weak``. The data sign such an axis where the step moves one way from the
reference pose (a shoulder or an elbow flexes forward from standing) or where it is the long
axis, near vertical in that pose (the forearm's pronation axis: it points up).
"""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab import stages
from motionlab.binding import sensor_for_segment
from motionlab.protocol import load_protocol
from motionlab.segments import placement, streams_of
from motionlab.segments.mounting import measure
from motionlab.segments.steps import find_steps
from motionlab.simulate import simulate

ARM = ("upperarm_r", "forearm_r", "upperarm_l", "forearm_l")


@pytest.fixture(scope="module")
def elbow():
    return load_protocol("elbow")


def _frame_errors_deg(session, truth, segments) -> dict[str, float]:
    """Largest angle (deg) between a calibrated segment axis and the true one, per segment."""
    out = {}
    for seg in segments:
        m_true = truth.sensors[sensor_for_segment(session, seg)]["mounting"]
        q = rot.mul(m_true, np.asarray(session.results.calibration.segments[seg].mounting, float))
        out[seg] = max(
            float(np.degrees(np.arccos(np.clip(rot.rotate(q, e) @ e, -1.0, 1.0))))
            for e in np.eye(3)
        )
    return out


def test_sensors_strapped_any_way_round_get_their_frames_from_the_data(elbow):
    session, truth = simulate(elbow, 205.0, 0, preset="clean", rate_hz=50.0, mounting="random")
    stages.prepare(session)
    stages.fuse(session)
    stages.calibrate(session, elbow)
    errors = _frame_errors_deg(session, truth, ARM)
    assert max(errors.values()) < 3.0, errors  # before: 179.5° (upper arms, forearms)
    cal = session.results.calibration
    for side in "rl":
        assert cal.grades[f"elbow_{side}"].grades[0] == "determined"


def test_a_trunk_bent_forward_signs_the_thorax_and_the_pelvis_that_tilts_with_it():
    """The lumbar protocol strapped any way round (seed 0: pelvis, thorax and lumbar sensors
    half a turn off the hint, lumbar flexion 42° RMS off, 'weak'): the forward bend signs the
    thorax's axis by its excursion and the pelvis's, which tilts 8-18° and back, by turning
    with it."""
    lumbar = load_protocol("lumbar")
    session, truth = simulate(lumbar, 185.0, 0, preset="clean", rate_hz=50.0, mounting="random")
    stages.prepare(session)
    stages.fuse(session)
    stages.calibrate(session, lumbar)
    errors = _frame_errors_deg(session, truth, ("pelvis", "thorax"))
    assert max(errors.values()) < 3.0, errors
    assert session.results.calibration.grades["lumbar"].grades == ["determined"] * 3


def test_a_biased_gyroscope_does_not_turn_the_forward_bend_the_other_way():
    """Sensors with the ``harsh`` preset's gyroscope biases (2°/s per axis), strapped any way
    round (seed 3): integrated from the step's start with its bias, the 20-s forward bend's 50°
    out and back read as a turn the other way, so both trunk frames went half a turn round
    (pelvis 169°, thorax 180° off) and lumbar flexion read as extension, graded determined.
    The bias the reference pose shows is taken off first."""
    lumbar = load_protocol("lumbar")
    session, truth = simulate(lumbar, 200.0, 3, preset="harsh", mounting="random")
    stages.prepare(session)
    stages.fuse(session)
    stages.calibrate(session, lumbar)
    errors = _frame_errors_deg(session, truth, ("pelvis", "thorax"))
    assert errors["thorax"] < 5.0 and errors["pelvis"] < 15.0, errors  # the pelvis hardly turns


def test_arm_movements_from_standing_sign_the_axes_of_a_protocol_whose_pose_is_supine():
    """The children's protocol (reference pose supine, arm movements standing) strapped any
    way round (seed 0: elbow flexion 61° RMS off, 'weak'): its arm movements start with the
    arms hanging, each segment's long axis vertical (across the supine pose's x and the
    movement's z), so they sign their axes as from a stand."""
    children = load_protocol("upper_body_children")
    session, truth = simulate(children, 205.0, 0, preset="clean", rate_hz=50.0, mounting="random")
    stages.prepare(session)
    stages.fuse(session)
    stages.calibrate(session, children)
    errors = _frame_errors_deg(session, truth, ("thorax", *ARM))
    assert max(errors.values()) < 3.0, errors
    assert not any(r.unsigned_steps for r in session.results.calibration.segments.values())


def test_the_hint_of_sensors_strapped_as_the_protocol_says_is_not_contradicted(elbow):
    """Within 30° of the placement: every axis the data sign points as the hint signed it."""
    session, _ = simulate(elbow, 205.0, 1, preset="clean", rate_hz=50.0)
    stages.prepare(session)
    streams = streams_of(session, elbow)
    steps = find_steps(streams, elbow)
    records = measure(elbow, streams, steps)
    signs = placement.data_signs(elbow, streams, steps, records)
    told = {key for key in signs if key[0] in ARM}
    # each arm segment's shoulder and elbow flexion (one way from standing), the forearm's
    # pronation axis (its long axis)
    assert {("upperarm_r", "shoulder_flexion_r"), ("forearm_r", "elbow_flexion_r"),
            ("forearm_r", "pronation_r"), ("forearm_l", "pronation_l")} <= told  # fmt: skip
    assert all(sign == 1 for sign in signs.values()), signs
    assert not placement.signs_contradicted(signs)
