"""Data quality (rates, gaps, saturation, rest, magnetic disturbance, exclusions) and
calibration quality (methods, ρ per movement, residual angles, what to repeat)."""

from __future__ import annotations

import numpy as np

from motionlab.clocksync import ClockFit, describe
from motionlab.report.model import (
    SessionView,
    calibration_rows,
    excluded,
    in_order,
    quality_rows,
)
from motionlab.report.pdf import MUTED, SIZE, Document, label_spans
from motionlab.segments.quality import FUNCTIONAL_RHO_MIN, RESIDUAL_MAX_DEG, STATIC_RHO_MIN

METHODS = {
    "procrustes": "the segment frame is the best fit to two or more measured axes",
    "primary_secondary": "one axis fixed as measured, the rotation about it from the others",
    "single_axis": "one axis measured, the rotation about it from the nominal placement",
}


def _f(x: float, spec: str = ".1f") -> str:
    return format(x, spec) if np.isfinite(x) else "-"


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _timeline(doc: Document, view: SessionView) -> None:
    """One lane per sensor: rest, magnetic disturbance and gaps over time, tasks shaded."""
    sensors = list(view.session.sensors.values())
    height = 1.3 + 0.28 * len(sensors)
    ax = doc.axes_grid(1, 1, height, left=0.9, bottom=0.5, top=0.25)[0][0]
    fusion = view.session.results.get("fusion", {})
    for k, s in enumerate(sensors):
        y = len(sensors) - 1 - k
        t = np.asarray(s.time, float)
        ax.broken_barh([(t[0], t[-1] - t[0])], (y - 0.35, 0.7), color="#d9e6f2")
        fz = fusion.get(s.label, {}) if isinstance(fusion, dict) else {}
        for key, colour in (("rest", "#9e9e9e"), ("mag_disturbed", "#f4a259")):
            mask = np.asarray(fz.get(key, np.zeros(0)), bool)
            if len(mask) == len(t):
                bars = [(t[a], t[b - 1] - t[a]) for a, b in _runs(mask)]
                ax.broken_barh(bars, (y - 0.3 + (0.35 if key == "rest" else 0), 0.25), color=colour)
        gaps = [(a, b - a) for a, b in (s.qc or {}).get("gaps", [])]
        if gaps:
            ax.broken_barh(gaps, (y - 0.4, 0.8), color="#b2182b")
    for a, b in view.blocks().values():
        ax.axvspan(a, b, color="#e8f4e8", zorder=0)
    ax.set_yticks(range(len(sensors)), [s.label for s in reversed(sensors)])
    ax.set_ylim(-0.6, len(sensors) + 0.5)
    ax.set_xlim(*ax.get_xlim())
    label_spans(ax, {k.replace("_", " "): v for k, v in view.blocks().items()}, SIZE["small"] - 1)
    ax.set_xlabel("time (s)")
    ax.set_title("The recording, sensor by sensor", loc="left")
    doc.paragraph(
        "Blue: recorded; grey: sensor at rest; orange: magnetic field disturbed; red: gap kept "
        "as missing; green background: task blocks used for the metrics.",
        size=SIZE["small"],
        colour=MUTED,
    )


