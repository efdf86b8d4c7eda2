"""Accelerometer-bias states of the default estimator (``smoother``) and its forward filter
(``mekf``), and their use by the calibration (:func:`motionlab.segments.corrected_acc`)."""

import numpy as np
import pytest
from fusion_signals import G, constant_rotation

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.fusion.detect import rest_mask
from motionlab.fusion.stage import (
    CALIBRATION_WINDOW_S,
    _joined_bias,
    _merged_windows,
    calibration_acc_bias,
    fuse_session,
    heading_concentration,
    levels_its_rests,
)
from motionlab.protocol import load_protocol
from motionlab.segments import corrected_acc
from motionlab.session import SensorStream, Session, load_session, save_session
from motionlab.simulate import simulate
from motionlab.timebase import runs

RATE = 100.0
BIAS = np.array([0.15, -0.2, 0.1])  # m/s², sensor frame


def _rest(s):
    return np.zeros((int(s * RATE), 3))


def _turn(axis, angle, s):
    n = int(s * RATE)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return (angle / s * (1 - np.cos(2 * np.pi * np.arange(n) / n)))[:, None] * a


def _recorded(omega, bias, seed):
    """Gyroscope and accelerometer (gravity plus ``bias`` and white noise, no linear
    acceleration) of the rotation rate ``omega`` from a fixed start, and the true orientation."""
    rng = np.random.default_rng(seed)
    quat = rot.integrate_gyro(rot.from_axis_angle([0.3, -1, 0.2], 0.6), omega, 1 / RATE)
    n = len(quat)
    acc = rot.rotate(rot.conj(quat), np.array([0, 0, G])) + bias
    gyr = omega + 0.002 * rng.standard_normal((n, 3))
    return gyr, acc + 0.05 * rng.standard_normal((n, 3)), quat


def _poses(bias=BIAS, seed=1):
    """Five rests (5 s) in different poses joined by 2 s turns about x, y, y+z and x+y."""
    omega = np.concatenate([
        _rest(5), _turn([1, 0, 0], np.pi / 2, 2), _rest(5), _turn([0, 1, 0], np.pi / 2, 2),
        _rest(5), _turn([0, 0.5, 1], 2.0, 2), _rest(5), _turn([1, 1, 0], -1.5, 2), _rest(5),
    ])  # fmt: skip
    return _recorded(omega, bias, seed)


def _tilt_deg(q, q_true):
    """Angle (deg) between the estimated and the true earth-up, in the sensor frame."""
    up = np.array([0.0, 0.0, 1.0])
    a = rot.rotate(rot.conj(q), np.broadcast_to(up, (len(q), 3)))
    b = rot.rotate(rot.conj(q_true), np.broadcast_to(up, (len(q), 3)))
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


@pytest.mark.parametrize("name", ["smoother", "mekf"])
def test_bias_is_recovered_from_rests_in_several_poses(name):
    """With a loose prior the poses determine the bias: measured error ≤ 0.012 m/s² (of 0.2)."""
    gyr, acc, _ = _poses()
    res = estimate(name, gyr, acc, None, RATE, acc_bias_init=0.5)
    assert np.abs(res.extra["acc_bias"][-1] - BIAS).max() < 0.025


@pytest.mark.parametrize("name", ["smoother", "mekf"])
def test_default_prior_halves_the_tilt_of_a_biased_accelerometer(name):
    """With the default prior (0.1 m/s², datasheet-like) the filter takes the poses' evidence
    only partly (measured bias error ≤ 0.10 m/s² of 0.2; the gyroscope noise of its model is a
    catch-all tuned on BROAD), but the tilt at the last rest falls to 0.50 (smoother; 0.47 on
    the raw accelerometer, ``acc_lowpass_tau`` 0: the pre-filter's turns carry the first
    pass's bias) and 0.54 (mekf) of that without bias states."""
    gyr, acc, quat = _poses()
    res = estimate(name, gyr, acc, None, RATE)
    without = estimate(name, gyr, acc, None, RATE, acc_bias_init=0.0)
    assert np.all(without.extra["acc_bias"] == 0.0)
    assert np.abs(res.extra["acc_bias"][-1] - BIAS).max() < 0.15
    last = slice(-400, None)
    new, old = _tilt_deg(res.quat, quat)[last].mean(), _tilt_deg(without.quat, quat)[last].mean()
    assert old > 0.9  # the bias does tilt the 6-state filter (0.96-0.97° measured)
    assert new < {"smoother": 0.55, "mekf": 0.65}[name] * old


