"""Functional axes: the rotation axis of a mono-axial movement from the gyroscope.

Ricci (2015, §6.2, eqs. 6.1-6.2): keep the (bias-compensated) angular-velocity samples whose norm
is at least 30 % of the peak, take the first right singular vector of the uncentred matrix as the
axis and ρ = σ₁ / (σ₁ + σ₂ + σ₃) as its reliability. Flexion and extension samples lie on the
same line through the origin, so no segmentation into half-cycles is needed. The singular
vector's sign is arbitrary; :func:`orient` fixes it with a prior direction (the protocol's
nominal mounting), so the axis points along the angular velocity of the named movement.

The axis is then refined on the samples within ``INLIER_DEG`` of it (either sign): turning into
or out of the step's start pose about another axis (e.g. bending the elbow to 90° before a
pronation) would otherwise tilt it. ρ stays Ricci's, over all samples above the threshold.
"""

from __future__ import annotations

import numpy as np

from motionlab.errors import InputError
from motionlab.segments.static import principal_axis

PEAK_FRACTION = 0.30
INLIER_DEG = 25.0


def functional_axis(
    gyr: np.ndarray, peak_fraction: float = PEAK_FRACTION
) -> tuple[np.ndarray, float, int]:
    """Rotation axis (3,) in sensor coordinates, reliability ρ, and the number of samples used.

    ``gyr`` is (N, 3) angular velocity in rad/s; samples below ``peak_fraction`` × the peak norm
    are left out (Ricci §6.2).
    """
    gyr = np.asarray(gyr, dtype=float)
    norm = np.linalg.norm(gyr, axis=1)
    if not np.any(np.isfinite(norm)) or np.nanmax(norm) <= 0:
        raise InputError("the segment does not move during the step", remedy="repeat the movement")
    keep = norm >= peak_fraction * np.nanmax(norm)
    axis, rho = principal_axis(gyr[keep])
    fast = gyr[keep]
    cos = np.abs(fast @ axis) / np.linalg.norm(fast, axis=1)
    inliers = cos >= np.cos(np.radians(INLIER_DEG))
    if inliers.sum() >= 3:
        refined, _ = principal_axis(fast[inliers])
        axis = refined if refined @ axis >= 0 else -refined
    return axis, rho, int(keep.sum())


def orient(axis: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """``axis`` or ``-axis``, whichever points within 90° of ``prior``."""
    return axis if float(np.dot(axis, prior)) >= 0 else -axis
