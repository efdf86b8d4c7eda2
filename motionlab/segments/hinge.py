"""Hinge-joint axis from the gyroscopes of the two adjacent segments, without any pose.

Seel, Raisch & Schauer (Sensors 2014 14:6891, eq. 1-4): for a hinge joint with unit axis ``j1`` in
sensor 1 and ``j2`` in sensor 2, the angular velocities' components perpendicular to the axis are
equal in size at every sample, ``‖g1 × j1‖ = ‖g2 × j2‖``, whatever the sensors' orientation and
the motion. ``j1``, ``j2`` in spherical coordinates minimise the sum of squared differences
(Gauss-Newton; here scipy's Levenberg-Marquardt). The signs of ``j1`` and ``j2`` are not
observable from the constraint and are fixed with prior directions (the nominal mounting).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from motionlab.errors import InputError


def _unit(phi: float, theta: float) -> np.ndarray:
    return np.array([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])


def _angles(v: np.ndarray) -> tuple[float, float]:
    v = v / np.linalg.norm(v)
    return float(np.arcsin(np.clip(v[2], -1, 1))), float(np.arctan2(v[1], v[0]))


def hinge_axes(
    gyr1: np.ndarray,
    gyr2: np.ndarray,
    prior1: np.ndarray | None = None,
    prior2: np.ndarray | None = None,
    n_starts: int = 6,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Joint axis in sensor 1 and sensor 2 coordinates (unit, (3,)) and the RMS residual (rad/s).

    ``gyr1``, ``gyr2`` are (N, 3) rad/s on one clock. The fit starts from the priors and from
    ``n_starts`` random directions (seeded) and keeps the best; signs follow the priors.
    """
    g1 = np.asarray(gyr1, float)
    g2 = np.asarray(gyr2, float)
    ok = np.all(np.isfinite(g1), axis=1) & np.all(np.isfinite(g2), axis=1)
    g1, g2 = g1[ok], g2[ok]
    if len(g1) < 20:
        raise InputError("too few samples for the hinge-axis fit", remedy="record more movement")
    stride = max(1, len(g1) // 4000)  # a few thousand samples are plenty
    g1, g2 = g1[::stride], g2[::stride]

    def residual(x: np.ndarray) -> np.ndarray:
        j1, j2 = _unit(x[0], x[1]), _unit(x[2], x[3])
        return np.linalg.norm(np.cross(g1, j1), axis=1) - np.linalg.norm(np.cross(g2, j2), axis=1)

    rng = np.random.default_rng(seed)
    starts = [rng.normal(size=6) for _ in range(n_starts)]
    if prior1 is not None and prior2 is not None:
        starts.insert(0, np.concatenate([prior1, prior2]))
    best = None
    for s in starts:
        x0 = np.array([*_angles(s[:3]), *_angles(s[3:])])
        fit = least_squares(residual, x0, method="lm")
        if best is None or fit.cost < best.cost:
            best = fit
    j1, j2 = _unit(best.x[0], best.x[1]), _unit(best.x[2], best.x[3])
    if prior1 is not None and j1 @ prior1 < 0:
        j1 = -j1
    if prior2 is not None and j2 @ prior2 < 0:
        j2 = -j2
    return j1, j2, float(np.sqrt(2 * best.cost / len(g1)))