def test_smoother_carries_the_bias_to_the_first_rest():
    gyr, acc, quat = _poses()
    res = estimate("smoother", gyr, acc, None, RATE, acc_bias_init=0.5)
    assert np.abs(res.extra["acc_bias"][0] - BIAS).max() < 0.025
    first = slice(0, 400)
    base = estimate("smoother", gyr, acc, None, RATE, acc_bias_init=0.0)
    assert _tilt_deg(res.quat, quat)[first].mean() < 0.3 * _tilt_deg(base.quat, quat)[first].mean()


@pytest.mark.parametrize("name", ["smoother", "mekf"])
@pytest.mark.parametrize("nine", [False, True])
def test_one_static_pose_leaves_the_bias_at_zero_and_the_orientation_as_before(name, nine):
    sig = constant_rotation(seconds=30.0, omega=(0.0, 0.0, 0.0))
    acc = sig["acc"] + BIAS  # not separable from the tilt: a static pose does not determine it
    mag = sig["mag"] if nine else None
    res = estimate(name, sig["gyr"], acc, mag, RATE)
    old = estimate(name, sig["gyr"], acc, mag, RATE, acc_bias_init=0.0)
    # measured: |bias| ≤ 5e-5 m/s², orientation within 2.1e-4° of the 6-state filter's
    assert np.abs(res.extra["acc_bias"]).max() < 1e-3
    assert np.degrees(rot.angle_between(res.quat, old.quat)).max() < 0.01


def test_stand_tilt_of_a_stand_and_walk_is_smaller():
    """Simulated stand + walk (``typical`` sensors, their own accelerometer biases): the
    inclination error over the stand, which the calibration inherits, shrinks."""
    session, truth = simulate(load_protocol("walk"), 30.0, 21, "typical", gait="normal")
    stand = [s for s in truth.steps if s["phase"] != "task"][0]
    errs = []
    for label, s in session.sensors.items():
        t = truth.sensors[label]["sample_time"]
        q_true = rot.resample(truth.time, truth.sensors[label]["orientation"], t)
        sel = (t > stand["start_s"] + 0.5) & (t < stand["end_s"] - 0.5)
        row = []
        for kw in ({}, {"acc_bias_init": 0.0}):
            q = estimate("smoother", s.gyr, s.acc, None, RATE, time=s.time, **kw).quat
            up = np.array([0.0, 0.0, 1.0])
            a = rot.rotate(rot.conj(q[sel]), np.broadcast_to(up, (sel.sum(), 3)))
            b = rot.rotate(rot.conj(q_true[sel]), np.broadcast_to(up, (sel.sum(), 3)))
            row.append(np.degrees(np.linalg.norm(np.cross(b, a).mean(axis=0))))
        errs.append(row)
    new, old = np.mean(errs, axis=0)
    assert new < 0.9 * old  # measured with the default prior: 0.63° against 0.78°


