"""Gait pages: spatio-temporal parameters against normative bands with the Movement Analysis
Profile (first page), then the pelvis, hip and knee cycle curves against the GPS's normative
curves; and the ``spatiotemporal.csv`` table. Drawn only when ``results.gait`` holds a gait
analysis (:mod:`motionlab.kinematics.gait`)."""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
import pandas as pd
import yaml

from motionlab.kinematics.gps import NORMATIVE_SOURCES, VARIABLES, normative
from motionlab.kinematics.spatiotemporal import STRIDE_COLUMNS, summary_rows
from motionlab.report.model import SessionView
from motionlab.report.pdf import BAND_COLOUR, MUTED, SIDE_COLOUR, SIZE, Document
from motionlab.results import Gait

_LABELS = {
    "cadence_steps_per_min": "cadence (steps/min)",
    "stride_time_s": "stride time (s)",
    "step_time_s": "step time (s)",
    "stance_time_s": "stance time (s)",
    "swing_time_s": "swing time (s)",
    "stance_pct": "stance (% of stride)",
    "swing_pct": "swing (% of stride)",
    "double_support_pct": "double support (% of stride)",
    "step_time_asymmetry_pct": "step-time asymmetry (symmetry index, %)",
    "stride_time_cv_pct": "stride-time variability (CV, %)",
    "step_length_m": "step length (m)*",
    "stride_length_m": "stride length (m)*",
    "walking_speed_m_s": "walking speed (m/s)*",
}


@lru_cache(maxsize=1)
def _bands() -> dict[str, Any]:
    with open(NORMATIVE_SOURCES, encoding="utf-8") as f:
        return yaml.safe_load(f)


def gait_result(view: SessionView) -> Gait | None:
    """The session's gait analysis, or None when there is none (or no gait was found)."""
    g = view.session.results.gait
    return g if g is not None and g.ok else None


def _fmt(s: dict[str, float], digits: int) -> str:
    if not np.isfinite(s.get("mean", np.nan)):
        return "-"
    return f"{s['mean']:.{digits}f} ± {s['sd']:.{digits}f} (CV {s['cv_pct']:.1f} %)"


def _outside(value: float, band: list[float] | None) -> bool:
    return bool(band) and np.isfinite(value) and not band[0] <= value <= band[1]


def gait_pages(doc: Document, view: SessionView) -> None:
    """The gait pages of one session (none without a gait analysis)."""
    g = gait_result(view)
    if g is None:
        return
    summ, bands = g.summary, _bands()["spatiotemporal"]
    doc.section(
        "Gait: spatio-temporal parameters and profile",
        "Events from the shank gyroscopes (initial contact: the shank stops swinging forward; "
        "final contact: midway between the last minimum before mid-swing and the following zero "
        "crossing); straight, steady strides only. "
        "Mean ± SD (CV) per side; normal bands are approximate ranges of healthy adults.",
    )
    rows, flags = [], []
    for c in STRIDE_COLUMNS:
        digits = 2 if c.endswith(("_s", "_m")) else 1
        r, left = summ["sides"]["r"][c], summ["sides"]["l"][c]
        band = bands.get(c)
        rows.append([_LABELS[c], _fmt(r, digits), _fmt(left, digits),
                     f"{band[0]:g}-{band[1]:g}" if band else "-"])  # fmt: skip
        flags.append([False, _outside(r["mean"], band), _outside(left["mean"], band), False])
    for c in ("step_time_asymmetry_pct", "stride_time_cv_pct"):
        band = bands.get(c)
        rows.append([_LABELS[c], f"{summ[c]:.1f} (both sides)", "",
                     f"{band[0]:g}-{band[1]:g}" if band else "-"])  # fmt: skip
        flags.append([False, _outside(summ[c], band), False, False])
    doc.table(["parameter", "right", "left", "normal"], rows, [0.34, 0.25, 0.25, 0.16],
              flagged=flags, align=["l", "r", "r", "r"])  # fmt: skip
    rejected = ", ".join(f"{k} {v}" for k, v in summ["strides_rejected"].items()) or "none"
    doc.paragraph(
        f"Strides kept: {summ['strides_kept']}; rejected: {rejected}. Overall cadence "
        f"{summ['cadence_steps_per_min']:.1f} steps/min. *Lengths and speed: {length_note(g)}",
        size=SIZE["small"],
    )
    doc.paragraph("Bands: " + _bands()["spatiotemporal_source"], size=SIZE["small"], colour=MUTED)
    _map_chart(doc, g.map)


