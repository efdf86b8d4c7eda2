"""Gait Profile Score (GPS) and Movement Analysis Profile (MAP), Baker et al. (2009, Gait
Posture 30:265).

For each kinematic variable ``i`` the Gait Variable Score is the RMS difference between the
subject's mean curve (one side's strides, 0-100 % from initial contact) and the normative mean
curve, over the cycle (51 points, every 2 %, as Baker et al.): ``GVS_i = sqrt(mean_t (x_i(t) −
x̄_i(t))²)`` (deg). The GPS is the RMS of the GVS: ``GPS = sqrt(mean_i GVS_i²)``; the MAP is the
bar chart of the GVS, with the GPS of each side and of both.

Variables (the sensors of the walk protocol give them): pelvic tilt, obliquity, rotation; hip
flexion, adduction, rotation; knee flexion, each per side (the pelvis with the side's signs,
:func:`motionlab.kinematics.pelvis.side_angles`). Ankle and foot progression need foot sensors and
are left out, so this GPS has 7 variables per side instead of Baker's 9 (15 with the pelvis once
for both sides); the overall GPS uses the pelvis once (the right side's cycles) and hip and knee of
both sides: 11 variables.

Normative curves: ``report_data/gait_normative.csv`` (see its YAML for sources, licence and why
they are approximate).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

DATA = Path(__file__).resolve().parent.parent / "report_data"  # as motionlab.report.normative
NORMATIVE = DATA / "gait_normative.csv"
NORMATIVE_SOURCES = DATA / "gait_normative.yaml"
VARIABLES = (
    "pelvis_tilt",
    "pelvis_obliquity",
    "pelvis_rotation",
    "hip_flexion",
    "hip_adduction",
    "hip_rotation",
    "knee_flexion",
)
PELVIS = VARIABLES[:3]
GPS_POINTS = np.arange(0, 101, 2)  # % of the cycle (Baker et al. 2009)


@lru_cache(maxsize=1)
def _table() -> pd.DataFrame:
    return pd.read_csv(NORMATIVE)


def normative(variable: str, percent: np.ndarray = GPS_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Normative mean and SD (deg) of ``variable`` at ``percent`` (0-100)."""
    t = _table()
    rows = t[t["variable"] == variable].sort_values("percent_pct")
    if rows.empty:
        raise KeyError(variable)
    x = rows["percent_pct"].to_numpy(dtype=float)
    mean = PchipInterpolator(x, rows["mean_deg"].to_numpy(dtype=float))(percent)
    sd = PchipInterpolator(x, rows["sd_deg"].to_numpy(dtype=float))(percent)
    return mean, sd


def gvs(curve: np.ndarray, variable: str) -> float:
    """Gait Variable Score (deg) of a mean curve sampled at 0-100 % (any number of points)."""
    curve = np.asarray(curve, dtype=float)
    pct = np.linspace(0.0, 100.0, len(curve))
    x = np.interp(GPS_POINTS, pct, curve)
    mean, _ = normative(variable)
    return float(np.sqrt(np.nanmean((x - mean) ** 2)))


def gps(scores: dict[str, float]) -> float:
    """GPS (deg): the RMS of the given GVS values (NaN ignored)."""
    v = np.array([s for s in scores.values() if np.isfinite(s)])
    return float(np.sqrt(np.mean(v**2))) if len(v) else float("nan")


def population_gps(variables: tuple[str, ...] = VARIABLES) -> float:
    """Expected GPS (deg) of a subject from the normative population: the RMS of the normative SD
    over variables and the cycle (each GVS² of a normal subject has the mean SD² of its
    variable)."""
    return float(np.sqrt(np.mean([np.mean(normative(v)[1] ** 2) for v in variables])))


def movement_analysis_profile(curves: dict[str, dict[str, np.ndarray]]) -> dict[str, Any]:
    """MAP and GPS from mean curves ``{side: {variable: (P,) deg over 0-100 %}}``.

    Returns ``{"gvs": {side: {variable: deg}}, "gps": {"r": deg, "l": deg, "overall": deg},
    "population_gps_deg": deg, "variables": [...]}``; a missing variable is left out.
    """
    scores: dict[str, dict[str, float]] = {}
    for side, by_var in curves.items():
        scores[side] = {v: gvs(by_var[v], v) for v in VARIABLES if v in by_var}
    overall = {f"r_{v}": s for v, s in scores.get("r", {}).items()}
    overall |= {f"l_{v}": s for v, s in scores.get("l", {}).items() if v not in PELVIS}
    if "r" not in scores:
        overall |= {f"l_{v}": s for v, s in scores.get("l", {}).items() if v in PELVIS}
    used = tuple(v for v in VARIABLES if any(v in s for s in scores.values()))
    return {
        "gvs": scores,
        "gps": {side: gps(s) for side, s in scores.items()} | {"overall": gps(overall)},
        "population_gps_deg": population_gps(used) if used else float("nan"),
        "variables": list(used),
    }
