"""The course of a long walk: spatio-temporal parameters part by part, and the change from the
first part to the last.

Endurance walks (the six-minute walk test, a long corridor walk) are read for how the gait
changes as the walker tires: speed, cadence and stride time early and late in the walk (motor
fatigue shows in the six-minute walk's speed: Goldman et al. 2008, Mult Scler 14:383; Phan-Ba
et al. 2012, PLoS ONE 7:e34744, as a deceleration index). Each walking task of the gait
analysis (:attr:`~motionlab.results.Gait.tasks`) lasting at least :data:`MIN_SPAN_S` is taken on
its own (a rest between two walks is no part of either): its kept strides, both sides pooled,
from its first kept stride to its last, are cut into equal parts of at least a minute, at most
:data:`MAX_PARTS`; per part the number of strides and the mean of each parameter of
:data:`COLUMNS` with its standard error ``SD/√n`` (NaN with fewer than
:data:`~motionlab.kinematics.spatiotemporal.MIN_STRIDES` strides). The change from the first
part to the last is given with its 95 % interval ``±1.96 √(se₁² + se₂²)`` (strides taken as
independent samples; the stride-to-stride correlation of real gait makes the true interval
somewhat wider), or withheld with the reason (too few strides in the first or the last part: a
pause there). The leg model's lengths carry a walker's own error (:mod:`.spatiotemporal`), much
the same at one pace, so a change in speed is read with the same model as the level.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from motionlab.kinematics.spatiotemporal import MIN_STRIDES, parameter_unit
from motionlab.results import Gait, StrideTable

MIN_SPAN_S = 180.0  # a walking task this long (s) or longer is shown part by part
MAX_PARTS = 10
COLUMNS = ("cadence_steps_per_min", "stride_time_s", "walking_speed_m_s", "stance_pct")


@dataclass(frozen=True)
class CoursePart:
    """One part of the walk: ``start_s``, ``end_s`` (s, on the session's clock), ``strides``
    (kept, both sides), and per column of :data:`COLUMNS` its ``mean`` and standard error ``se``
    (NaN with too few)."""

    start_s: float
    end_s: float
    strides: int
    mean: dict[str, float] = field(default_factory=dict)
    se: dict[str, float] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """Its time range as ``m:ss–m:ss`` on the session's clock."""
        return f"{_clock(self.start_s)}–{_clock(self.end_s)}"


@dataclass(frozen=True)
class WalkCourse:
    """The parts of one long walking task (:func:`walk_course`) and, per column, the change from
    the first part to the last (``change``) with the half-width of its 95 % interval
    (``change_ci``), NaN with ``withheld`` saying why."""

    task: str
    parts: list[CoursePart]
    change: dict[str, float]
    change_ci: dict[str, float]
    withheld: str = ""

    def rows(self) -> pd.DataFrame:
        """The course as a table (``spatiotemporal_course.csv``): per part and parameter
        ``task``, ``part`` (its time range, m:ss), ``start_s``, ``end_s``, ``parameter``,
        ``unit``, ``mean``, ``se`` and ``strides``; then per parameter a row ``part``
        ``change`` (the last part's mean less the first's) with ``ci95`` the half-width of
        its 95 % interval and ``note`` why it is withheld, where it is."""
        rows = [{"task": self.task, "part": p.label, "start_s": p.start_s, "end_s": p.end_s,
                 "parameter": c, "unit": parameter_unit(c), "mean": p.mean[c], "se": p.se[c],
                 "ci95": np.nan, "strides": p.strides, "note": ""}
                for p in self.parts for c in COLUMNS]  # fmt: skip
        rows += [{"task": self.task, "part": "change", "start_s": self.parts[0].start_s,
                  "end_s": self.parts[-1].end_s, "parameter": c, "unit": parameter_unit(c),
                  "mean": self.change[c], "se": np.nan, "ci95": self.change_ci[c],
                  "strides": None, "note": self.withheld} for c in COLUMNS]  # fmt: skip
        out = pd.DataFrame(rows)
        out["strides"] = out["strides"].astype("Int64")
        return out


def walk_courses(gait: Gait | None) -> list[WalkCourse]:
    """The course of every walking task of ``gait`` lasting at least :data:`MIN_SPAN_S`, in
    time order (module docstring); empty without."""
    if gait is None or not gait.ok or gait.strides is None:
        return []
    blocks = sorted((gait.tasks or {}).items(), key=lambda kv: kv[1].start_s)
    out = []
    for task, block in blocks:
        if block.end_s - block.start_s >= MIN_SPAN_S:
            course = walk_course(gait.strides, task, (block.start_s, block.end_s))
            if course is not None:
                out.append(course)
    return out


def walk_course(
    strides: StrideTable | None, task: str = "walk", span: tuple[float, float] | None = None
) -> WalkCourse | None:
    """The course of the kept strides in ``strides`` that start within ``span`` (s; all of
    them without), named ``task``; ``None`` without two parts of a minute's kept strides."""
    if strides is None or not len(strides.start_s):
        return None
    kept = np.array(strides.kept, bool)  # a copy: the table is the gait result's own
    start_all = np.asarray(strides.start_s, float)
    if span is not None:
        kept &= (start_all >= span[0]) & (start_all <= span[1])
    start = start_all[kept]
    if len(start) < 2:
        return None
    length = float(start[-1] - start[0])
    n_parts = min(MAX_PARTS, int(length // 60.0))
    if n_parts < 2:
        return None
    edges = np.linspace(start[0], start[-1], n_parts + 1)
    values = {c: _column(strides, c, kept) for c in COLUMNS}
    parts = []
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        inside = (start >= a) & ((start < b) if k < n_parts - 1 else (start <= b))
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
    few = [name for name, p in (("first", first), ("last", last)) if p.strides < MIN_STRIDES]
    withheld = (f"fewer than {MIN_STRIDES} steady strides in the {' and '.join(few)} part "
                "(a pause or turns there)") if few else ""  # fmt: skip
    return WalkCourse(task, parts, change, ci, withheld)


#: decimals each column is shown with (more where its interval would read 0)
DIGITS = {"cadence_steps_per_min": 1, "stride_time_s": 2, "walking_speed_m_s": 2, "stance_pct": 1}


def change_text(course: WalkCourse, column: str) -> str:
    """``+a ± b`` of a column's change from the first part to the last, with as many decimals
    as its interval needs to show (up to two more than :data:`DIGITS`); ``-`` where withheld."""
    change, ci = course.change[column], course.change_ci[column]
    if not np.isfinite(change):
        return "-"
    digits = DIGITS[column]
    while digits < DIGITS[column] + 2 and round(ci, digits) == 0:
        digits += 1
    return f"{round(change, digits) + 0.0:+.{digits}f} ± {ci:.{digits}f}"


def _column(strides: StrideTable, column: str, kept: np.ndarray) -> np.ndarray:
    """A stride-table column of the kept strides (NaN where the table has none)."""
    values = getattr(strides, column, None)
    if values is None:
        return np.full(int(kept.sum()), np.nan)
    return np.asarray(values, float)[kept]


def _clock(seconds: float) -> str:
    """``m:ss`` of a time in s."""
    whole = int(round(seconds))
    return f"{whole // 60}:{whole % 60:02d}"
