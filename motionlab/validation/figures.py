"""Figures of a validation result (``session.results.validation``), for the report.

Each function takes the stored :class:`~motionlab.results.Validation` and returns a
:class:`matplotlib.figure.Figure` (no pyplot state; save it with ``fig.savefig``). Angles in
degrees, time in s (IMU clock).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from motionlab.results import Validation
from motionlab.validation.tables import angle_columns, sensor_labels

IMU_COLOUR = "tab:blue"
REF_COLOUR = "black"


def _figure(rows: int = 1, height: float = 3.0) -> tuple[Figure, list]:
    fig = Figure(figsize=(8.0, height * rows), layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, list(axes)


def _columns(result: Validation, columns: list[str] | None) -> list[str]:
    cols = angle_columns(result) if columns is None else list(columns)
    if not cols:
        raise ValueError("the result holds no joint angles")
    return cols


def _angle_panels(
    result: Validation, columns: list[str] | None, height: float
) -> tuple[np.ndarray, Figure, list[tuple]]:
    """A figure with one panel per angle over time (s): ``(time, figure, [(axes, column, the
    column's AngleAgreement)])``."""
    cols = _columns(result, columns)
    fig, axes = _figure(len(cols), height)
    axes[-1].set_xlabel("time (s)")
    entries = result.angles.columns
    panels = [(ax, col, entries[col]) for ax, col in zip(axes, cols, strict=True)]
    return result.angles.time_s, fig, panels


def angle_overlay(result: Validation, columns: list[str] | None = None) -> Figure:
    """IMU and optical angle curves over time, one panel per angle."""
    t, fig, panels = _angle_panels(result, columns, 2.2)
    for ax, col, e in panels:
        ax.plot(t, e.ref_deg, color=REF_COLOUR, lw=1.0, label="optical")
        ax.plot(t, e.imu_deg, color=IMU_COLOUR, lw=1.0, label="IMU")
        ax.set_ylabel(f"{col.removesuffix('_deg')} (°)", fontsize=8)
        title = f"RMSE {e.rmse_deg:.1f}°, r {e.r:.2f}" if not e.withheld else "not stated"
        ax.set_title(title, fontsize=8, loc="right")
    panels[0][0].legend(loc="upper left", fontsize=8)
    return fig


def angle_error(result: Validation, columns: list[str] | None = None) -> Figure:
    """IMU − optical error of each angle over time, with its bias and limits of agreement."""
    t, fig, panels = _angle_panels(result, columns, 2.0)
    for ax, col, e in panels:
        ax.plot(t, np.asarray(e.imu_deg) - np.asarray(e.ref_deg), color=IMU_COLOUR, lw=0.8)
        ax.axhline(e.bias_deg, color="tab:red", lw=1.0)
        for limit in e.loa_deg:
            ax.axhline(limit, color="tab:red", lw=0.8, ls="--")
        ax.set_ylabel(f"{col.removesuffix('_deg')}\nerror (°)", fontsize=8)
    return fig


def bland_altman(result: Validation, column: str) -> Figure:
    """Bland–Altman plot of one angle: difference against mean, bias and 95 % limits."""
    e = result.angles.columns[column]
    imu, ref = np.asarray(e.imu_deg), np.asarray(e.ref_deg)
    ok = np.isfinite(imu) & np.isfinite(ref)
    fig, (ax,) = _figure(1, 4.0)
    ax.scatter(0.5 * (imu[ok] + ref[ok]), imu[ok] - ref[ok], s=2, alpha=0.3, color=IMU_COLOUR)
    lo, hi = e.loa_deg
    ax.axhline(e.bias_deg, color="tab:red", label=f"bias {e.bias_deg:+.2f}°")
    ax.axhline(lo, color="tab:red", ls="--", label=f"95 % LoA [{lo:+.1f}, {hi:+.1f}]°")
    ax.axhline(hi, color="tab:red", ls="--")
    ax.set_xlabel(f"mean of IMU and optical {column.removesuffix('_deg')} (°)")
    ax.set_ylabel("IMU − optical (°)")
    ax.legend(fontsize=8)
    return fig


def sync_figure(result: Validation) -> Figure:
    """Window lags around the fitted clock model, inliers and outliers."""
    s = result.sync
    t = np.asarray(s.window_time_s)
    fig, (ax,) = _figure(1, 3.5)
    if len(t):
        model = s.time_offset_s + s.drift_ppm * 1e-6 * t
        resid = (np.asarray(s.window_lag_s) - model) * 1e3
        inl = np.asarray(s.inliers, bool)
        ax.errorbar(t[inl], resid[inl], yerr=np.asarray(s.window_sd_s)[inl] * 1e3, fmt="o",
                    ms=3, color=IMU_COLOUR, label="inlier windows")  # fmt: skip
        ax.plot(t[~inl], resid[~inl], "x", color="tab:red", label="outliers")
        ax.axhline(0.0, color=REF_COLOUR, lw=1.0)
        ax.legend(fontsize=8)
    ax.set_title(f"offset {s.time_offset_s:.4f} s, drift {s.drift_words()}", fontsize=9)
    ax.set_xlabel("IMU time (s)")
    ax.set_ylabel("lag − clock model (ms)")
    return fig


def alignment_figure(result: Validation) -> Figure:
    """Orientation error after alignment over time: total, heading, inclination per sensor."""
    labels = sensor_labels(result)
    if not labels:
        raise ValueError("the result holds no orientation errors")
    t = result.orientation.time_s
    al = result.alignment
    fig, axes = _figure(len(labels), 2.0)
    for ax, label in zip(axes, labels, strict=True):
        o = result.orientation.sensors[label]
        for key, deg, colour in (("total", o.total_deg, REF_COLOUR),
                                 ("heading", o.heading_deg, "tab:orange"),
                                 ("inclination", o.inclination_deg, IMU_COLOUR)):  # fmt: skip
            ax.plot(t, deg, lw=0.8, color=colour, label=key)
        x = al.sensor_to_cluster[label].angle_deg if label in al.sensor_to_cluster else np.nan
        ax.set_title(f"{label}: sensor → cluster {x:.1f}°", fontsize=8, loc="right")
        ax.set_ylabel("error (°)", fontsize=8)
    axes[0].legend(loc="upper left", fontsize=8, ncols=3)
    axes[0].set_title(
        f"alignment {al.mode}: lab → earth {al.lab_to_earth.angle_deg:.1f}°",
        fontsize=9,
        loc="left",
    )
    axes[-1].set_xlabel("time (s)")
    return fig
