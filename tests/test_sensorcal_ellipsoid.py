"""Ellipsoid fits recover known offsets and soft-iron / gain matrices from simulated samples."""

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.sensorcal import coverage, fibonacci_sphere, fit_ellipsoid

FIELD = 50.0  # µT


def directions(n: int, rng: np.random.Generator, cap_deg: float = 180.0) -> np.ndarray:
    """Uniform unit vectors within ``cap_deg`` of +z (z uniform on the cap: equal areas)."""
    z = rng.uniform(np.cos(np.radians(cap_deg)), 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    r = np.sqrt(1 - z**2)
    return np.column_stack((r * np.cos(phi), r * np.sin(phi), z))


def distortion(rng: np.random.Generator, symmetric: bool = True) -> tuple[np.ndarray, np.ndarray]:
    a = np.eye(3) + rng.normal(0.0, 0.08, (3, 3))
    if symmetric:
        a = (a + a.T) / 2
    return a, rng.normal(0.0, 20.0, 3)


def test_full_sphere_recovers_offset_and_soft_iron():
    rng = np.random.default_rng(0)
    a, o = distortion(rng)
    y = FIELD * directions(3000, rng) @ a.T + o + rng.normal(0.0, 0.3, (3000, 3))
    fit = fit_ellipsoid(y, norm=FIELD)
    assert np.abs(fit.offset - o).max() < 0.05  # µT, noise 0.3 µT
    assert np.abs(fit.matrix - np.linalg.inv(a)).max() < 1e-3
    assert 0.25 < fit.residual_rms < 0.35
    assert fit.coverage > 0.95 and fit.norm == FIELD
    assert (fit.offset_sd < 0.05).all()
    corrected = np.linalg.norm(fit.apply(y), axis=1)
    assert abs(corrected.mean() - FIELD) < 0.02


def test_general_gain_matrix_is_recovered_up_to_a_rotation():
    rng = np.random.default_rng(1)
    a, o = distortion(rng, symmetric=False)
    y = FIELD * directions(3000, rng) @ a.T + o + rng.normal(0.0, 0.2, (3000, 3))
    fit = fit_ellipsoid(y)  # no field norm: det(matrix) = 1
    assert np.linalg.det(fit.matrix) == pytest.approx(1.0, abs=1e-9)
    assert fit.norm == pytest.approx(FIELD * np.linalg.det(a) ** (1 / 3), rel=1e-3)
    # matrix @ a maps true field vectors to corrected ones: a scaled rotation
    sv = np.linalg.svd(fit.matrix @ a, compute_uv=False)
    assert np.allclose(sv, fit.norm / FIELD, rtol=2e-3)
    assert np.allclose(fit.matrix, fit.matrix.T)
    assert np.abs(fit.offset - o).max() < 0.05


def test_partial_coverage_recovers_within_one_percent():
    rng = np.random.default_rng(2)
    a, o = distortion(rng)
    y = FIELD * directions(2000, rng, cap_deg=100.0) @ a.T + o + rng.normal(0.0, 0.3, (2000, 3))
    fit = fit_ellipsoid(y, norm=FIELD)
    assert 0.5 < fit.coverage < 0.75
    assert np.abs(fit.offset - o).max() < 0.01 * FIELD
    assert np.abs(fit.matrix - np.linalg.inv(a)).max() < 0.01
    # the reported uncertainty is honest: the errors are within 4 standard deviations
    assert (np.abs(fit.offset - o) < 4 * fit.offset_sd).all()


def test_accelerometer_from_static_poses():
    rng = np.random.default_rng(3)
    g = 9.80665
    k = np.eye(3) + np.tril(rng.normal(0.0, 0.01, (3, 3)))
    b = rng.normal(0.0, 0.1, 3)
    poses = np.repeat(g * directions(24, rng), 100, axis=0)
    y = poses @ k.T + b + rng.normal(0.0, 0.02, poses.shape)
    fit = fit_ellipsoid(y, norm=g, min_coverage=0.1)
    assert np.abs(fit.offset - b).max() < 0.01
    assert np.allclose(np.linalg.svd(fit.matrix @ k, compute_uv=False), 1.0, atol=1e-3)


def test_fibonacci_grid_and_coverage():
    grid = fibonacci_sphere(200)
    assert np.allclose(np.linalg.norm(grid, axis=1), 1.0)
    assert np.linalg.norm(grid.mean(axis=0)) < 0.01
    rng = np.random.default_rng(4)
    assert coverage(directions(5000, rng)) == 1.0
    assert 0.5 <= coverage(directions(5000, rng, 90.0)) <= 0.65  # cells straddle the rim
    ring = np.column_stack(
        (np.cos(np.linspace(0, 6.3, 500)), np.sin(np.linspace(0, 6.3, 500)), 0 * np.ones(500))
    )
    assert coverage(ring) < 0.25


@pytest.mark.parametrize(
    "case, message",
    [
        ("few", "only 10 samples"),
        ("nan", "NaN"),
        ("ring", "plane"),
        ("cap", "cover|ellipsoid|determined"),
        ("same", "identical"),
        ("shape", "expected N×3"),
    ],
)
def test_bad_inputs_raise_input_error(case, message):
    rng = np.random.default_rng(5)
    y = FIELD * directions(500, rng)
    if case == "few":
        y = y[:10]
    elif case == "nan":
        y[7, 1] = np.nan
    elif case == "ring":
        phi = rng.uniform(0, 2 * np.pi, 500)
        y = FIELD * np.column_stack((np.cos(phi), np.sin(phi), np.zeros(500))) + [3.0, 1.0, 2.0]
    elif case == "cap":
        y = FIELD * directions(500, rng, cap_deg=25.0) + rng.normal(0, 0.3, (500, 3))
    elif case == "same":
        y = np.tile([1.0, 2.0, 3.0], (100, 1))
    elif case == "shape":
        y = y[:, :2]
    with pytest.raises(InputError, match=message):
        fit_ellipsoid(y, name="mag")
