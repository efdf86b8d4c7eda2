"""Multi-position accelerometer calibration recovers a known bias, scale and misalignment."""

import numpy as np
import pytest
from sensorcal_signals import G, axis_poses, measure, random_poses, trajectory

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.sensorcal import find_poses, multiposition


def truth(rng, lower: bool):
    scale = 1.0 + rng.normal(0.0, 0.01, 3)
    mis = rng.normal(0.0, 0.01, (3, 3))
    np.fill_diagonal(mis, 0.0)
    if lower:
        mis = np.tril(mis)
    return rng.normal(0.0, 0.15, 3), scale, mis


def poses_up(q: np.ndarray) -> np.ndarray:
    return rot.rotate(rot.conj(q), np.array([0.0, 0.0, G]))


def test_norm_method_recovers_bias_scale_and_lower_misalignment():
    rng = np.random.default_rng(0)
    b, s, m = truth(rng, lower=True)
    k = (np.eye(3) + m) @ np.diag(s)
    f = poses_up(random_poses(14, seed=1))
    y = f @ k.T + b + rng.normal(0.0, 1e-3, f.shape)  # pose means: 1 mm/s² noise
    fit = multiposition(y)
    assert fit.method == "norm" and fit.n_poses == 14
    assert np.abs(fit.bias - b).max() < 3e-3
    assert np.abs(fit.scale - s).max() < 3e-4
    assert np.abs(fit.misalignment - m).max() < 3e-4
    assert np.allclose(np.triu(fit.misalignment), 0.0)
    assert fit.residual_rms < 2e-3
    corrected = (y - fit.bias) @ fit.matrix.T
    assert np.abs(np.linalg.norm(corrected, axis=1) - G).max() < 5e-3


def test_six_position_recovers_full_misalignment():
    rng = np.random.default_rng(2)
    b, s, m = truth(rng, lower=False)
    k = (np.eye(3) + m) @ np.diag(s)
    f = poses_up(axis_poses())
    y = f @ k.T + b + rng.normal(0.0, 1e-3, f.shape)
    fit = multiposition(y)  # six axis-aligned poses: auto picks the nominal solver
    assert fit.method == "nominal"
    assert np.abs(fit.bias - b).max() < 2e-3
    assert np.abs(fit.scale - s).max() < 3e-4
    assert np.abs(fit.misalignment - m).max() < 3e-4
    assert np.allclose(fit.gain, k, atol=3e-4)


def test_poses_found_in_a_recording():
    rng = np.random.default_rng(3)
    b, s, m = truth(rng, lower=True)
    k = (np.eye(3) + m) @ np.diag(s)
    _, q, w = trajectory(random_poses(12, seed=4), hold=3.0, move=1.5)
    sig = measure(q, w, seed=5, gyr_bias=np.radians([1.0, -0.5, 0.8]), acc_gain=k, acc_bias=b)
    poses, counts = find_poses(sig["acc"], sig["gyr"], 100.0)
    assert len(poses) == 12 and (counts > 150).all()
    fit = multiposition(poses, weights=counts)
    assert fit.method == "norm"  # pose means carry 1.2 mm/s² of noise (0.02 / √260)
    assert np.abs(fit.bias - b).max() < 5e-3
    assert np.abs(fit.scale - s).max() < 1e-3
    assert np.abs(fit.misalignment - m).max() < 1e-3


@pytest.mark.parametrize(
    "case, message",
    [
        ("five", "only 5 poses"),
        ("seven_tilted", "distinct poses"),
        ("plane", "do not determine"),
        ("nan", "NaN"),
        ("nominal_tilted", "from every ±axis"),
        ("method", "unknown method"),
        ("weights", "weights"),
    ],
)
def test_bad_poses_raise_input_error(case, message):
    rng = np.random.default_rng(6)
    y = poses_up(random_poses(12, seed=7)) + rng.normal(0, 1e-3, (12, 3))
    kwargs = {}
    if case == "five":
        y = y[:5]
    elif case == "seven_tilted":
        y = y[:7]
    elif case == "plane":  # every pose a turn about the sensor x axis
        phi = np.linspace(0, 2 * np.pi, 12, endpoint=False)
        y = G * np.column_stack((np.zeros(12), np.cos(phi), np.sin(phi)))
        kwargs["method"] = "norm"
        y = np.vstack((y, y[:3] * 0.999))  # 15 rows, all in the y–z plane
    elif case == "nan":
        y[3, 0] = np.nan
    elif case == "nominal_tilted":
        kwargs["method"] = "nominal"
    elif case == "method":
        kwargs["method"] = "best"
    elif case == "weights":
        kwargs["weights"] = np.ones(3)
    with pytest.raises(InputError, match=message):
        multiposition(y, **kwargs)
