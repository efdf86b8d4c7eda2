"""Hinge-joint axis from the gyroscopes of the two adjacent segments, without any pose.

Seel, Raisch & Schauer (Sensors 2014 14:6891, eq. 1-4): for a hinge joint with unit axis ``j1`` in
sensor 1 and ``j2`` in sensor 2, the angular velocities' components perpendicular to the axis are
equal in size at every sample, ``‖g1 × j1‖ = ‖g2 × j2‖``, whatever the sensors' orientation and
the motion. ``j1``, ``j2`` in spherical coordinates minimise the sum of squared differences
(Gauss-Newton; here scipy's Levenberg-Marquardt with the analytic Jacobian of Seel's eq. 4,
``∂‖g × j‖/∂j = (‖g‖² j − (g·j) g) / ‖g × j‖``). The signs of ``j1`` and ``j2`` are not
observable from the constraint and are fixed with prior directions (the nominal mounting).

Samples where neither segment turns (below ``ACTIVE_FRACTION`` of the 95th-percentile rate)
carry no information about the axes and are left out; of the others at most ``MAX_SAMPLES``,
evenly spaced, enter the fit.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from motionlab.errors import InputError
from motionlab.minpack import lm

ACTIVE_FRACTION = 0.1
MAX_SAMPLES = 2000
MAX_EVALUATIONS = 100


def _unit(phi: float, theta: float) -> np.ndarray:
    return np.array([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])


def _tangents(phi: float, theta: float) -> tuple[np.ndarray, np.ndarray]:
    """∂j/∂φ and ∂j/∂θ of :func:`_unit`."""
    return (
        np.array([-np.sin(phi) * np.cos(theta), -np.sin(phi) * np.sin(theta), np.cos(phi)]),
        np.array([-np.cos(phi) * np.sin(theta), np.cos(phi) * np.cos(theta), 0.0]),
    )


def _angles(v: np.ndarray) -> tuple[float, float]:
    v = v / np.linalg.norm(v)
    return float(np.arcsin(np.clip(v[2], -1, 1))), float(np.arctan2(v[1], v[0]))


def _perpendicular(g: np.ndarray, gg: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, ...]:
    """‖g × j‖ (N,) for a unit ``j``, with ``g · j`` and the norm floored at 1e-12 (what its
    gradient, :func:`_gradient`, needs); ``gg`` is ``‖g‖²`` (N,)."""
    gj = g @ j
    norm = np.sqrt(np.maximum(gg - gj**2, 0.0))
    return norm, gj, np.maximum(norm, 1e-12)


def _gradient(g: np.ndarray, gg: np.ndarray, j: np.ndarray, gj: np.ndarray, safe: np.ndarray):
    """The gradient of ‖g × j‖ with respect to j (N, 3), Seel's eq. 4."""
    return (gg[:, None] * j - gj[:, None] * g) / safe[:, None]


def _active(g1: np.ndarray, g2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples where a segment turns, at most ``MAX_SAMPLES`` of them, evenly spaced."""
    rate = np.maximum(np.linalg.norm(g1, axis=1), np.linalg.norm(g2, axis=1))
    keep = rate >= ACTIVE_FRACTION * np.percentile(rate, 95)
    if keep.sum() >= 20:
        g1, g2 = g1[keep], g2[keep]
    stride = int(np.ceil(len(g1) / MAX_SAMPLES))
    return g1[::stride], g2[::stride]


def hinge_axes(
    gyr1: np.ndarray,
    gyr2: np.ndarray,
    prior1: np.ndarray | None = None,
    prior2: np.ndarray | None = None,
    n_starts: int = 6,
    seed: int = 0,
    loss: str = "linear",
    f_scale: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Joint axis in sensor 1 and sensor 2 coordinates (unit, (3,)) and the RMS residual (rad/s).

    ``gyr1``, ``gyr2`` are (N, 3) rad/s on one clock. The fit starts from the priors and from
    ``n_starts`` random directions (seeded) and keeps the best; signs follow the priors. The
    residual is over the samples used (see the module docstring). ``loss`` and ``f_scale``
    (rad/s) select a robust loss of scipy's ``least_squares`` (e.g. ``"soft_l1"``: samples off
    the hinge model weigh less); the default is plain least squares (Levenberg-Marquardt).
    """
    g1 = np.asarray(gyr1, float)
    g2 = np.asarray(gyr2, float)
    ok = np.all(np.isfinite(g1), axis=1) & np.all(np.isfinite(g2), axis=1)
    g1, g2 = g1[ok], g2[ok]
    if len(g1) < 20:
        raise InputError("too few samples for the hinge-axis fit", remedy="record more movement")
    g1, g2 = _active(g1, g2)

    gg = [np.einsum("ij,ij->i", g, g) for g in (g1, g2)]  # ‖g‖², the same at every step
    memo: dict[bytes, list] = {}

    def perpendicular(x: np.ndarray) -> list[tuple[np.ndarray, ...]]:
        """:func:`_perpendicular` of both segments at ``x``, once per ``x`` (the fit asks for
        the Jacobian where it has just evaluated the residual)."""
        key = x.tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = [
                _perpendicular(g, gg[k], _unit(x[2 * k], x[2 * k + 1]))
                for k, g in enumerate((g1, g2))
            ]
        return memo[key]

    def residual(x: np.ndarray) -> np.ndarray:
        (norm1, _, _), (norm2, _, _) = perpendicular(x)
        return norm1 - norm2

    def jacobian(x: np.ndarray) -> np.ndarray:
        out = np.empty((len(g1), 4))
        parts = perpendicular(x)
        for k, (g, sign) in enumerate(((g1, 1.0), (g2, -1.0))):
            phi, theta = x[2 * k], x[2 * k + 1]
            _, gj, safe = parts[k]
            grad = _gradient(g, gg[k], _unit(phi, theta), gj, safe)
            d_phi, d_theta = _tangents(phi, theta)
            out[:, 2 * k] = sign * (grad @ d_phi)
            out[:, 2 * k + 1] = sign * (grad @ d_theta)
        return out

    rng = np.random.default_rng(seed)
    starts = [rng.normal(size=6) for _ in range(n_starts)]
    if prior1 is not None and prior2 is not None:
        starts.insert(0, np.concatenate([prior1, prior2]))
    best = None
    for s in starts:
        x0 = np.array([*_angles(s[:3]), *_angles(s[3:])])
        if loss == "linear":
            fit = lm(residual, x0, jacobian, max_nfev=MAX_EVALUATIONS)  # least_squares' "lm"
        else:
            fit = least_squares(
                residual, x0, jac=jacobian, method="trf", loss=loss, f_scale=f_scale,
                max_nfev=MAX_EVALUATIONS,
            )  # fmt: skip
        if best is None or fit.cost < best.cost:
            best = fit
    j1, j2 = _unit(best.x[0], best.x[1]), _unit(best.x[2], best.x[3])
    if prior1 is not None and j1 @ prior1 < 0:
        j1 = -j1
    if prior2 is not None and j2 @ prior2 < 0:
        j2 = -j2
    rms = float(np.sqrt(np.mean(residual(best.x) ** 2)))
    return j1, j2, rms