def test_the_calibration_takes_the_bias_the_walk_determines():
    """Simulated stand + 60 s walk (``typical``: accelerometer bias σ 0.1 m/s² per axis): the
    stand's gravity direction from ``acc − acc_bias`` (the fusion entry's bias, estimated with
    the calibration's wider prior) is closer to the true vertical than the raw accelerometer's."""
    session, truth = simulate(load_protocol("walk"), 60.0, 23, "typical", gait="normal")
    stand = [s for s in truth.steps if s["phase"] != "task"][0]
    session.results.fusion.update(fuse_session(session, "default", magnetometer=False))
    raw, cal = [], []
    for label, s in session.sensors.items():
        t = truth.sensors[label]["sample_time"]
        q_true = rot.resample(truth.time, truth.sensors[label]["orientation"], t)
        sel = (t > stand["start_s"] + 0.5) & (t < stand["end_s"] - 0.5)
        up = rot.rotate(rot.conj(q_true[sel]), np.array([0.0, 0.0, 1.0])).mean(axis=0)
        for out, acc in ((raw, s.acc), (cal, corrected_acc(session, label))):
            g = acc[sel].mean(axis=0)
            out.append(np.degrees(np.arccos(g @ up / np.linalg.norm(g) / np.linalg.norm(up))))
    assert np.mean(cal) < 0.65 * np.mean(raw)  # measured 0.54° against 0.99°
    assert max(cal) < 0.6 * max(raw)  # measured 0.97° against 2.31°


def test_the_calibration_bias_is_the_smoother_with_the_wider_prior():
    gyr, acc, _ = _poses()
    ses = _session(acc.copy(), gyr.copy())
    ses.results.fusion.update(fuse_session(ses, "default", magnetometer=False))
    s = ses.sensors["thigh_r"]
    wider = calibration_acc_bias(s.gyr, s.acc, s.rate_hz, s.time)
    np.testing.assert_array_equal(ses.results.fusion["thigh_r"].acc_bias, wider)
    assert np.abs(wider[0] - BIAS).max() < 0.025  # five poses determine it whatever the prior
    off = _session(acc.copy(), gyr.copy())
    entry = fuse_session(off, "default", {"acc_bias_init": "0"}, magnetometer=False)["thigh_r"]
    assert entry.acc_bias is None  # no bias states: the raw accelerometer


def _session(acc, gyr):
    n = len(acc)
    s = SensorStream("thigh_r", np.arange(n) / RATE, acc=acc, gyr=gyr, segment="thigh", side="r")
    ses = Session(metadata={})
    ses.sensors[s.label] = s
    return ses


def test_calibration_sees_the_accelerometer_less_the_fused_bias(tmp_path):
    gyr, acc, _ = _poses()
    ses = _session(acc.copy(), gyr.copy())
    np.testing.assert_array_equal(corrected_acc(ses, "thigh_r"), acc)  # not fused yet
    ses.results.fusion.update(fuse_session(ses, "default", magnetometer=False))
    entry = ses.results.fusion["thigh_r"]
    assert entry.acc_bias.shape == acc.shape
    np.testing.assert_allclose(corrected_acc(ses, "thigh_r"), acc - entry.acc_bias)
    np.testing.assert_array_equal(ses.sensors["thigh_r"].acc, acc)  # input untouched
    save_session(ses, tmp_path / "s.h5")
    back = load_session(tmp_path / "s.h5")
    np.testing.assert_allclose(back.results.fusion["thigh_r"].acc_bias, entry.acc_bias)


def _poses_then_walk(seed=1):
    """Three rests in different poses (2 s turns between), 100 s of rotation without rest, and
    a last rest of 5 s."""
    t = np.arange(int(100 * RATE)) / RATE
    ramp = np.minimum(1.0, np.minimum(t, t[::-1]))[:, None]
    move = ramp * np.column_stack([np.sin(0.7 * t), np.cos(0.5 * t), 0.5 * np.sin(0.3 * t) + 0.3])
    omega = np.concatenate([
        _rest(5), _turn([1, 0, 0], np.pi / 2, 2), _rest(5), _turn([0, 1, 0], np.pi / 2, 2),
        _rest(5), move, _rest(5),
    ])  # fmt: skip
    return _recorded(omega, BIAS, seed)[:2]


