"""Orientation error of an estimate against a reference, as the BROAD benchmark defines it.

Both inputs are (N, 4) unit quaternions, scalar first, sensor → ENU earth. The error quaternion is
``e = q_est ⊗ conj(q_ref)`` (expressed in the earth frame), and per sample (degrees)

- total angle ``2·acos(|e_w|)``,
- heading (rotation about the vertical) ``2·atan(|e_z / e_w|)``,
- inclination (rotation about a horizontal axis) ``2·acos(sqrt(e_w² + e_z²))``.

Reference: Laidig, Caruso, Cereatti, Seel, "BROAD — A Benchmark for Robust Inertial Orientation
Estimation", Data 2021, 6(7):72, doi:10.3390/data6070072.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError


def error_angles(q_est: np.ndarray, q_ref: np.ndarray) -> dict[str, np.ndarray]:
    """Per-sample total, heading and inclination error in degrees (NaN where either is NaN)."""
    q_est = np.asarray(q_est, dtype=float)
    q_ref = np.asarray(q_ref, dtype=float)
    if q_est.shape != q_ref.shape or q_est.shape[-1] != 4:
        raise InputError(
            f"estimate {q_est.shape} and reference {q_ref.shape} are not matching (N, 4) arrays",
            remedy="resample both onto the same time base",
        )
    e = rot.mul(q_est, rot.conj(q_ref))
    w = np.abs(e[..., 0])
    z = np.abs(e[..., 3])
    with np.errstate(invalid="ignore", divide="ignore"):
        total = 2.0 * np.arccos(np.clip(w, 0.0, 1.0))
        heading = 2.0 * np.arctan2(z, w)
        inclination = 2.0 * np.arccos(np.clip(np.sqrt(w * w + z * z), 0.0, 1.0))
    return {
        "total": np.degrees(total),
        "heading": np.degrees(heading),
        "inclination": np.degrees(inclination),
    }


def orientation_errors(
    q_est: np.ndarray, q_ref: np.ndarray, mask: np.ndarray | None = None
) -> dict[str, float]:
    """RMS errors (degrees) over ``mask`` samples, skipping NaN reference samples.

    Returns ``total_rmse_deg``, ``heading_rmse_deg``, ``inclination_rmse_deg``, the total
    (geodesic) error's ``median_deg``, ``iqr_deg``, ``p95_deg``, and ``n_samples`` used.
    """
    ang = error_angles(q_est, q_ref)
    valid = np.isfinite(ang["total"])
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != valid.shape:
            raise InputError(f"mask has shape {mask.shape}, expected {valid.shape}")
        valid &= mask
    if not valid.any():
        raise InputError("no sample has both an estimate and a reference", remedy="check the mask")
    total = ang["total"][valid]
    q25, q50, q75, q95 = np.percentile(total, [25, 50, 75, 95])
    return {
        "total_rmse_deg": float(np.sqrt(np.mean(total**2))),
        "heading_rmse_deg": float(np.sqrt(np.mean(ang["heading"][valid] ** 2))),
        "inclination_rmse_deg": float(np.sqrt(np.mean(ang["inclination"][valid] ** 2))),
        "median_deg": float(q50),
        "iqr_deg": float(q75 - q25),
        "p95_deg": float(q95),
        "n_samples": int(valid.sum()),
    }
