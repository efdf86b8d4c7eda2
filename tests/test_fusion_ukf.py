"""Tests of the quaternion UKF (``ukf``) and its intrinsic sigma-point mean."""

import numpy as np
from fusion_signals import constant_rotation, heading_aligned, wrong_start

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion import estimate
from motionlab.fusion.ukf import intrinsic_mean

BIAS = (0.01, -0.02, 0.015)


def _run(sig, mag=True):
    return estimate("ukf", sig["gyr"], sig["acc"], sig["mag"] if mag else None, sig["rate"])


def _err(q, sig):
    return np.degrees(rot.angle_between(q, sig["quat"]))


def test_mean_of_symmetric_sigma_set_is_its_centre():
    centre = rot.from_axis_angle([0.3, -1.0, 0.4], 2.0)
    offsets = 0.4 * np.vstack([np.eye(3), -np.eye(3)]) + 0.05
    offsets[3:] = -offsets[:3]
    pts = rot.mul(centre, rot.from_rotvec(offsets))
    pts[1] *= -1  # sign does not matter
    mean = intrinsic_mean(pts, start=pts[0])
    assert rot.angle_between(mean, centre) < 1e-9


def test_mean_of_two_is_the_slerp_midpoint():
    a = rot.from_axis_angle([0, 0, 1], 0.2)
    b = rot.from_axis_angle([1, 1, 0], 1.5)
    mid = rot.slerp(a, b, 0.5)
    assert rot.angle_between(intrinsic_mean(np.stack([a, b])), mid) < 1e-9


def test_mean_rejects_bad_shape():
    try:
        intrinsic_mean(np.zeros((3, 3)))
    except InputError as exc:
        assert "(M, 4)" in str(exc)
    else:
        raise AssertionError("no InputError")


def test_converges_from_90_degree_wrong_start():
    sig = constant_rotation(seconds=20.0, bias=BIAS)
    err = _err(_run(wrong_start(sig)).quat, sig)
    assert err[0] > 80.0
    assert err[int(10 * sig["rate"]) :].max() < 3.0


def test_tracks_constant_rate_rotation_and_estimates_bias():
    sig = constant_rotation(seconds=30.0, bias=BIAS)
    res = _run(sig)
    err = _err(res.quat, sig)[int(10 * sig["rate"]) :]
    assert np.sqrt(np.mean(err**2)) < 1.5
    np.testing.assert_allclose(res.gyro_bias[-1], BIAS, atol=0.003)
    assert not res.mag_disturbed.any()


def test_six_d_mode():
    sig = constant_rotation(seconds=20.0, bias=BIAS)
    res = _run(sig, mag=False)
    assert res.mag_disturbed is None
    late = np.arange(len(sig["quat"])) > len(sig["quat"]) // 2
    err = _err(heading_aligned(res.quat, sig["quat"], late), sig)
    assert err[int(5 * sig["rate"]) :].max() < 3.0