def test_the_calibration_bias_joins_rests_far_apart():
    """The calibration's smoother runs over windows of 45 s around the rests only; the last
    rest's window (one pose) takes the bias that the first window's three poses determine:
    measured error 0.028 m/s² at the last rest (the whole recording's smoother 0.025; the
    last window on its own 0.114)."""
    gyr, acc = _poses_then_walk()
    rest = rest_mask(gyr, acc, RATE, np.deg2rad(2.0), 0.5, min_duration=1.5)
    pad = int(CALIBRATION_WINDOW_S * RATE)
    assert len(_merged_windows(runs(rest), pad, len(rest))) == 2
    bias = calibration_acc_bias(gyr, acc, RATE)
    assert np.abs(bias[-100] - BIAS).max() < 0.04
    assert np.abs(bias[100] - BIAS).max() < 0.04
    whole = calibration_acc_bias(gyr, acc, RATE, window_s=1e9)
    assert np.abs(bias[-100] - whole[-100]).max() < 0.01


def test_windows_around_rests():
    assert _merged_windows(np.array([[100, 200], [350, 400], [900, 950]]), 100, 1000) == [
        (0, 500),
        (800, 1000),
    ]
    assert _merged_windows(np.zeros((0, 2), int), 100, 1000) == []
    gyr = np.zeros((300, 3)) + [0.5, 0.0, 0.0]  # turning all along: no rest, no bias
    acc = np.tile([0.0, 0.0, G], (300, 1))
    assert np.all(calibration_acc_bias(gyr, acc, RATE) == 0.0)


def test_joined_bias_by_hand():
    """Prior N(0, 0.5² I): window 1 measures x (likelihood mean 0.1, information 96), window 2
    y (−0.2, 96); each window's posterior is then 0.96 of its likelihood mean. Joined: both get
    (0.096, −0.192, 0); with a random walk of 0.01 m/s²/√s over 100 s between them the other
    window's information is 96 / (1 + 0.01 · 96)."""
    c1, c2 = np.diag([0.01, 0.25, 0.25]), np.diag([0.25, 0.01, 0.25])
    ends = [(0.0, np.array([0.096, 0.0, 0.0]), c1), (100.0, np.array([0.0, -0.192, 0.0]), c2)]
    for b in _joined_bias(ends, 0.0):
        np.testing.assert_allclose(b, [0.096, -0.192, 0.0], atol=1e-12)
    weak = 96 / (1 + 0.01 * 96)
    b1, b2 = _joined_bias(ends, 0.01)
    np.testing.assert_allclose(b1, [0.096, weak * -0.2 / (4 + weak), 0.0], atol=1e-12)
    np.testing.assert_allclose(b2, [weak * 0.1 / (4 + weak), -0.192, 0.0], atol=1e-12)


def _swing(centre_deg, amp_deg, turn_deg=360.0, seed=2):
    """A rest with the sensor's z up (5 s), 40 s of a segment swinging about the sensor's x
    axis between ``centre ± amp`` degrees from that pose (0.3 Hz) while its heading turns
    steadily by ``turn_deg`` (as walking round a room: 0 is a straight walk), a rest again;
    the sensor 0.3 m from the joint it swings about, so the accelerometer also reads the
    swing's centripetal (along +y) and tangential acceleration (the turn's own, under
    0.01 m/s², left out)."""
    t = np.arange(int(40 * RATE)) / RATE
    ease = np.minimum(1.0, np.minimum(t, t[-1] - t) / 2.0)
    theta = np.radians(centre_deg) * (1 - np.cos(np.pi * ease)) / 2
    theta = np.concatenate([np.zeros(500), theta + np.radians(amp_deg) * ease * np.sin(
        2 * np.pi * 0.3 * t), np.zeros(500)])  # fmt: skip
    psi = np.radians(turn_deg) * np.concatenate([np.zeros(500), t / t[-1], np.ones(500)])
    rate, yaw_rate = np.gradient(theta, 1 / RATE), np.gradient(psi, 1 / RATE)
    quat = rot.mul(rot.from_rotvec(np.outer(0.4 + psi, [0, 0, 1])),
                   rot.from_rotvec(np.outer(theta, [1, 0, 0])))  # fmt: skip
    lever = np.column_stack([0 * theta, 0.3 * rate**2, -0.3 * np.gradient(rate, 1 / RATE)])
    rng = np.random.default_rng(seed)
    acc = rot.rotate(rot.conj(quat), np.array([0, 0, G])) + lever + BIAS
    omega = np.column_stack([rate, yaw_rate * np.sin(theta), yaw_rate * np.cos(theta)])
    gyr = omega + 0.002 * rng.standard_normal((len(theta), 3))
    return gyr, acc + 0.05 * rng.standard_normal(acc.shape), quat


