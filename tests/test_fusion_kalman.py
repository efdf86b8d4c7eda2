"""Tests of To's quaternion KF (``kf``) and Liu's quaternion EKF with bias states (``ekf``)."""

import numpy as np
import pytest
from fusion_signals import constant_rotation, heading_aligned, wrong_start

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.fusion.kalman import paper_process_noise

BIAS = (0.01, -0.02, 0.015)


def _errors(res, sig, mag: bool = True) -> np.ndarray:
    """Angle (deg) between estimate and truth per sample (heading-aligned in 6-D)."""
    q = res.quat
    if not mag:
        late = np.arange(len(q)) > len(q) // 2
        q = heading_aligned(q, sig["quat"], late)
    return np.degrees(rot.angle_between(q, sig["quat"]))


def _run(name, sig, mag=True, **kw):
    return estimate(name, sig["gyr"], sig["acc"], sig["mag"] if mag else None, sig["rate"], **kw)


# the KF has no bias state: without rest its heading lags by bias × time constant
CASES = [("kf", (0.0, 0.0, 0.0)), ("ekf", BIAS)]


@pytest.mark.parametrize(("name", "bias"), CASES)
def test_converges_from_90_degree_wrong_start(name, bias):
    sig = constant_rotation(seconds=20.0, bias=bias)
    bad = wrong_start(sig)
    err = _errors(_run(name, bad), sig)
    assert err[0] > 80.0
    assert err[int(10 * sig["rate"]) :].max() < 3.0


@pytest.mark.parametrize(("name", "bias"), CASES)
def test_tracks_constant_rate_rotation(name, bias):
    sig = constant_rotation(seconds=20.0, bias=bias)
    res = _run(name, sig)
    # after start-up (3 s) the EKF learns the bias, which takes a few seconds
    err = _errors(res, sig)[int(10 * sig["rate"]) :]
    assert np.sqrt(np.mean(err**2)) < 1.5
    assert np.isclose(np.linalg.norm(res.quat, axis=1), 1.0).all()
    assert (np.sum(res.quat[1:] * res.quat[:-1], axis=1) >= 0).all()
    assert not res.mag_disturbed.any()


def test_ekf_estimates_known_gyro_bias():
    sig = constant_rotation(seconds=30.0, bias=BIAS)
    res = _run("ekf", sig)
    np.testing.assert_allclose(res.gyro_bias[-1], BIAS, atol=0.003)


@pytest.mark.parametrize(("name", "bias"), CASES)
def test_six_d_mode_keeps_inclination_and_a_fixed_heading(name, bias):
    sig = constant_rotation(seconds=20.0, bias=bias)
    res = _run(name, sig, mag=False)
    assert res.mag_disturbed is None
    err = _errors(res, sig, mag=False)[int(8 * sig["rate"]) :]
    assert err.max() < 2.5


def test_kf_rest_bias_and_paper_noise():
    # at rest the KF takes the gyroscope's mean as its bias
    sig = constant_rotation(seconds=10.0, omega=(0.0, 0.0, 0.0), bias=BIAS, gyr_noise=0.002)
    res = _run("kf", sig)
    assert res.rest[-1]
    np.testing.assert_allclose(res.gyro_bias[-1], BIAS, atol=0.002)
    # To's printed noise (eqs. 197-198) trusts the observation quaternion almost fully
    moving = constant_rotation(seconds=10.0)
    err = _errors(_run("kf", moving, paper_noise=True), moving)[int(2 * moving["rate"]) :]
    assert np.sqrt(np.mean(err**2)) < 2.0
    assert np.linalg.eigvalsh(paper_process_noise()).min() >= -1e-12
