"""Ellipsoid fit of accelerometer or magnetometer samples: offset and full 3×3 correction.

Model (Ricci 2015, thesis eq. 2.10 and the "scalar calibration" eq. 2.17): a triaxial sensor in a
field of constant magnitude ``R`` (gravity, or the geomagnetic field) reads ``y = A v + o``
with ``|v| = R``: ``o`` is the offset (bias, hard iron) and ``A`` the gain matrix (scale factors,
axis misalignment, soft iron). The readings lie on the ellipsoid
``(y − o)ᵀ Cᵀ C (y − o) = R²`` with ``C = A⁻¹``, and the correction is

    v = C (y − o).

Only ``CᵀC`` is observable: a rotation of the corrected frame fits the data as well. We report
the symmetric positive-definite ``C`` (the polar factor), i.e. the correction with the least
rotation of the sensor axes.

Fit, in three steps, on samples centred and scaled for conditioning:

1. algebraic least squares for the quadric with the ellipsoid-specific constraint
   ``4J − I² = 1`` (Li & Griffiths, "Least squares ellipsoid specific fitting", GMP 2004),
   giving ``o = −A⁻¹b`` and ``C = (A / (oᵀAo − d))^{1/2}``;
2. Levenberg–Marquardt (:func:`scipy.optimize.least_squares`) on the residuals
   ``|C (y − o)| − 1`` over the 9 parameters (offset, upper triangle of the symmetric ``C``),
   with the analytic Jacobian;
3. the same, with each sample weighted by the inverse of the number of samples in its
   direction cell, so every direction counts once: a recording spends most of its time at rest
   in one orientation, and without the balance those samples pull the fit (on BROAD the
   magnetometer offsets of two trials of one sensor differed by 4 µT unbalanced, 0.3 µT
   balanced).

``R`` is the given field norm (``g`` for an accelerometer, a known local geomagnetic field for a
magnetometer); without one, ``det C = 1``, which keeps the sensor's mean gain and reports ``R``
as the measured field norm.

Quality: residual RMS of ``|v| − R`` (sensor units), coverage (the fraction of a Fibonacci grid
of directions whose nearest-direction cell holds a corrected sample), the field norm, and the
parameters' standard deviations from the Jacobian at the solution (for white residuals: a lower
bound when the field is not quite homogeneous).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import sqrtm
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from motionlab.errors import InputError
from motionlab.sensorcal._validate import samples3

_TRIU = np.triu_indices(3)
MAX_NFEV = 200  # a well-posed fit converges in about ten iterations
_REMEDY = "rotate the sensor slowly through as many orientations as possible"


@dataclass
class EllipsoidFit:
    """Result of :func:`fit_ellipsoid`; apply it with ``v = matrix @ (y − offset)``.

    Attributes
    ----------
    offset
        (3,) offset ``o`` in sensor units.
    matrix
        (3, 3) symmetric positive-definite correction ``C``.
    norm
        Field norm ``R`` after correction (sensor units).
    residual_rms
        RMS of ``|C (y − o)| − R`` over the samples (sensor units).
    coverage
        Fraction (0–1) of the direction grid hit by the corrected samples.
    offset_sd, matrix_sd
        (3,) and (3, 3) standard deviations of the estimates (sensor units and dimensionless).
    n_samples
        Number of samples fitted.
    """

    offset: np.ndarray
    matrix: np.ndarray
    norm: float
    residual_rms: float
    coverage: float
    offset_sd: np.ndarray
    matrix_sd: np.ndarray
    n_samples: int

    def apply(self, y: np.ndarray) -> np.ndarray:
        """Corrected samples (N, 3) from raw samples (N, 3)."""
        return (np.asarray(y, dtype=float) - self.offset) @ self.matrix.T

    def quality(self) -> dict[str, Any]:
        """JSON-able quality figures."""
        return {
            "residual_rms": self.residual_rms,
            "coverage": round(self.coverage, 4),
            "norm": self.norm,
            "n_samples": self.n_samples,
            "offset_sd": self.offset_sd.tolist(),
            "matrix_sd_max": float(self.matrix_sd.max()),
        }


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) nearly uniform unit directions on the golden-angle (Fibonacci) spiral."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z**2)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.column_stack((r * np.cos(phi), r * np.sin(phi), z))


def coverage(directions: np.ndarray, n_grid: int = 100) -> float:
    """Fraction of a ``n_grid``-direction Fibonacci grid whose cell holds one of ``directions``.

    A cell is the set of directions nearer to its grid point than to any other (about
    ``sqrt(4π/n_grid)`` rad across: 20° for 100 points). With 100 points a full turn about one
    axis covers about 0.2, a hemisphere about 0.6 (rim cells count), the whole sphere 1.
    """
    u = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    _, idx = cKDTree(fibonacci_sphere(n_grid)).query(u)
    return len(np.unique(idx)) / n_grid


def _sym(p: np.ndarray) -> np.ndarray:
    c = np.zeros((3, 3))
    c[_TRIU] = p
    return c + np.triu(c, 1).T


def _algebraic(x: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Li & Griffiths (2004) ellipsoid-specific fit: offset and unit-sphere ``C``, or None."""
    cross = 2 * x[:, [1, 0, 0]] * x[:, [2, 2, 1]]  # 2yz, 2xz, 2xy
    d = np.column_stack((x**2, cross, 2 * x, np.ones(len(x))))
    s = d.T @ d
    s11, s12, s22 = s[:6, :6], s[:6, 6:], s[6:, 6:]
    k = 4.0
    c1 = np.full((3, 3), k / 2 - 1) - (k / 2) * np.eye(3)
    cons = np.zeros((6, 6))
    cons[:3, :3] = c1
    cons[3:, 3:] = -k * np.eye(3)
    try:
        t = -np.linalg.solve(s22, s12.T)
        vals, vecs = np.linalg.eig(np.linalg.solve(cons, s11 + s12 @ t))
    except np.linalg.LinAlgError:
        return None
    vals = np.real(vals)
    if not (vals > 0).any():
        return None
    v1 = np.real(vecs[:, int(np.argmax(vals))])
    v = np.concatenate((v1, t @ v1))
    a = np.array([[v[0], v[5], v[4]], [v[5], v[1], v[3]], [v[4], v[3], v[2]]])
    try:
        o = -np.linalg.solve(a, v[6:9])
    except np.linalg.LinAlgError:
        return None
    scale = o @ a @ o - v[9]
    m = a / scale
    if not np.isfinite(m).all() or np.linalg.eigvalsh(m).min() <= 0:
        return None
    return o, np.real(sqrtm(m))


