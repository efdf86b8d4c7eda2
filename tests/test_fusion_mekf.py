"""Multiplicative EKF (``mekf``) and its RTS smoother (``smoother``, the default estimator)."""

import h5py
import numpy as np
import pytest
from conftest import SHARED, needs_shared
from fusion_signals import FIELD, G, constant_rotation, heading_aligned, wrong_start

from motionlab import rotations as rot
from motionlab.fusion import DEFAULT_ESTIMATOR, estimate
from motionlab.validation.orientation_error import error_angles, orientation_errors


def _rest_then_motion(
    seconds_rest=5.0, seconds_move=40.0, rate=100.0, bias=(0.0, 0.0, 0.0), seed=1
):
    """Rest, a tumbling motion with a varying rate, rest again: truth and noisy signals."""
    rng = np.random.default_rng(seed)
    n_rest, n_move = int(seconds_rest * rate), int(seconds_move * rate)
    t = np.arange(n_move) / rate
    omega = np.stack(
        [1.2 * np.sin(0.7 * t), 0.8 * np.sin(1.1 * t + 1.0), 1.5 * np.sin(0.4 * t + 2.0)], axis=1
    )
    omega = np.concatenate([np.zeros((n_rest, 3)), omega, np.zeros((n_rest, 3))])
    q0 = rot.from_axis_angle([0.3, -1.0, 0.2], 0.6)
    quat = rot.integrate_gyro(q0, omega, 1.0 / rate)
    n = len(quat)
    acc = rot.rotate(rot.conj(quat), np.array([0.0, 0.0, G]))
    mag = rot.rotate(rot.conj(quat), FIELD)
    return {
        "gyr": omega + np.asarray(bias) + 0.005 * rng.standard_normal((n, 3)),
        "acc": acc + 0.1 * rng.standard_normal((n, 3)),
        "mag": mag + 0.5 * rng.standard_normal((n, 3)),
        "quat": quat,
        "rate": rate,
    }


def test_smoother_is_the_default():
    assert DEFAULT_ESTIMATOR == "smoother"


@pytest.mark.parametrize("name", ["mekf", "smoother"])
def test_converges_from_a_90_degree_wrong_start(name):
    sig = wrong_start(constant_rotation(seconds=60.0, omega=(0.2, -0.1, 0.3)))
    res = estimate(name, sig["gyr"], sig["acc"], sig["mag"], rate=sig["rate"])
    err = error_angles(res.quat, sig["quat"])["total"]
    if name == "mekf":
        assert err[0] > 80.0
    # the defaults average slowly (tuned for BROAD): within 20° after 10 s, 5.5° after 40 s
    assert np.max(err[1000:]) < 20.0
    assert np.max(err[4000:]) < 5.5


@pytest.mark.parametrize("name", ["mekf", "smoother"])
def test_tracks_a_constant_rate_rotation(name):
    sig = constant_rotation(seconds=30.0, omega=(0.3, -0.2, 0.5))
    res = estimate(name, sig["gyr"], sig["acc"], sig["mag"], rate=sig["rate"])
    err = orientation_errors(res.quat, sig["quat"])
    assert err["total_rmse_deg"] < 1.0
    assert err["inclination_rmse_deg"] < 0.5


@pytest.mark.parametrize("name", ["mekf", "smoother"])
def test_estimates_a_constant_gyro_bias(name):
    bias = (0.02, 0.0, 0.0)
    sig = _rest_then_motion(bias=bias)
    res = estimate(name, sig["gyr"], sig["acc"], sig["mag"], rate=sig["rate"])
    # the last rest phase: within 0.5 mrad/s of the truth on every axis
    np.testing.assert_allclose(res.gyro_bias[-100:].mean(axis=0), bias, atol=5e-4)
    assert res.rest[:400].all() and not res.rest[1000:4000].any()


def test_smoother_beats_the_forward_filter():
    sig = _rest_then_motion(bias=(0.01, -0.01, 0.005), seed=3)
    sig["acc"] = sig["acc"] + 0.5 * np.random.default_rng(4).standard_normal(sig["acc"].shape)
    fwd = estimate("mekf", sig["gyr"], sig["acc"], sig["mag"], rate=sig["rate"])
    smo = estimate("smoother", sig["gyr"], sig["acc"], sig["mag"], rate=sig["rate"])
    e_f = orientation_errors(fwd.quat, sig["quat"])["total_rmse_deg"]
    e_s = orientation_errors(smo.quat, sig["quat"])["total_rmse_deg"]
    assert e_s <= e_f
    assert e_s < 1.0


@pytest.mark.parametrize("name", ["mekf", "smoother"])
def test_6d_heading_stays_fixed(name):
    sig = _rest_then_motion(bias=(0.0, 0.0, 0.01), seed=5)
    res = estimate(name, sig["gyr"], sig["acc"], None, rate=sig["rate"])
    assert res.mag_disturbed is None
    aligned = heading_aligned(res.quat, sig["quat"], np.ones(len(res.quat), dtype=bool))
    err = error_angles(aligned, sig["quat"])
    assert np.max(err["heading"]) < 1.5
    assert np.sqrt(np.mean(err["inclination"] ** 2)) < 0.5


@pytest.mark.parametrize("name", ["mekf", "smoother"])
def test_magnetic_disturbance_does_not_tilt(name):
    sig = constant_rotation(seconds=40.0, omega=(0.2, -0.3, 0.25), seed=2)
    # a 40 µT step in the earth-frame field (a magnet nearby) from 15 s to 25 s
    step = np.zeros((len(sig["quat"]), 3))
    step[1500:2500] = [30.0, 0.0, 25.0]
    mag = sig["mag"] + rot.rotate(rot.conj(sig["quat"]), step)
    res = estimate(name, sig["gyr"], sig["acc"], mag, rate=sig["rate"])
    err = error_angles(res.quat, sig["quat"])
    assert res.mag_disturbed[1520:2480].all() and not res.mag_disturbed[500:1490].any()
    assert np.max(err["inclination"][1000:]) < 0.5
    assert np.max(err["heading"][1000:]) < 2.0


@needs_shared
def test_broad_smoother_accuracy():
    totals = []
    for trial in ("02_undisturbed_slow_rotation_B", "24_disturbed_tapping_A"):
        with h5py.File(SHARED / "datasets" / "broad" / f"{trial}.hdf5", "r") as f:
            gyr, acc, mag = f["imu_gyr"][:], f["imu_acc"][:], f["imu_mag"][:]
            ref, mask, rate = f["opt_quat"][:], f["movement"][:], f.attrs["sampling_rate"]
        res = estimate("default", gyr, acc, mag, rate=rate)
        totals.append(orientation_errors(res.quat, ref, mask.astype(bool))["total_rmse_deg"])
    # measured 0.56° and 0.93° (offline VQF: 1.01°, 1.16°)
    assert np.mean(totals) < 1.0
