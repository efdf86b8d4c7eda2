"""Complementary filters: gyro-bias estimates, disturbance gating, 6-D fallback, parameters."""

import numpy as np
import pytest
from fusion_signals import FIELD, constant_rotation

from motionlab import rotations as rot
from motionlab.fusion import estimate
from motionlab.validation.orientation_error import error_angles, orientation_errors

MINE = ["madgwick", "mahony", "liu_gn", "adaptive_cf"]
BIAS = (0.02, -0.03, 0.025)


@pytest.fixture(scope="module")
def biased():
    return constant_rotation(seconds=60.0, bias=BIAS, seed=5)


@pytest.mark.parametrize(
    ("name", "params"), [("mahony", {"ki": 0.05}), ("adaptive_cf", {"bias_gain": 0.1})]
)
def test_estimates_a_known_gyro_bias(name, params, biased):
    res = estimate(name, biased["gyr"], biased["acc"], biased["mag"], biased["rate"], **params)
    final = res.gyro_bias[-500:].mean(axis=0)
    np.testing.assert_allclose(final, BIAS, atol=0.004)
    err = orientation_errors(res.quat, biased["quat"], np.arange(len(res.quat)) > 3000)
    assert err["total_rmse_deg"] < 2.0


def test_mahony_default_bias_gain_moves_towards_the_bias(biased):
    res = estimate("mahony", biased["gyr"], biased["acc"], biased["mag"], biased["rate"])
    assert np.all(np.sign(res.gyro_bias[-1]) == np.sign(BIAS))


@pytest.mark.parametrize("name", MINE)
def test_heading_stays_consistent_through_a_magnetic_disturbance(name):
    sig = constant_rotation(seconds=40.0, seed=2)
    mag = sig["mag"].copy()
    # 10 s next to a magnet: +25 µT along a fixed earth direction, so norm and dip both change
    bad = slice(1500, 2500)
    mag[bad] += rot.rotate(rot.conj(sig["quat"][bad]), np.array([20.0, -10.0, 12.0]))
    clean = estimate(name, sig["gyr"], sig["acc"], sig["mag"], sig["rate"])
    res = estimate(name, sig["gyr"], sig["acc"], mag, sig["rate"])
    assert res.mag_disturbed[1550:2450].mean() > 0.9
    assert res.mag_disturbed[500:1400].mean() < 0.1
    heading = error_angles(res.quat, sig["quat"])["heading"]
    assert heading[bad].max() < 3.0
    ref = error_angles(clean.quat, sig["quat"])["heading"]
    assert np.sqrt(np.mean(heading[bad] ** 2)) < np.sqrt(np.mean(ref[bad] ** 2)) + 1.0


@pytest.mark.parametrize("name", MINE)
def test_unusable_magnetometer_gives_a_6d_estimate(name):
    sig = constant_rotation(seconds=20.0)
    rng = np.random.default_rng(1)
    junk = 200.0 * rng.standard_normal(sig["mag"].shape)  # no earth field anywhere
    res = estimate(name, sig["gyr"], sig["acc"], junk, sig["rate"])
    assert res.extra["mag_used"] is False and res.mag_disturbed is None
    six = estimate(name, sig["gyr"], sig["acc"], None, sig["rate"])
    np.testing.assert_allclose(res.quat, six.quat, atol=1e-12)


def test_gain_changes_the_estimate_as_documented():
    # a larger Madgwick β trusts acc/mag more: less drift under a gyro bias, more noise at rest
    sig = constant_rotation(seconds=30.0, bias=(0.05, 0.0, 0.0), acc_noise=0.0, mag_noise=0.0)
    late = np.arange(3000) > 1500
    lo = estimate("madgwick", sig["gyr"], sig["acc"], sig["mag"], sig["rate"], beta=0.01)
    hi = estimate("madgwick", sig["gyr"], sig["acc"], sig["mag"], sig["rate"], beta=0.2)
    e_lo = orientation_errors(lo.quat, sig["quat"], late)["total_rmse_deg"]
    e_hi = orientation_errors(hi.quat, sig["quat"], late)["total_rmse_deg"]
    assert e_hi < 1.0 < e_lo


def test_field_used_in_tests_matches_the_enu_convention():
    # north-facing sensor at rest: mag has +y (north) and −z (down) components
    assert FIELD[1] > 0 and FIELD[2] < 0 and FIELD[0] == 0