def _residuals(p: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.linalg.norm((x - p[:3]) @ _sym(p[3:]), axis=1) - 1.0


def _jacobian(p: np.ndarray, x: np.ndarray) -> np.ndarray:
    c = _sym(p[3:])
    d = x - p[:3]
    u = d @ c  # C symmetric: rows are C d
    n = np.linalg.norm(u, axis=1, keepdims=True)
    g = u / n  # d|u|/du
    jac = np.empty((len(x), 9))
    jac[:, :3] = -(g @ c)
    for col, (i, j) in enumerate(zip(*_TRIU, strict=True)):
        jac[:, 3 + col] = g[:, i] * d[:, j] + (g[:, j] * d[:, i] if i != j else 0.0)
    return jac


def _refine(x: np.ndarray, p0: np.ndarray, weights: np.ndarray, name: str):
    """Levenberg–Marquardt on the weighted residuals; :class:`InputError` if it fails."""
    w = np.sqrt(weights)
    sol = least_squares(
        lambda p: w * _residuals(p, x),
        p0,
        jac=lambda p: w[:, None] * _jacobian(p, x),
        method="lm",
        xtol=1e-12,
        max_nfev=MAX_NFEV,
    )
    ok = sol.success and np.isfinite(sol.x).all()
    if not ok or np.linalg.eigvalsh(_sym(sol.x[3:])).min() <= 0:
        raise InputError(
            "the samples do not fit an ellipsoid",
            where=name,
            remedy=_REMEDY,
        )
    return sol


def _cell_weights(x: np.ndarray, p: np.ndarray, n_grid: int) -> np.ndarray:
    """Weights (mean 1) giving every occupied direction cell the same total weight."""
    u = (x - p[:3]) @ _sym(p[3:])
    _, idx = cKDTree(fibonacci_sphere(n_grid)).query(u / np.linalg.norm(u, axis=1, keepdims=True))
    w = 1.0 / np.bincount(idx, minlength=n_grid)[idx]
    return w / w.mean()


def fit_ellipsoid(
    samples: np.ndarray,
    norm: float | None = None,
    min_coverage: float = 0.3,
    max_sd: float = 0.02,
    n_grid: int = 100,
    balance: bool = True,
    name: str = "samples",
) -> EllipsoidFit:
    """Fit offset and symmetric correction matrix to samples of a constant-magnitude field.

    Parameters
    ----------
    samples
        (N, 3) raw readings in sensor units (m/s² or µT), N ≥ 20, spread over many directions.
    norm
        Field norm after correction (e.g. 9.81 m/s²); None keeps ``det C = 1``.
    min_coverage
        Least fraction of the direction grid the data must cover (:func:`coverage`).
    max_sd
        Largest accepted standard deviation of an estimate, relative to the field norm (offset)
        or absolute (matrix entries); a larger one means the data do not determine the fit.
    n_grid
        Number of grid directions for the coverage and the balance.
    balance
        Refit with every occupied direction cell weighted equally, so that long stays in one
        orientation (rest) do not outweigh the rest of the sphere.
    name
        Where the samples come from, for error messages.

    Returns
    -------
    EllipsoidFit

    Raises
    ------
    InputError
        Too few samples, NaN, samples in a plane or a small patch (coverage), a fit that is
        not an ellipsoid or is poorly determined.
    """
    y = samples3(samples, name, 20, "rotate the sensor through many orientations")
    remedy = _REMEDY
    mu = y.mean(axis=0)
    s = np.sqrt(np.mean(np.sum((y - mu) ** 2, axis=1)))
    if not s > 0:
        raise InputError("all samples are identical", where=name, remedy=remedy)
    x = (y - mu) / s
    sv = np.linalg.svd(x - x.mean(axis=0), compute_uv=False)
    if sv[-1] < 1e-3 * sv[0]:
        raise InputError(
            "samples lie in a plane: the ellipsoid is undetermined", where=name, remedy=remedy
        )
    start = _algebraic(x)
    if start is None:
        start = (np.zeros(3), np.eye(3))
    sol = _refine(x, np.concatenate((start[0], start[1][_TRIU])), np.ones(len(x)), name)
    if balance:
        sol = _refine(x, sol.x, _cell_weights(x, sol.x, n_grid), name)
    c = _sym(sol.x[3:])
    offset = mu + s * sol.x[:3]
    c_unit = c / s  # maps y − offset onto the unit sphere
    radius = float(norm) if norm is not None else float(np.linalg.det(c_unit) ** (-1 / 3))
    matrix = radius * c_unit
    corrected = (y - offset) @ matrix.T
    cov_ok = coverage(corrected, n_grid)
    if cov_ok < min_coverage:
        raise InputError(
            f"samples cover {cov_ok:.0%} of the directions, need {min_coverage:.0%}",
            where=name,
            remedy=remedy,
        )
    res = np.linalg.norm(corrected, axis=1) - radius
    sigma2 = float(np.sum(sol.fun**2) / max(len(y) - 9, 1))
    jtj = sol.jac.T @ sol.jac
    with np.errstate(divide="ignore", invalid="ignore"):
        cov = np.linalg.pinv(jtj) * sigma2 if np.linalg.cond(jtj) < 1e14 else None
    if cov is None:
        raise InputError("the data do not determine the fit", where=name, remedy=remedy)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    offset_sd = s * sd[:3]
    matrix_sd = radius / s * _sym(sd[3:])
    worst = max(float(offset_sd.max() / radius), float(matrix_sd.max()))
    if worst > max_sd:
        raise InputError(
            f"the fit is poorly determined (relative standard deviation {worst:.3f})",
            where=name,
            remedy=remedy,
        )
    return EllipsoidFit(
        offset=offset,
        matrix=matrix,
        norm=radius,
        residual_rms=float(np.sqrt(np.mean(res**2))),
        coverage=cov_ok,
        offset_sd=offset_sd,
        matrix_sd=matrix_sd,
        n_samples=len(y),
    )
