"""Static poses with a horizontal segment axis (``horizontal_axis``): the elbow's standing pose.

A right-elbow protocol is simulated (``clean`` preset, seed 1, mounting error up to 30°); in the
standing pose the forearm's anterior axis is horizontal (flexion and pronation zero, carrying
angle 10°). A constant accelerometer bias of 0.2 m/s² is added along the forearm sensor's axis
that points forward in that pose. The session is then fused (:func:`motionlab.stages.fuse`), which
estimates part of that bias (``acc_bias``, about 0.13 m/s² of it here); the calibration reads the
accelerometer less that estimate, and the rest of the bias (about 0.07 m/s²) tilts its gravity
by about 0.4° about the segment's z axis.
"""

import numpy as np
import pytest
from protocol_texts import ELBOW_R

from motionlab import rotations as rot
from motionlab import stages
from motionlab.errors import InputError
from motionlab.protocol import load_protocol
from motionlab.segments import calibrate_segments
from motionlab.segments.frames import level
from motionlab.simulate import simulate

# the standing pose takes extra keys through "%s"
ELBOW = ELBOW_R.replace("{upperarm_r: y}}", "{upperarm_r: y}\n     %s}")
BIAS = 0.2  # m/s²


def protocol(tmp_path, extra: str):
    path = tmp_path / "elbow_r.yaml"
    path.write_text(ELBOW % extra)
    return load_protocol(path)


def test_level_by_hand():
    m = rot.to_matrix(rot.from_axis_angle([0.0, 0.0, 1.0], np.radians(3.0)))  # x tilted up 3°
    up = np.array([0.0, 1.0, 0.0])
    out = level(m, up, np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(out @ [1.0, 0, 0], [1.0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(out @ [0, 0, 1.0], [0, 0, 1.0], atol=1e-12)  # z untouched
    y = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(level(m, m @ y, y), m)  # an axis straight up: left as it is


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("elbow")
    plain = protocol(tmp, "")
    session, truth = simulate(plain, duration=70, seed=1, preset="clean", rest_s=5.0)
    q_mount = truth.sensors["forearm_r"]["mounting"]  # sensor → segment
    forward = rot.rotate(rot.conj(q_mount), np.array([1.0, 0.0, 0.0]))  # segment x in sensor
    session.sensors["forearm_r"].acc = session.sensors["forearm_r"].acc + BIAS * forward
    stages.fuse(session)
    return tmp, plain, session, truth, forward


def test_forearm_tilt_follows_the_standing_accelerometer(sessions):
    tmp, plain, session, truth, forward = sessions
    leveled = protocol(tmp, ", horizontal_axis: {forearm_r: x}")
    before = calibrate_segments(session, plain).segments["forearm_r"]
    cal = calibrate_segments(session, leveled)
    after = cal.segments["forearm_r"]
    rec = after.axes["standing:horizontal"]
    assert rec.method == "horizontal" and rec.residual_deg < 1e-6
    assert rec.rho > 0.99
    # the change is a turn about the segment's z axis by the tilt of the bias the fusion left
    # in the standing accelerometer (atan(0.074 / 9.81) = 0.43°; 1.17° for the whole bias)
    s, (t0, t1) = session.sensors["forearm_r"], cal.steps["standing"]
    estimated = session.results.fusion["forearm_r"].acc_bias[(s.time >= t0) & (s.time <= t1)]
    left = BIAS - np.mean(estimated @ forward)
    assert 0.03 < left < 0.15  # the fusion took part of it, not all
    m0, m1 = rot.to_matrix(before.mounting), rot.to_matrix(after.mounting)
    turn = rot.to_rotvec(rot.from_matrix(m0.T @ m1))  # in segment coordinates
    assert abs(np.degrees(turn[2])) == pytest.approx(np.degrees(np.arctan(left / 9.81)), abs=0.05)
    assert np.degrees(np.linalg.norm(turn[:2])) < 0.3
    truth_mount = rot.conj(truth.sensors["forearm_r"]["mounting"])
    assert np.degrees(rot.angle(rot.mul(rot.conj(truth_mount), after.mounting))) < 2.0


def test_horizontal_axis_only_in_static_steps(tmp_path):
    pronation = "axis: {forearm_r: y},"
    bad = ELBOW.replace(pronation, pronation + " horizontal_axis: {forearm_r: x},") % ""
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    with pytest.raises(InputError, match="horizontal") as err:
        load_protocol(path)
    assert "line 12" in str(err.value)


def test_horizontal_axis_alone_does_not_fix_a_segment(tmp_path):
    """A stand and little else (getting into the pose): the forearm's horizontal axis fixes
    nothing and 20 s of small movements hardly fix the elbow's axes: the calibration goes on,
    and no elbow angle is graded 'determined'."""
    path = tmp_path / "alone.yaml"
    path.write_text(
        "name: one\nsegments:\n  upperarm_r: {side: r}\n  forearm_r: {side: r}\ncalibration:\n"
        "  - {name: standing, kind: static, duration_s: 4, vertical_axis: {upperarm_r: y},\n"
        "     horizontal_axis: {forearm_r: x}}\n"
        "joints:\n  elbow_r: {type: elbow, proximal: upperarm_r, distal: forearm_r, side: r}\n"
    )
    one = load_protocol(path)
    session, _ = simulate(one, duration=20, seed=0, preset="clean", rest_s=2.0)
    stages.fuse(session)
    cal = calibrate_segments(session, one)
    assert not cal.ok
    grades = cal.grades["elbow_r"]
    assert "determined" not in grades.grades
    assert all(grades.reasons)
