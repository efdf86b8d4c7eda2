"""Accelerometer-bias states of the default estimator (``smoother``) and its forward filter
(``mekf``), and their use by the calibration (:func:`motionlab.segments.corrected_acc`)."""

import numpy as np
import pytest
from fusion_signals import G, constant_rotation

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.fusion.stage import calibration_acc_bias, fuse_session
from motionlab.protocol import load_protocol
from motionlab.segments import corrected_acc
from motionlab.session import SensorStream, Session, load_session, save_session
from motionlab.simulate import simulate

RATE = 100.0
BIAS = np.array([0.15, -0.2, 0.1])  # m/s², sensor frame


def _poses(bias=BIAS, seed=1):
    """Five rests (5 s) in different poses joined by 2 s turns about x, y, y+z and x+y; the
    accelerometer reads gravity plus ``bias`` and white noise (no linear acceleration)."""
    rng = np.random.default_rng(seed)

    def rest(s):
        return np.zeros((int(s * RATE), 3))

    def turn(axis, angle, s):
        n = int(s * RATE)
        a = np.asarray(axis, float) / np.linalg.norm(axis)
        return (angle / s * (1 - np.cos(2 * np.pi * np.arange(n) / n)))[:, None] * a

    omega = np.concatenate([
        rest(5), turn([1, 0, 0], np.pi / 2, 2), rest(5), turn([0, 1, 0], np.pi / 2, 2), rest(5),
        turn([0, 0.5, 1], 2.0, 2), rest(5), turn([1, 1, 0], -1.5, 2), rest(5),
    ])  # fmt: skip
    quat = rot.integrate_gyro(rot.from_axis_angle([0.3, -1, 0.2], 0.6), omega, 1 / RATE)
    n = len(quat)
    acc = rot.rotate(rot.conj(quat), np.array([0, 0, G])) + bias
    gyr = omega + 0.002 * rng.standard_normal((n, 3))
    return gyr, acc + 0.05 * rng.standard_normal((n, 3)), quat


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
    catch-all tuned on BROAD), but the tilt at the last rest falls to 0.40 (smoother) and 0.54
    (mekf) of that without bias states."""
    gyr, acc, quat = _poses()
    res = estimate(name, gyr, acc, None, RATE)
    without = estimate(name, gyr, acc, None, RATE, acc_bias_init=0.0)
    assert np.all(without.extra["acc_bias"] == 0.0)
    assert np.abs(res.extra["acc_bias"][-1] - BIAS).max() < 0.15
    last = slice(-400, None)
    new, old = _tilt_deg(res.quat, quat)[last].mean(), _tilt_deg(without.quat, quat)[last].mean()
    assert old > 0.9  # the bias does tilt the 6-state filter (0.96-0.97° measured)
    assert new < {"smoother": 0.5, "mekf": 0.65}[name] * old


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
    fuse_session(session, "default", magnetometer=False)
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
    fuse_session(ses, "default", magnetometer=False)
    s = ses.sensors["thigh_r"]
    wider = calibration_acc_bias(s.gyr, s.acc, s.rate_hz, s.time)
    np.testing.assert_array_equal(ses.results.fusion["thigh_r"].acc_bias, wider)
    assert np.abs(wider[0] - BIAS).max() < 0.025  # five poses determine it whatever the prior
    off = _session(acc.copy(), gyr.copy())
    fuse_session(off, "default", {"acc_bias_init": "0"}, magnetometer=False)
    assert off.results.fusion["thigh_r"].acc_bias is None  # no bias states: the raw accelerometer


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
    fuse_session(ses, "default", magnetometer=False)
    entry = ses.results.fusion["thigh_r"]
    assert entry.acc_bias.shape == acc.shape
    np.testing.assert_allclose(corrected_acc(ses, "thigh_r"), acc - entry.acc_bias)
    np.testing.assert_array_equal(ses.sensors["thigh_r"].acc, acc)  # input untouched
    save_session(ses, tmp_path / "s.h5")
    back = load_session(tmp_path / "s.h5")
    np.testing.assert_allclose(back.results.fusion["thigh_r"].acc_bias, entry.acc_bias)