def data_quality_page(doc: Document, view: SessionView) -> None:
    doc.section(
        "Data quality",
        "What the sensors delivered: sampling, missing data, saturation, periods at rest "
        "(used to correct the gyroscope drift) and magnetic disturbance.",
    )
    rows, flagged = [], []
    for q in quality_rows(view):
        rows.append(
            [
                q["sensor"],
                _f(q["rate_hz"]),
                _f(q["jitter_ms"], ".2f"),
                _f(q["duration_s"]),
                str(q["dropped_samples"]),
                str(q["gaps_filled"]),
                f"{q['gaps_kept']} ({q['gaps_kept_s']:.1f} s)",
                str(q["saturated_samples"]),
                _f(q["rest_pct"], ".0f"),
                _f(q["mag_disturbed_pct"], ".0f"),
            ]
        )
        flagged.append(
            [False] * 6
            + [q["gaps_kept"] > 0, q["saturated_samples"] > 0, False]
            + [bool(np.isfinite(q["mag_disturbed_pct"]) and q["mag_disturbed_pct"] > 20)]
        )
    doc.table(
        [
            "Sensor",
            "Rate (Hz)",
            "Jitter (ms)",
            "Length (s)",
            "Missing samples",
            "Gaps filled",
            "Gaps kept",
            "Saturated samples",
            "At rest (%)",
            "Mag. disturbed (%)",
        ],
        rows,
        [0.13, 0.08, 0.09, 0.09, 0.1, 0.08, 0.12, 0.11, 0.09, 0.11],
        flagged,
    )
    doc.paragraph(
        "Missing samples were counted from the time stamps; gaps up to the ingest limit were "
        "interpolated (filled), longer ones kept as missing. Saturated: samples stuck at the "
        "sensor's measuring range.",
        size=SIZE["small"],
        colour=MUTED,
    )
    flags = [
        f"{q['sensor']}: {', '.join(f.replace('_', ' ') for f in q['flags'])}"
        for q in quality_rows(view)
        if q["flags"]
    ]
    doc.heading("Quality checks raised")
    doc.bullets(flags or ["none: every check of every sensor passed"])
    synced = view.session.results.get("clock_sync", {})
    if synced:
        doc.heading("Sensor clocks")
        doc.paragraph(
            "Each sensor's clock against its neighbour's, from the acceleration of the joint "
            "centre they share; corrected where the estimate was reliable and not zero.",
            size=SIZE["small"],
            colour=MUTED,
        )
        doc.bullets([describe(ClockFit(**fit)) for fit in synced.values()])
    _timeline(doc, view)
    doc.heading("Excluded from the analysis, and why")
    doc.bullets(excluded(view) or ["nothing"])


def calibration_page(doc: Document, view: SessionView) -> None:
    cal = view.session.results.get("calibration", {})
    doc.section(
        "Calibration quality",
        "How each sensor's position on its body segment was found: static poses fix the "
        "vertical axis (gravity), functional movements the joint axes. ρ (reliability, 0-1) says "
        "how clean a pose or movement was; the residual is the angle between a measured axis and "
        "the fitted segment frame.",
    )
    steps = cal.get("steps", {})
    kinds = {s.name: s.kind for s in view.protocol.calibration}
    rows = [
        [
            name.replace("_", " "),
            kinds.get(name, ""),
            f"{rng[0]:.1f}–{rng[1]:.1f}" if rng else "not performed (optional)",
        ]
        for name, rng in ((k, steps[k]) for k in in_order(steps, list(kinds)))
    ]
    doc.heading("Steps found in the recording")
    doc.table(["Step", "Kind", "Time (s)"], rows, [0.4, 0.2, 0.4], align=["l", "l", "l"])

    doc.heading("Per segment and step")
    rows, flagged = [], []
    for r in calibration_rows(view):
        floor = STATIC_RHO_MIN if r["kind"] == "static" else FUNCTIONAL_RHO_MIN
        if np.isfinite(r["reference_rho"]):
            floor = r["reference_rho"] - 0.1
        rows.append(
            [
                r["segment"],
                r["method"].replace("_", " "),
                r["step"].replace("_", " "),
                _f(r["rho"], ".3f"),
                f"≥ {floor:.2f}",
                _f(r["residual_deg"]),
                "yes" if r["used"] else "no",
                "ok" if r["segment_ok"] else "check",
            ]
        )
        flagged.append(
            [False] * 3
            + [r["rho"] < floor, False, r["residual_deg"] > RESIDUAL_MAX_DEG, False]
            + [not r["segment_ok"]]
        )
    doc.table(
        ["Segment", "Method", "Step", "ρ", "ρ wanted", "Residual (°)", "In fit", "Segment"],
        rows,
        [0.13, 0.14, 0.19, 0.08, 0.12, 0.13, 0.09, 0.12],
        flagged,
        align=["l", "l", "l", "r", "r", "r", "r", "r"],
    )
    messages = [
        m
        for res in cal.get("segments", {}).values()
        for m in res.get("quality", {}).get("messages", [])
    ]
    doc.heading("Warnings and what to repeat next time")
    doc.bullets(messages or ["none: every segment was calibrated within the quality limits"])
    doc.paragraph(
        f"Limits: ρ ≥ {STATIC_RHO_MIN:.2f} for static poses and ≥ {FUNCTIONAL_RHO_MIN:.2f} for "
        f"functional movements (or within 0.1 of the protocol's reference), residual ≤ "
        f"{RESIDUAL_MAX_DEG:.0f}°. Methods: "
        + "; ".join(f"'{k.replace('_', ' ')}': {v}" for k, v in METHODS.items())
        + ". 'In fit': no when a joint movement's axis was left out because a step keeping the "
        "joint still measured the same axis better.",
        size=SIZE["small"],
        colour=MUTED,
    )
