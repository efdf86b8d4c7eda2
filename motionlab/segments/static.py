"""Static poses: the direction of gravity in the sensor frame, with its reliability.

Convention: an accelerometer at rest reads the specific force, about +9.81 m/s² along the sensor
axis that points up, so the mean reading over a still window is the "up" direction in sensor
coordinates. Following Ricci (2015, eqs. 6.1-6.2) the direction is the first right singular vector
of the uncentred reading matrix, and its reliability ρ = σ₁ / (σ₁ + σ₂ + σ₃) (1 for a perfectly
still sensor, 1/3 for readings spread in all directions).
"""

from __future__ import annotations

import numpy as np

from motionlab.errors import InputError


def principal_axis(samples: np.ndarray, min_samples: int = 3) -> tuple[np.ndarray, float]:
    """First right singular vector of the uncentred (N, 3) matrix and ρ = σ₁/Σσ (Ricci eq. 6.2).

    The sign is that of the mean sample (arbitrary if the mean is zero). Fewer than
    ``min_samples`` finite samples are refused.
    """
    samples = np.asarray(samples, dtype=float)
    samples = samples[np.all(np.isfinite(samples), axis=1)]
    if len(samples) < max(1, min_samples):
        raise InputError(f"only {len(samples)} valid samples for an axis", remedy="record longer")
    _, sigma, vt = np.linalg.svd(samples, full_matrices=False)
    axis = vt[0]
    if axis @ samples.sum(axis=0) < 0:
        axis = -axis
    total = sigma.sum()
    rho = float(sigma[0] / total) if total > 0 else 1.0 / 3.0
    return axis, rho


def gravity_axis(acc: np.ndarray, min_samples: int = 3) -> tuple[np.ndarray, float]:
    """Unit "up" direction (3,) in sensor coordinates and its reliability ρ, from a still window.

    ``acc`` is (N, 3) specific force in m/s²; ``min_samples`` as in :func:`principal_axis` (a
    single-pose calibration from orientations takes even one sample).
    """
    return principal_axis(acc, min_samples)