def length_note(g: Gait) -> str:
    """One sentence on the stride length and speed: the model, its measured error, or why not."""
    speed = g.summary.get("walking_speed_m_s", np.nan)
    if not np.isfinite(speed):
        return (g.walking_speed or "not measured") + "."
    return (
        f"overall {speed:.2f} m/s; {g.walking_speed}. Measured error on one real walk (Vicon "
        "walking2, 3 strides, with the foot-roll factor taken from it): stride length within "
        "2 % of the heel markers on its steady strides; an estimate checked on one walker only "
        "(docs/kinematics.md)."
    )


def _map_chart(doc: Document, mp: dict[str, Any]) -> None:
    """The Movement Analysis Profile: GVS per variable and side, and the GPS."""
    doc.heading("Gait Profile Score and Movement Analysis Profile")
    ((ax,),) = doc.axes_grid(1, 1, 3.0, left=0.6, bottom=0.9, top=0.2)
    names = [*mp["variables"], "GPS"]
    x = np.arange(len(names))
    for k, side in enumerate(("r", "l")):
        vals = [mp["gvs"].get(side, {}).get(v, np.nan) for v in mp["variables"]]
        vals.append(mp["gps"].get(side, np.nan))
        ax.bar(x + (k - 0.5) * 0.38, vals, 0.36, color=SIDE_COLOUR[side],
               label={"r": "right", "l": "left"}[side])  # fmt: skip
    expected = f"expected GPS of a normal subject {mp['population_gps_deg']:.1f}°"
    ax.axhline(mp["population_gps_deg"], color=MUTED, ls="--", lw=0.8, label=expected)
    ax.set_xticks(x, [n.replace("_", " ") for n in names], rotation=30, ha="right")
    ax.set_ylabel("deg (RMS difference)")
    ax.legend(loc="upper left", frameon=False)
    doc.paragraph(
        f"GPS: right {mp['gps'].get('r', np.nan):.1f}°, left {mp['gps'].get('l', np.nan):.1f}°, "
        f"overall {mp['gps']['overall']:.1f}° (Baker et al. 2009, Gait Posture 30:265; "
        f"{len(mp['variables'])} variables per side, no ankle or foot). The normative curves are "
        "approximate, built from published key values (report_data/gait_normative.yaml): the "
        "score compares shapes, it is not a validated clinical GPS.",
        size=SIZE["small"],
        colour=MUTED,
    )


def curve_page(doc: Document, view: SessionView) -> None:
    """Mean ± SD cycle curves per side against the normative mean ± SD."""
    g = gait_result(view)
    if g is None:
        return
    curves = g.curves
    used = [v for v in VARIABLES if any(v in curves.get(s, {}) for s in "rl")]
    if not used:
        return
    doc.section("Gait: pelvis, hip and knee over the stride",
                "Mean ± SD over kept strides (0 % = initial contact) against the normative "
                "mean ± SD used by the GPS.")  # fmt: skip
    nrows = (len(used) + 1) // 2
    grid = doc.axes_grid(nrows, 2, 2.2 * nrows + 0.4, left=0.6, hspace=0.6, top=0.35)
    pct = np.linspace(0, 100, 101)
    for i, v in enumerate(used):
        ax = grid[i // 2][i % 2]
        mean, sd = normative(v, pct)
        ax.fill_between(pct, mean - sd, mean + sd, color=BAND_COLOUR, alpha=0.6, lw=0)
        for side in ("r", "l"):
            c = curves.get(side, {})
            if v in c:
                m, s = np.asarray(c[v]), np.asarray(c[f"{v}_sd"])
                ax.plot(pct, m, color=SIDE_COLOUR[side], lw=1.2)
                ax.fill_between(pct, m - s, m + s, color=SIDE_COLOUR[side], alpha=0.15, lw=0)
        ax.set_title(v.replace("_", " "))
        ax.set_xlim(0, 100)
        ax.set_ylabel("deg")
    for j in range(len(used), nrows * 2):
        grid[j // 2][j % 2].set_visible(False)


def gait_report_pages(doc: Document, view: SessionView) -> None:
    """Both gait pages."""
    gait_pages(doc, view)
    curve_page(doc, view)


def gait_frames(view: SessionView) -> dict[str, pd.DataFrame]:
    """``spatiotemporal.csv`` (one row per stride, kept or not, with the reason) and
    ``spatiotemporal_summary.csv`` (per side mean, SD, CV); nothing without a gait analysis."""
    g = gait_result(view)
    if g is None:
        return {}
    strides = pd.DataFrame({k: np.asarray(v) for k, v in g.strides.items()})
    strides = strides[["side", "start_s", "kept", "reason", *STRIDE_COLUMNS]]
    return {
        "spatiotemporal.csv": strides,
        "spatiotemporal_summary.csv": summary_rows(g.summary),
    }
