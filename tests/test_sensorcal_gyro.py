"""Gyroscope bias from the rest windows of a recording with motion between them."""

import numpy as np
import pytest
from sensorcal_signals import measure, random_poses, trajectory

from motionlab.errors import InputError
from motionlab.sensorcal import gyro_bias

BIAS = np.radians([1.5, -0.8, 0.6])  # 1.5 °/s: close to the 2 °/s rest threshold on purpose


def recording(hold: float = 6.0, tumble: float = 0.0, seed: int = 0):
    t, q, w = trajectory(random_poses(4, seed=seed), hold=hold, move=2.0, tumble=tumble)
    return t, measure(q, w, seed=seed, gyr_bias=BIAS, noise=(0.005, 0.03, 0.2))


def test_bias_from_rest_windows_between_movements():
    t, sig = recording()
    fit = gyro_bias(sig["gyr"], sig["acc"], 100.0, t)
    assert (np.abs(fit.bias - BIAS) < 4 * fit.std_error).all()
    # 0.005 rad/s noise over ~2000 rest samples
    assert np.allclose(fit.noise, 0.005, rtol=0.1)
    assert np.allclose(fit.std_error, 0.005 / np.sqrt(fit.mask.sum()), rtol=0.1)
    assert len(fit.windows) == 4 and 20.0 <= fit.rest_s <= 24.0
    # every window lies inside a hold (the holds start every 8 s and last 6 s)
    starts = fit.windows[:, 0] % 8.0
    ends = fit.windows[:, 1] % 8.0
    assert (starts < ends).all() and (ends <= 6.0).all()
    assert np.abs(fit.spread).max() < np.radians(0.05)
    assert fit.quality()["n_windows"] == 4


def test_gyroscope_alone_judges_rest():
    t, sig = recording(seed=1)
    fit = gyro_bias(sig["gyr"], None, 100.0)
    assert (np.abs(fit.bias - BIAS) < 4 * fit.std_error).all()
    assert fit.std_error.max() < np.radians(0.01)


def test_turning_at_constant_rate_is_not_rest():
    # a steady 10 °/s spin about the vertical keeps the accelerometer still
    n = 3000
    gyr = np.tile(np.radians([0.0, 0.0, 10.0]), (n, 1)) + BIAS
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    with pytest.raises(InputError, match="at rest"):
        gyro_bias(gyr, acc, 100.0)


@pytest.mark.parametrize(
    "case, message", [("moving", "at rest"), ("nan", "NaN"), ("length", "acc")]
)
def test_bad_inputs_raise(case, message):
    t, sig = recording(hold=0.5, tumble=20.0)
    gyr, acc = sig["gyr"], sig["acc"]
    if case == "nan":
        t, sig = recording()
        gyr, acc = sig["gyr"].copy(), sig["acc"]
        gyr[100] = np.nan
    elif case == "length":
        acc = acc[:-5]
    with pytest.raises(InputError, match=message):
        gyro_bias(gyr, acc, 100.0)


def test_simulated_session_biases():
    simulate = pytest.importorskip("motionlab.simulate")
    ses, truth = simulate.simulate("knee", duration=40, seed=0, calibration=False)
    for seg, s in ses.sensors.items():
        fit = gyro_bias(s.gyr, s.acc, s.rate_hz, s.time)
        true_bias = truth.sensors[seg]["gyr_bias"][fit.mask].mean(axis=0)
        assert len(fit.windows) >= 3 and fit.rest_s > 8.0
        # 0.5 °/s biases recovered to 0.02 °/s (white-noise standard error ≈ 0.003 °/s)
        assert np.abs(fit.bias - true_bias).max() < np.radians(0.02), seg
