"""Multi-position accelerometer calibration: bias, scale factors and axis misalignment.

Model (Ricci 2015, thesis eqs. 2.2–2.4): a static accelerometer reads
``y = K f + b + n`` with ``K = M S``, ``S = diag(s_x, s_y, s_z)`` the scale factors and ``M``
the cross-coupling matrix with unit diagonal and off-diagonal ``α_ij`` (rad, small angles). At
rest the specific force ``f`` is gravity, ``|f| = g`` (Lötters 1998; thesis §2.2). The
correction is ``f = K⁻¹ (y − b)``.

Two solvers, from the mean reading of each static pose:

- ``"nominal"``: the poses are known directions of ``f`` in the housing frame (the classic
  six-position test: each axis up and down against a levelled surface). ``y = K f + b`` is linear
  in ``K`` and ``b``: least squares over all poses, full ``M`` (six ``α``). Needs poses whose
  directions span 3-D with an offset (rank 4), at least six.
- ``"norm"``: unknown pose orientations (Tedaldi, Pretto & Menegatti, ICRA 2014; Fong 2008):
  Levenberg–Marquardt on ``|K⁻¹ (y_i − b)| − g``. Only ``KᵀK`` is observable from norms, so ``K``
  is kept lower triangular: the calibrated x axis is the sensor x axis and the calibrated y axis
  lies in the plane of the sensor x and y axes; ``M`` then has three ``α`` (below the diagonal).
  Needs at least nine poses in well-spread orientations.

``"auto"`` takes ``"norm"`` with nine or more distinct poses, otherwise ``"nominal"`` when every
pose is within ``axis_tol`` of a ±axis and all six appear.

Units: m/s², rad.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from motionlab.errors import InputError
from motionlab.fusion.rest import find_rest
from motionlab.sensorcal._validate import positive_rate, samples3
from motionlab.timebase import runs
from motionlab.units import STANDARD_GRAVITY

_TRIL = np.tril_indices(3)
_REMEDY = "hold the sensor still (≥ 2 s) in six or more orientations, e.g. each axis up and down"


@dataclass
class MultiPositionFit:
    """Result of :func:`multiposition`; apply it with ``f = matrix @ (y − bias)``.

    Attributes
    ----------
    bias
        (3,) m/s².
    scale
        (3,) scale factors ``diag(S)`` (1 = nominal gain).
    misalignment
        (3, 3) ``M − I``: the off-diagonal cross-coupling ``α_ij``, rad.
    method
        ``"nominal"`` or ``"norm"``.
    residual_rms
        RMS of ``|f| − g`` over the poses, m/s².
    n_poses
        Number of poses used.
    """

    bias: np.ndarray
    scale: np.ndarray
    misalignment: np.ndarray
    method: str
    residual_rms: float
    n_poses: int

    @property
    def gain(self) -> np.ndarray:
        """(3, 3) ``K = M S``."""
        return (np.eye(3) + self.misalignment) @ np.diag(self.scale)

    @property
    def matrix(self) -> np.ndarray:
        """(3, 3) correction ``K⁻¹``."""
        return np.linalg.inv(self.gain)

    def quality(self) -> dict[str, Any]:
        """JSON-able quality figures and the model terms."""
        return {
            "method": self.method,
            "n_poses": self.n_poses,
            "residual_rms": self.residual_rms,
            "scale": self.scale.tolist(),
            "misalignment_rad": self.misalignment.tolist(),
        }


def find_poses(
    acc: np.ndarray, gyr: np.ndarray | None, rate: float, min_duration: float = 2.0
) -> tuple[np.ndarray, np.ndarray]:
    """Mean accelerometer reading (P, 3) and sample count (P,) of each static pose.

    Poses are the rest windows (bias-tolerant detector, :mod:`motionlab.fusion.rest`) of at
    least ``min_duration`` s; without ``gyr`` only the accelerometer judges rest.
    """
    rate = positive_rate(rate)
    acc = samples3(acc, "acc", 2)
    gyr = np.zeros_like(acc) if gyr is None else samples3(gyr, "gyr", len(acc))
    mask = find_rest(gyr, acc, rate, min_duration=min_duration)
    idx = runs(mask)
    means = np.array([acc[a:b].mean(axis=0) for a, b in idx]).reshape(-1, 3)
    return means, (idx[:, 1] - idx[:, 0]).astype(int)


def distinct_directions(y: np.ndarray, min_angle: float = np.deg2rad(10.0)) -> int:
    """Number of directions among the rows of ``y`` at least ``min_angle`` rad apart (greedy)."""
    u = y / np.linalg.norm(y, axis=1, keepdims=True)
    kept: list[np.ndarray] = []
    for v in u:
        if all(v @ k < np.cos(min_angle) for k in kept):
            kept.append(v)
    return len(kept)


def _nominal_directions(y: np.ndarray, axis_tol: float) -> np.ndarray | None:
    """Unit ±axis nearest each pose, or None if a pose is further than ``axis_tol`` rad away."""
    u = y / np.linalg.norm(y, axis=1, keepdims=True)
    axis = np.argmax(np.abs(u), axis=1)
    cos = np.abs(u[np.arange(len(u)), axis])
    if (cos < np.cos(axis_tol)).any():
        return None
    f = np.zeros_like(u)
    f[np.arange(len(u)), axis] = np.sign(u[np.arange(len(u)), axis])
    return f


def _split(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    scale = np.diag(k).copy()
    return scale, k / scale - np.eye(3)


def _fit_nominal(y: np.ndarray, f: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, ...]:
    design = np.column_stack((f, np.ones(len(f))))
    if np.linalg.matrix_rank(design) < 4:
        raise InputError("the pose directions do not span 3-D", where="acc poses", remedy=_REMEDY)
    w = np.sqrt(weights)[:, None]
    sol, *_ = np.linalg.lstsq(design * w, y * w, rcond=None)
    return sol[:3].T, sol[3]


def _norm_residuals(p: np.ndarray, y: np.ndarray, g: float) -> np.ndarray:
    k = np.zeros((3, 3))
    k[_TRIL] = p[3:]
    return np.linalg.norm(np.linalg.solve(k, (y - p[:3]).T), axis=0) - g


def _fit_norm(y: np.ndarray, g: float, weights: np.ndarray) -> tuple[np.ndarray, ...]:
    w = np.sqrt(weights / weights.mean())
    p0 = np.concatenate((np.zeros(3), (np.eye(3) * np.mean(np.linalg.norm(y, axis=1)) / g)[_TRIL]))
    sol = least_squares(lambda p: w * _norm_residuals(p, y, g), p0, method="lm", xtol=1e-14)
    jtj = sol.jac.T @ sol.jac
    if np.linalg.cond(jtj) > 1e10:
        raise InputError(
            "the poses do not determine bias, scale and misalignment",
            where="acc poses",
            remedy=_REMEDY,
        )
    k = np.zeros((3, 3))
    k[_TRIL] = sol.x[3:]
    return k, sol.x[:3]


def multiposition(
    poses: np.ndarray,
    gravity: float = STANDARD_GRAVITY,
    method: str = "auto",
    weights: np.ndarray | None = None,
    axis_tol: float = np.deg2rad(20.0),
) -> MultiPositionFit:
    """Accelerometer bias, scale factors and misalignment from static poses.

    Parameters
    ----------
    poses
        (P, 3) mean accelerometer reading of each static pose, m/s² (:func:`find_poses`).
    gravity
        Local gravity, m/s².
    method
        ``"auto"``, ``"norm"`` or ``"nominal"`` (see the module docstring).
    weights
        (P,) relative weight of each pose (e.g. its sample count); default equal.
    axis_tol
        Largest angle (rad) between a pose and its ±axis for ``"nominal"``.

    Returns
    -------
    MultiPositionFit
    """
    y = samples3(poses, "acc poses", 6, _REMEDY, what="poses")
    w = np.ones(len(y)) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (len(y),) or not (w > 0).all():
        raise InputError("weights must be positive, one per pose", where="weights")
    if method not in ("auto", "norm", "nominal"):
        raise InputError(f"unknown method {method!r}", where="method", remedy="auto, norm, nominal")
    n_distinct = distinct_directions(y)
    nominal = _nominal_directions(y, axis_tol)
    if method == "auto":
        six = nominal is not None and len(np.unique(nominal, axis=0)) == 6
        method = "norm" if n_distinct >= 9 else "nominal" if six else ""
        if not method:
            raise InputError(
                f"{n_distinct} distinct poses: need nine, or the six axis-up/axis-down poses",
                where="acc poses",
                remedy=_REMEDY,
            )
    if method == "nominal":
        if nominal is None:
            raise InputError(
                f"a pose is more than {np.degrees(axis_tol):.0f}° from every ±axis",
                where="acc poses",
                remedy="align each axis with gravity, or use method 'norm'",
            )
        k, b = _fit_nominal(y, nominal * gravity, w)
    else:
        if n_distinct < 9:
            raise InputError(
                f"{n_distinct} distinct poses, need nine for method 'norm'",
                where="acc poses",
                remedy=_REMEDY,
            )
        k, b = _fit_norm(y, gravity, w)
    scale, mis = _split(k)
    res = np.linalg.norm(np.linalg.solve(k, (y - b).T), axis=0) - gravity
    return MultiPositionFit(
        bias=b,
        scale=scale,
        misalignment=mis,
        method=method,
        residual_rms=float(np.sqrt(np.mean(res**2))),
        n_poses=len(y),
    )
