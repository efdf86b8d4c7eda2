"""The validation result as a JSON summary and as CSV tables (degrees, units in column names)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from motionlab.plain import plain
from motionlab.results import AngleAgreement, SensorOrientationError, Validation

ANGLE_STATS = (
    "rmse_deg", "bias_deg", "sd_deg", "max_abs_deg", "rmse_centred_deg", "r", "cmc", "n_samples",
    "withheld",
)  # fmt: skip
CSV_FILES = (
    "validation_angles.csv", "validation_metrics.csv", "validation_orientation.csv",
    "validation_sync.csv",
)  # fmt: skip
ORIENTATION_STATS = (
    "total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg", "median_deg", "iqr_deg",
    "p95_deg", "n_samples", "withheld",
)  # fmt: skip


def angle_columns(result: Validation) -> list[str]:
    """The angle columns of a result (those with statistics)."""
    return list(result.angles.columns) if result.angles is not None else []


def sensor_labels(result: Validation) -> list[str]:
    """The sensors with orientation errors."""
    return list(result.orientation.sensors)


def _stats(record: SensorOrientationError | AngleAgreement, names: tuple) -> dict[str, Any]:
    """The statistics ``names`` of a record as the file stores them (``None``: not given;
    ``withheld``: why a statistic the validation cannot state is not given)."""
    tree = record.to_tree()
    return {s: tree.get(s) for s in names}


def summary(result: Validation) -> dict[str, Any]:
    """JSON-able digest: ``time_offset_s``, ``drift_ppm``, the alignment rotations (quaternion
    and angle), per sensor the orientation errors, per angle ``rmse_deg``, ``bias_deg``,
    ``loa_deg``, ``r``, ``cmc`` and the other statistics."""
    sync = result.sync
    al = result.alignment
    out = {
        "time_offset_s": sync.time_offset_s,
        "drift_ppm": sync.drift_ppm,
        "sync": {
            "method": sync.method,
            "inlier_ratio": sync.inlier_ratio,
            "residual_rms_s": sync.residual_rms_s,
            "n_windows": sync.n_windows,
            "standard_error_ms": 1e3 * sync.standard_error_s,
            "ends_standard_error_ms": None
            if sync.ends_standard_error_s is None
            else 1e3 * sync.ends_standard_error_s,
            "drift_grade": sync.drift_grade,
            "drift_measured_ppm": sync.drift_measured_ppm,
            "drift_se_ppm": sync.drift_se_ppm,
            "grade": sync.grade,
            "fallback": sync.fallback,
            "signal": sync.signal,
        },
        "alignment": {
            "mode": al.mode,
            "lab_to_earth": al.lab_to_earth.to_tree(),
            "sensor_to_cluster": {k: r.to_tree() for k, r in al.sensor_to_cluster.items()},
            "heading_deg": al.heading_deg,
            "residual_rms_deg": al.residual_rms_deg,
        },
        "orientation": {
            k: _stats(e, ORIENTATION_STATS) for k, e in result.orientation.sensors.items()
        },
        "angles": {},
        "notes": list(result.notes),
    }
    reference = result.reference.to_tree()
    if reference:
        out["reference"] = reference
    for col, entry in (result.angles.columns if result.angles is not None else {}).items():
        digest = _stats(entry, ANGLE_STATS) | {"loa_deg": entry.loa_deg}
        reps = entry.repetitions
        if reps is not None and reps.n:
            digest["repetitions"] = {
                "n": reps.n,
                "rmse_deg_mean": float(np.mean(reps.rmse_deg)),
                "rom_error_deg_mean": float(np.mean(reps.rom_error_deg)),
                "cmc": reps.cmc,
            }
        out["angles"][col] = digest
    return plain(out)


def tables(result: Validation) -> dict[str, pd.DataFrame]:
    """CSV tables by file name: angle curves, angle metrics, orientation metrics, sync windows."""
    out: dict[str, pd.DataFrame] = {}
    angles = result.angles
    if angles is not None and angles.columns:
        curves = {"time_s": angles.time_s}
        for col, e in angles.columns.items():
            stem = col.removesuffix("_deg")
            curves[f"{stem}_imu_deg"] = e.imu_deg
            curves[f"{stem}_ref_deg"] = e.ref_deg
        out["validation_angles.csv"] = pd.DataFrame(curves)
        rows = []
        for col, e in angles.columns.items():
            lo, hi = e.loa_deg
            rows.append({"angle": col} | _stats(e, ANGLE_STATS)
                        | {"loa_low_deg": lo, "loa_high_deg": hi})  # fmt: skip
        out["validation_metrics.csv"] = pd.DataFrame(rows)
    if result.orientation.sensors:
        out["validation_orientation.csv"] = pd.DataFrame(
            [
                {"sensor": k} | _stats(e, ORIENTATION_STATS)
                for k, e in result.orientation.sensors.items()
            ]  # fmt: skip
        )
    sync = result.sync
    if len(sync.window_time_s):
        out["validation_sync.csv"] = pd.DataFrame(
            {
                "time_s": sync.window_time_s,
                "lag_s": sync.window_lag_s,
                "lag_sd_s": sync.window_sd_s,
                "correlation": sync.window_corr,
                "pair": sync.window_pair,
                "inlier": sync.inliers,
            }
        )
    return out
