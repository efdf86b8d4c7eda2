"""The course of a long walk: spatio-temporal parameters part by part, and the change from the
first part to the last.

Endurance walks (the six-minute walk test, a long corridor walk) are read for how the gait
changes as the walker tires: speed, cadence and stride time early and late in the walk (motor
fatigue shows in the six-minute walk's speed: Goldman et al. 2008, Mult Scler 14:383; Phan-Ba
et al. 2012, PLoS ONE 7:e34744, as a deceleration index). For a walk whose kept strides span
at least :data:`MIN_SPAN_S`, the kept strides of both sides
(:class:`~motionlab.results.StrideTable`) are pooled in parts of whole minutes, at most
:data:`MAX_PARTS` of them: per part the number of strides and the mean of each parameter of
:data:`COLUMNS` with its standard error ``SD/√n`` (NaN with fewer than
:data:`~motionlab.kinematics.spatiotemporal.MIN_STRIDES` strides). The change from the first
part to the last is given with its 95 % interval ``±1.96 √(se₁² + se₂²)`` (strides taken as
independent samples; the stride-to-stride correlation of real gait makes the true interval
somewhat wider). The leg model's lengths carry a walker's own error (:mod:`.spatiotemporal`),
much the same at one pace, so a change in speed is read with the same model as the level.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from motionlab.kinematics.spatiotemporal import MIN_STRIDES, parameter_unit
from motionlab.results import StrideTable

MIN_SPAN_S = 180.0  # the kept strides of a walk this long (s) or longer are shown by part
MAX_PARTS = 10
COLUMNS = ("cadence_steps_per_min", "stride_time_s", "walking_speed_m_s", "stance_pct")


@dataclass(frozen=True)
class CoursePart:
    """One part of the walk: ``start_s``, ``end_s`` (s), ``strides`` (kept, both sides), and per
    column of :data:`COLUMNS` its ``mean`` and standard error ``se`` (NaN with too few)."""

    start_s: float
    end_s: float
    strides: int
    mean: dict[str, float] = field(default_factory=dict)
    se: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class WalkCourse:
    """The parts of a long walk (:func:`walk_course`) and, per column, the change from the first
    part to the last (``change``) with the half-width of its 95 % interval (``change_ci``)."""

    parts: list[CoursePart]
    change: dict[str, float]
    change_ci: dict[str, float]

    def rows(self) -> pd.DataFrame:
        """The course as a table (``spatiotemporal_course.csv``): per part and parameter
        ``part`` (its time range), ``start_s``, ``end_s``, ``parameter``, ``unit``, ``mean``,
        ``se`` and ``strides``; then per parameter a row ``part`` ``change`` (the last part's
        mean less the first's) with ``ci95`` the half-width of its 95 % interval."""
        rows = [{"part": f"{p.start_s:.0f}-{p.end_s:.0f} s", "start_s": p.start_s,
                 "end_s": p.end_s, "parameter": c, "unit": parameter_unit(c), "mean": p.mean[c],
                 "se": p.se[c], "ci95": np.nan, "strides": p.strides}
                for p in self.parts for c in COLUMNS]  # fmt: skip
        rows += [{"part": "change", "start_s": self.parts[0].start_s,
                  "end_s": self.parts[-1].end_s, "parameter": c, "unit": parameter_unit(c),
                  "mean": self.change[c], "se": np.nan, "ci95": self.change_ci[c],
                  "strides": np.nan} for c in COLUMNS]  # fmt: skip
        return pd.DataFrame(rows)


def walk_course(strides: StrideTable | None) -> WalkCourse | None:
    """The course of the walk in ``strides`` (module docstring); ``None`` when its kept strides
    span less than :data:`MIN_SPAN_S`."""
    if strides is None or not len(strides.start_s):
        return None
    kept = np.asarray(strides.kept, bool)
    start = np.asarray(strides.start_s, float)[kept]
    if len(start) < 2 or start[-1] - start[0] < MIN_SPAN_S:
        return None
    minutes = int(np.ceil((start[-1] - start[0]) / 60.0))
    width = 60.0 * int(np.ceil(minutes / MAX_PARTS))
    edges = start[0] + width * np.arange(int(np.ceil((start[-1] - start[0]) / width)) + 1)
    edges[-1] = max(edges[-1], start[-1] + 1e-9)
    values = {c: _column(strides, c, kept) for c in COLUMNS}
    parts = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        inside = (start >= a) & (start < b)
        mean, se = {}, {}
        for c, v in values.items():
            x = v[inside][np.isfinite(v[inside])]
            ok = len(x) >= MIN_STRIDES
            mean[c] = float(np.mean(x)) if ok else float("nan")
            se[c] = float(np.std(x, ddof=1) / np.sqrt(len(x))) if ok else float("nan")
        parts.append(CoursePart(float(a), float(b), int(inside.sum()), mean, se))
    first, last = parts[0], parts[-1]
    change = {c: last.mean[c] - first.mean[c] for c in COLUMNS}
    ci = {c: 1.96 * float(np.hypot(first.se[c], last.se[c])) for c in COLUMNS}
    return WalkCourse(parts, change, ci)


def _column(strides: StrideTable, column: str, kept: np.ndarray) -> np.ndarray:
    """A stride-table column of the kept strides (NaN where the table has none)."""
    values = getattr(strides, column, None)
    if values is None:
        return np.full(int(kept.sum()), np.nan)
    return np.asarray(values, float)[kept]
