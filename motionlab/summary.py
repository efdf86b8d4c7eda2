"""A JSON-able summary of a session, shared by ``motionlab info`` and the report."""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.session import CHANNEL_UNITS, MarkerSet, Session


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def model_output_summary(markers: MarkerSet) -> dict[str, dict[str, Any]]:
    """Per model output kind: ``count``, ``units`` (distinct, as the file gives them), ``names``."""
    out: dict[str, dict[str, Any]] = {}
    for o in markers.model_outputs.values():
        entry = out.setdefault(o.kind, {"count": 0, "units": [], "names": []})
        entry["count"] += 1
        entry["names"].append(o.name)
        if o.unit not in entry["units"]:
            entry["units"].append(o.unit)
    return out


def session_summary(session: Session) -> dict[str, Any]:
    """Per sensor: label, rate_hz, n_samples, duration_s, channels, units, gaps, qc; markers too.

    ``rate_hz`` is estimated from the stored time stamps; ``gaps`` are the gaps kept as missing
    (``[start_s, end_s]``), ``flags`` the QC flags (:mod:`motionlab.qc`), ``qc`` every check.
    Marker sets list their model outputs per kind (:func:`model_output_summary`), subjects,
    flags (``duplicate_labels``) and the reader's warnings.
    """
    sensors = []
    for s in session.sensors.values():
        sensors.append(
            {
                "label": s.label,
                "serial": s.serial,
                "vendor": s.vendor,
                "segment": s.segment,
                "side": s.side,
                "rate_hz": _finite(s.rate_hz),
                "n_samples": s.n_samples,
                "duration_s": s.duration_s,
                "start_s": float(s.time[0]) if s.n_samples else None,
                "channels": s.channels,
                "units": {ch: CHANNEL_UNITS[ch] for ch in ["time", *s.channels]},
                "source_units": s.source_units,
                "jitter_ms": s.qc.get("jitter_ms"),
                "gaps": s.qc.get("gaps", []),
                "flags": s.qc.get("flags", {}),
                "qc": s.qc,
                "notes": list(s.attrs.get("notes", [])),
            }
        )
    markers = [
        {
            "name": m.name,
            "rate_hz": _finite(m.rate_hz),
            "n_markers": m.n_markers,
            "n_frames": int(len(m.time)),
            "labels": list(m.labels),
            "units": "m",
            "source_units": m.source_units,
            "rigid_bodies": list(m.rigid_bodies),
            "model_outputs": model_output_summary(m),
            "subjects": m.attrs.get("subjects", []),
            "flags": m.attrs.get("flags", {}),
            "warnings": m.attrs.get("warnings", []),
        }
        for m in session.markers.values()
    ]
    return {
        "schema_version": session.schema_version,
        "metadata": session.metadata,
        "sensors": sensors,
        "markers": markers,
        "results": session.results.stages(),
        "stale": session.lineage.stale(session.results),
        "provenance": session.provenance,
    }