@pytest.mark.parametrize(
    ("centre", "turn", "levels"), [(5.0, 360.0, True), (60.0, 360.0, False), (5.0, 0.0, False)]
)
def test_movement_far_from_its_rest_or_straight_does_not_level_it(centre, turn, levels):
    """A swing about its rest pose (mean tilt 13°) while turning round judges the rest; one
    that spends the movement 60° from it (mean tilt 58°, as a forearm in free arm movement)
    does not, nor one that never turns (a straight walk: a bias fixed in the sensor frame then
    stays fixed in the earth frame too, as the walker's own acceleration at the start does),
    and the calibration then takes no bias (the recording as it is)."""
    gyr, acc, quat = _swing(centre, 20.0, turn)
    rest = rest_mask(gyr, acc, RATE, np.deg2rad(2.0), 0.5, min_duration=1.5)
    assert runs(rest).shape[0] == 2  # the two rests, in one pose
    assert levels_its_rests(quat, acc, rest) is levels
    bias = calibration_acc_bias(gyr, acc, RATE)
    assert np.all(bias == 0.0) is not levels


def test_heading_concentration():
    """The mean resultant length of the headings of a sensor axis perpendicular to the
    vertical: 1 heading one way (tilts do not matter), 0 there and back in equal parts,
    |3 e^{i0} + e^{iπ}| / 4 = 0.5 three quarters one way, |Σ e^{ikπ/2}| = 0 round the
    compass."""
    up = np.array([0.0, 0.0, 1.0])
    tilted = rot.from_rotvec(np.outer(np.linspace(-0.5, 0.5, 40), [1.0, 0.0, 0.0]))
    assert heading_concentration(tilted, up) == pytest.approx(1.0)
    yaw = rot.from_rotvec(np.outer([0.0, np.pi, 0.0, 0.0], [0.0, 0.0, 1.0]))
    assert heading_concentration(yaw, up) == pytest.approx(0.5)
    assert heading_concentration(yaw[:2], up) == pytest.approx(0.0, abs=1e-12)
    compass = rot.from_rotvec(np.outer(np.arange(4) * np.pi / 2, [0.0, 0.0, 1.0]))
    assert heading_concentration(compass, up) == pytest.approx(0.0, abs=1e-12)


def test_rests_in_two_poses_level_themselves():
    """Rests in different poses determine the bias through the gyroscope whatever the
    movement between them: the five poses are judged to level their rests, while the first
    rest alone, the other poses taken for movement (its vertical 48° from the earth's on
    average), is not."""
    gyr, acc, quat = _poses()
    rest = rest_mask(gyr, acc, RATE, np.deg2rad(2.0), 0.5, min_duration=1.5)
    assert runs(rest).shape[0] == 5
    assert levels_its_rests(quat, acc, rest)
    one = rest.copy()
    one[int(runs(rest)[1][0]) :] = False  # only the first rest counts as one
    assert not levels_its_rests(quat, acc, one)
