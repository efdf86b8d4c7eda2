"""The validation result as a JSON summary and as CSV tables (degrees, units in column names)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from motionlab.plain import plain
from motionlab.results import Validation

ANGLE_STATS = (
    "rmse_deg", "bias_deg", "sd_deg", "max_abs_deg", "rmse_centred_deg", "r", "cmc", "n_samples",
)  # fmt: skip
CSV_FILES = (
    "validation_angles.csv", "validation_metrics.csv", "validation_orientation.csv",
    "validation_sync.csv",
)  # fmt: skip
ORIENTATION_STATS = (
    "total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg", "median_deg", "iqr_deg",
    "p95_deg", "n_samples",
)  # fmt: skip


def angle_columns(result: Validation) -> list[str]:
    """The angle columns of a result (those with statistics)."""
    angles = result.angles or {}
    return [k for k, v in angles.items() if isinstance(v, dict) and "rmse_deg" in v]


def sensor_labels(result: Validation) -> list[str]:
    """The sensors with orientation errors."""
    return [k for k, v in result.orientation.items() if isinstance(v, dict)]


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
            k: {s: result.orientation[k].get(s) for s in ORIENTATION_STATS}
            for k in sensor_labels(result)
        },
        "angles": {},
        "notes": list(result.notes),
    }
    if result.reference:
        out["reference"] = dict(result.reference)
    for col in angle_columns(result):
        entry = result.angles[col]
        out["angles"][col] = {s: entry[s] for s in ANGLE_STATS} | {"loa_deg": entry["loa_deg"]}
        reps = entry.get("repetitions")
        if isinstance(reps, dict) and reps.get("n"):
            out["angles"][col]["repetitions"] = {
                "n": reps["n"],
                "rmse_deg_mean": float(np.mean(reps["rmse_deg"])),
                "rom_error_deg_mean": float(np.mean(reps["rom_error_deg"])),
                "cmc": reps["cmc"],
            }
    return plain(out)


def tables(result: Validation) -> dict[str, pd.DataFrame]:
    """CSV tables by file name: angle curves, angle metrics, orientation metrics, sync windows."""
    out: dict[str, pd.DataFrame] = {}
    cols = angle_columns(result)
    if cols:
        angles = result.angles
        curves = {"time_s": angles["time_s"]}
        for col in cols:
            stem = col.removesuffix("_deg")
            curves[f"{stem}_imu_deg"] = angles[col]["imu_deg"]
            curves[f"{stem}_ref_deg"] = angles[col]["ref_deg"]
        out["validation_angles.csv"] = pd.DataFrame(curves)
        rows = []
        for col in cols:
            e = angles[col]
            lo, hi = e["loa_deg"]
            rows.append({"angle": col} | {s: e[s] for s in ANGLE_STATS}
                        | {"loa_low_deg": lo, "loa_high_deg": hi})  # fmt: skip
        out["validation_metrics.csv"] = pd.DataFrame(rows)
    labels = sensor_labels(result)
    if labels:
        out["validation_orientation.csv"] = pd.DataFrame(
            [
                {"sensor": k} | {s: result.orientation[k].get(s) for s in ORIENTATION_STATS}
                for k in labels
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
