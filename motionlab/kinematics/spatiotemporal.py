"""Spatio-temporal gait parameters per stride and per side (mean, SD, CV), from gait events.

Per kept stride of side ``s`` (initial contact IC to the next IC of the same side, its final
contact FC; ``o`` the other side), times in s:

- stride time ``IC_s(k+1) − IC_s(k)``; stance ``FC_s − IC_s``; swing ``stride − stance``;
  stance and swing in % of the stride;
- step time: from the other side's last IC before ``IC_s(k)`` to ``IC_s(k)`` (the step that lands
  on side ``s``);
- double support: initial (``IC_s`` to the first FC of ``o`` after it) plus terminal (the IC of
  ``o`` inside the stride to ``FC_s``), in % of the stride;
- cadence (steps/min) ``120 / stride time``.

A step time is kept only when the step lies inside one steady bout: the other side's stride that
starts with the step's first contact is kept too and still runs at the step's landing (else NaN:
a step across a turn, a stop or a rejected stride is no step of the walk).

Summaries per side, of the kept strides: mean, SD (ddof 1), CV (% = 100 SD/mean), the standard
error ``SD/√n``, median and interquartile range (``q1``, ``q3``); all NaN with fewer than
:data:`MIN_STRIDES` values (``strides_n`` still says how many). Both sides: cadence from the mean
stride time of all kept strides; step-time asymmetry as the symmetry index of Robinson et al.
(1987, J Manipulative Physiol Ther 10:172), ``100 |R − L| / ((R + L)/2)`` of the mean step times
of *paired* steps only (a step onto the right and the next step onto the left, both kept, the
second starting at the first's landing), at least :data:`MIN_STRIDES` pairs, with its standard
error from the paired differences; stride-time variability as the CV of the stride time (Hausdorff
2005, J NeuroEng Rehabil 2:19) *within* steady bouts (the pooled SD of runs of consecutive kept
strides over the mean: a change of pace after a turn is no variability), with every measured
side at :data:`MIN_STRIDES` strides or more, its standard error ``CV/√(2 dof)`` (the large-sample
error of a CV of normal data, dof the pooled degrees of freedom); the cadence too needs every
measured side at :data:`MIN_STRIDES`. A side is measured when the table has strides of it (its
shank carries a sensor): a recording of one leg gives that leg's cadence and variability, and no
asymmetry. A number not given has its reason in ``withheld`` (``"not enough steady strides (2
of 3 needed)"``). Whatever compares one leg's events or reach with the other's
(:data:`BOTH_LEGS` and the asymmetry) needs both legs' sensors on one clock: where the clock
sync could not link them (:meth:`motionlab.results.ClockSync.not_linked`) it is withheld.

Step length, stride length and walking speed (with thigh and shank sensors and segment lengths):
a double-pendulum leg model after Salarian et al. (2004, IEEE TBME 51:1434) and Aminian et al.
(2002, J Biomech 35:689). Each leg's *reach*, the ankle's distance in front of its hip, is
``L_thigh sin θ_thigh + L_shank sin θ_shank`` with ``θ`` a segment's sagittal inclination from
the vertical (positive with its lower end forward, from its calibrated orientation: gravity only,
no heading). At an initial contact both feet are on the floor, and the step length is the
landing leg's reach minus the other leg's, times :data:`FOOT_ROLL_FACTOR`; a stride is the
other side's step inside it plus the side's own step at its end; speed = stride length / stride
time. Segment lengths: the subject's ``thigh_m`` and ``shank_m`` when given, else 0.245 and
0.246 × ``height_m`` (Winter 2009, Biomechanics and Motor Control of Human Movement, Fig. 4.1);
without either, no lengths are computed.

The ankle-to-ankle distance is shorter than the heel-to-heel step: the trailing foot has rolled
over its forefoot since its own contact. On the real walk (Vicon ``walking2``, thigh and tibia
marker clusters as virtual sensors, lengths from the joint centres, ``bench/gait_real.py``) the
model without the factor was 18-23 % short of the heel markers' steps (n = 4 steps, 3 strides,
one adult at 1.65 m/s); :data:`FOOT_ROLL_FACTOR` = 1.25 is that walk's mean ratio, so its error
there after the factor is a training error, not a test. The simulator cannot test it: its feet
slide in stance (no foot-floor contact model), so its pelvis speed and leg motion disagree
(``bench/gait.py`` reports both).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from motionlab import rotations as rot
from motionlab.kinematics.gait_events import GAP_REASON, SideEvents, Strides
from motionlab.results import GaitEvents, GaitSummary, StrideStats

#: step length = ankle-to-ankle distance × this (module docstring; Vicon walking2, n = 4 steps)
FOOT_ROLL_FACTOR = 1.25
#: thigh and shank length per m of body height (Winter 2009, Fig. 4.1)
LENGTH_FRACTIONS = {"thigh": 0.245, "shank": 0.246}
#: the model, for the CSV, summary and report
LENGTH_MODEL = (
    "double pendulum (thigh + shank inclination and lengths) at initial contact, × 1.25 for "
    "the foot roll (Salarian 2004, Aminian 2002); real walk: 18-23 % short without the factor"
)

#: fewest kept strides of a side (or paired steps) from which a summary number is given
MIN_STRIDES = 3

#: bounds (s) of the event detector's own timing error, rounded up from docs/kinematics.md:
#: initial contact within 3 ms on the real walk (n = 4) and 0.4-1.5 ms on the simulator; final
#: contact 9-16 ms after the force plates (n = 2), -14 to +8 ms from Zeni's (n = 4)
IC_ERROR_S, FC_ERROR_S = 0.01, 0.02
#: bound (s) of how early the shank may stop swinging before the heel lands, a bias of the
#: walker's, the same at every initial contact: 25-35 ms on the real 16-IMU walk against its
#: feet' heel points, -1 ms on the Vicon walk (docs/kinematics.md). It cancels in the times
#: from one initial contact to another and enters those from an initial to a final contact
IC_BIAS_S = 0.035
#: relative bound of the leg model's step and stride length and speed: 2 % on the real walk
#: its foot-roll factor was taken from (a training error), +12 % on the real 16-IMU walk against
#: its feet's integration (docs/kinematics.md)
LENGTH_ERROR = 0.12

#: per-stride columns (units in the names)
STRIDE_COLUMNS = (
    "stride_time_s",
    "step_time_s",
    "stance_time_s",
    "swing_time_s",
    "stance_pct",
    "swing_pct",
    "double_support_pct",
    "cadence_steps_per_min",
    "step_length_m",
    "stride_length_m",
    "walking_speed_m_s",
)
#: per-stride columns that need the other leg's events or reach at one instant (a step lands
#: from the other foot): with the legs' clocks not linked they are withheld, with the asymmetry
BOTH_LEGS = ("step_time_s", "double_support_pct", "step_length_m", "stride_length_m",
             "walking_speed_m_s")  # fmt: skip


def sagittal_inclination(q: np.ndarray) -> np.ndarray:
    """Inclination (rad) of ISB segments (segment → earth ``q`` (N, 4)) from the vertical in
    their own sagittal plane, positive with the lower end forward: ``atan2(x_up, y_up)``."""
    q = np.asarray(q, dtype=float)
    x = rot.rotate(q, np.array([1.0, 0.0, 0.0]))
    y = rot.rotate(q, np.array([0.0, 1.0, 0.0]))
    return np.arctan2(x[..., 2], y[..., 2])


def leg_reach(
    q_thigh: np.ndarray, q_shank: np.ndarray, thigh_m: float, shank_m: float
) -> np.ndarray:
    """Forward distance (m) of the ankle from the hip in the leg's sagittal plane, from the
    thigh and shank orientations (segment → earth, same samples) and lengths (m)."""
    return thigh_m * np.sin(sagittal_inclination(q_thigh)) + shank_m * np.sin(
        sagittal_inclination(q_shank)
    )


def segment_lengths(subject: dict[str, Any] | None) -> tuple[float, float, str] | None:
    """``(thigh_m, shank_m, source)`` from the subject metadata (``thigh_m`` and ``shank_m``,
    else ``height_m`` × :data:`LENGTH_FRACTIONS`), or None without them."""
    subject = subject or {}
    try:
        t, s = float(subject["thigh_m"]), float(subject["shank_m"])
        if 0.1 < t < 1.0 and 0.1 < s < 1.0:
            return t, s, "subject thigh_m and shank_m"
    except (KeyError, TypeError, ValueError):
        pass
    try:
        h = float(subject["height_m"])
    except (KeyError, TypeError, ValueError):
        return None
    if not 0.5 <= h <= 2.5:
        return None
    thigh, shank = LENGTH_FRACTIONS["thigh"] * h, LENGTH_FRACTIONS["shank"] * h
    return thigh, shank, f"{h:g} m height × Winter's fractions"


def _step(reach: dict[str, tuple[np.ndarray, np.ndarray]], side: str, t: float) -> float:
    """Step length (m) landing on ``side`` at its initial contact ``t``."""
    other = "l" if side == "r" else "r"
    if side not in reach or other not in reach or not np.isfinite(t):
        return np.nan
    at = {s: float(np.interp(t, *reach[s], left=np.nan, right=np.nan)) for s in (side, other)}
    return FOOT_ROLL_FACTOR * (at[side] - at[other])


def _last_before(x: np.ndarray, t: float) -> float:
    m = x < t
    return float(x[m][-1]) if m.any() else np.nan


def _first_after(x: np.ndarray, t: float) -> float:
    m = x > t
    return float(x[m][0]) if m.any() else np.nan


def _steady_step(other: Strides | None, t0: float, ic_o: np.ndarray) -> float:
    """Time (s) of the step that lands at ``t0``, from the other side's last contact before it;
    NaN unless the other side's stride starting there is kept and still runs at ``t0`` (the step
    lies inside one steady bout)."""
    start = _last_before(ic_o, t0)
    if other is None or not np.isfinite(start):
        return np.nan
    j = np.flatnonzero(np.isclose(other.ic, start, atol=1e-9))
    if len(j) == 0 or not other.kept[j[0]] or other.next_ic[j[0]] < t0:
        return np.nan
    return float(t0 - start)


def stride_table(
    sides: dict[str, Strides],
    events: dict[str, GaitEvents | SideEvents],
    reach: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> pd.DataFrame:
    """One row per stride of both sides: ``side, start_s, kept, reason`` and :data:`STRIDE_COLUMNS`.

    ``events`` ``{side: events}`` of all detected events (their ``ic`` (K,) and ``fc`` (M,),
    s), for the other side's contacts; ``reach`` ``{side: (time s, leg reach m)}``
    (:func:`leg_reach`) for the lengths and speed (NaN without it).
    """
    reach = reach or {}
    rows = []
    for side, st in sides.items():
        other = "l" if side == "r" else "r"
        ev = events.get(other)
        ic_o = np.asarray(ev.ic) if ev is not None else np.zeros(0)
        fc_o = np.asarray(ev.fc) if ev is not None else np.zeros(0)
        for k in range(len(st)):
            t0, fc, t1 = st.ic[k], st.fc[k], st.next_ic[k]
            stride = t1 - t0
            stance = fc - t0
            ic_other = _first_after(ic_o, t0)
            ic_other = ic_other if ic_other < t1 else np.nan
            initial = _first_after(fc_o, t0) - t0
            terminal = fc - ic_other
            ds = initial + terminal
            length = _step(reach, other, ic_other) + _step(reach, side, t1)
            rows.append(
                {
                    "side": side,
                    "start_s": t0,
                    "kept": bool(st.kept[k]),
                    "reason": st.reason[k],
                    "stride_time_s": stride,
                    "step_time_s": _steady_step(sides.get(other), t0, ic_o),
                    "stance_time_s": stance,
                    "swing_time_s": stride - stance,
                    "stance_pct": 100 * stance / stride,
                    "swing_pct": 100 * (stride - stance) / stride,
                    "double_support_pct": 100 * ds / stride if 0 <= ds < stride else np.nan,
                    "cadence_steps_per_min": 120.0 / stride,
                    "step_length_m": _step(reach, side, t0),
                    "stride_length_m": length,
                    "walking_speed_m_s": length / stride,
                }
            )
    cols = ["side", "start_s", "kept", "reason", *STRIDE_COLUMNS]
    return pd.DataFrame(rows, columns=cols).sort_values("start_s", ignore_index=True)


def method_error(column: str, value: float, stride_s: float) -> float:
    """Bound of the method's own error (the column's unit) on a per-side mean of ``column``
    (:data:`STRIDE_COLUMNS`, or ``step_time_asymmetry_pct``), from the event timing bounds
    :data:`IC_ERROR_S`, :data:`FC_ERROR_S` and :data:`LENGTH_ERROR`; ``stride_s`` the mean stride
    time (s). A time between two initial contacts carries one IC error (their common bias
    cancels), one from an IC to an FC both and the walker's IC bias :data:`IC_BIAS_S`; double
    support has two such intervals. The stride-time CV has none (a constant bias does not vary).
    NaN for an unknown column."""
    ic = IC_ERROR_S
    ic_fc = IC_ERROR_S + IC_BIAS_S + FC_ERROR_S
    pct = 100.0 / stride_s
    bounds = {
        "stride_time_s": ic,
        "step_time_s": ic,
        "stance_time_s": ic_fc,
        "swing_time_s": ic_fc,
        "stance_pct": ic_fc * pct,
        "swing_pct": ic_fc * pct,
        "double_support_pct": 2 * ic_fc * pct,
        "cadence_steps_per_min": 120.0 * ic / stride_s**2,
        "step_length_m": LENGTH_ERROR * abs(value),
        "stride_length_m": LENGTH_ERROR * abs(value),
        "walking_speed_m_s": LENGTH_ERROR * abs(value),
        "step_time_asymmetry_pct": 200.0 * ic / stride_s,
        "stride_time_cv_pct": 0.0,
    }
    return float(bounds.get(column, np.nan))


def _stats(x: pd.Series) -> StrideStats:
    """Mean, SD, CV, SE, median, q1, q3 (NaN below :data:`MIN_STRIDES` values) and
    ``strides_n``."""
    x = x.dropna().to_numpy(dtype=float)
    if len(x) < MIN_STRIDES:
        nan = np.nan
        return StrideStats(nan, nan, nan, nan, nan, nan, nan, strides_n=len(x))
    sd = float(np.std(x, ddof=1))
    mean = float(np.mean(x))
    q1, median, q3 = (float(v) for v in np.percentile(x, [25, 50, 75]))
    return StrideStats(
        mean=mean,
        sd=sd,
        cv_pct=100 * sd / mean if mean else np.nan,
        se=float(sd / np.sqrt(len(x))),
        median=median,
        q1=q1,
        q3=q3,
        strides_n=len(x),
    )


def _within_bout_cv(kept: pd.DataFrame) -> tuple[float, int]:
    """``(CV %, degrees of freedom)`` of the stride time within steady bouts: the pooled SD of
    each side's runs of consecutive kept strides (a stride starting where the one before ended)
    over the mean stride time, so that a change of pace between bouts (after a turn or a stop)
    is not counted as variability."""
    ss, dof, values = 0.0, 0, []
    for side in ("r", "l"):
        part = kept[kept["side"] == side].dropna(subset=["stride_time_s"])
        start = part["start_s"].to_numpy(dtype=float)
        stride = part["stride_time_s"].to_numpy(dtype=float)
        breaks = np.flatnonzero(~np.isclose(start[1:], (start + stride)[:-1], atol=1e-6)) + 1
        for bout in np.split(stride, breaks):
            if len(bout) > 1:
                ss += float(np.sum((bout - bout.mean()) ** 2))
                dof += len(bout) - 1
        values += list(stride)
    if dof == 0:
        return np.nan, 0
    return float(100 * np.sqrt(ss / dof) / np.mean(values)), dof


def withhold_both_legs(table: pd.DataFrame) -> pd.DataFrame:
    """The stride table with its :data:`BOTH_LEGS` columns NaN: with the two legs' sensors on
    clocks nothing linked, a step time, double support or step length compares one leg's event
    with the other's at an unknown offset (on a simulated walk without a pelvis sensor, 25 ms
    read as 10 % step-time asymmetry)."""
    return table.assign(**{c: np.nan for c in BOTH_LEGS})


def too_few(n: int, what: str = "steady strides") -> str:
    """``'not enough steady strides (2 of 3 needed)'``."""
    return f"not enough {what} ({n} of {MIN_STRIDES} needed)"


def _paired_steps(kept: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """``(right, left)`` step times (s) of consecutive pairs: a kept step onto the right and the
    kept step onto the left that starts at its landing (both inside one steady bout)."""
    steps = kept.dropna(subset=["step_time_s"])
    left = steps[steps["side"] == "l"]
    left_start = (left["start_s"] - left["step_time_s"]).to_numpy()
    r_out, l_out = [], []
    for _, row in steps[steps["side"] == "r"].iterrows():
        j = np.flatnonzero(np.isclose(left_start, row["start_s"], atol=1e-6))
        if len(j):
            r_out.append(row["step_time_s"])
            l_out.append(left["step_time_s"].to_numpy()[j[0]])
    return np.asarray(r_out, dtype=float), np.asarray(l_out, dtype=float)


def summary(table: pd.DataFrame, not_linked: str = "") -> GaitSummary:
    """Per side the statistics of each stride-table column over the kept strides, and the
    bilateral numbers (:class:`~motionlab.results.GaitSummary`; module docstring).
    ``not_linked``: why the two legs' clocks are not one (:func:`withhold_both_legs`): the
    :data:`BOTH_LEGS` columns and the asymmetry are then withheld with it."""
    if not_linked:
        table = withhold_both_legs(table)
    kept = table[table["kept"]]
    sides: dict[str, dict[str, StrideStats]] = {}
    withheld: dict[str, str] = {}
    counts = {}
    for side in ("r", "l"):
        part = kept[kept["side"] == side]
        sides[side] = {c: _stats(part[c]) for c in STRIDE_COLUMNS}
        counts[side] = int(part["stride_time_s"].notna().sum())
    stride = kept["stride_time_s"].dropna()
    measured = [side for side in ("r", "l") if (table["side"] == side).any()]
    fewest = min((counts[side] for side in measured), default=0)
    cadence = np.nan
    if fewest >= MIN_STRIDES:
        cadence = 120.0 / float(stride.mean())
    else:
        withheld["cadence_steps_per_min"] = too_few(fewest) + " on one side"
    r, left = _paired_steps(kept)
    asym = asym_se = np.nan
    if len(r) >= MIN_STRIDES:
        total = float(r.mean() + left.mean())
        asym = 200 * abs(float(r.mean() - left.mean())) / total
        diff_se = float(np.std(r - left, ddof=1)) / np.sqrt(len(r))
        asym_se = float(200 * diff_se / total)
    elif len(measured) == 1:
        leg = "right" if measured == ["r"] else "left"
        withheld["step_time_asymmetry_pct"] = f"only the {leg} leg measured: needs both legs"
    else:
        withheld["step_time_asymmetry_pct"] = too_few(len(r), "paired steady steps")
    cv = cv_se = np.nan
    if fewest >= MIN_STRIDES:
        cv, dof = _within_bout_cv(kept)
        cv_se = float(cv / np.sqrt(2 * dof)) if dof else np.nan
    else:
        withheld["stride_time_cv_pct"] = too_few(fewest) + " on one side"
    speed = kept["walking_speed_m_s"].dropna()
    if 0 < len(speed) < MIN_STRIDES:
        withheld["walking_speed_m_s"] = too_few(len(speed))
    if not_linked and len(measured) == 2:
        withheld |= {c: not_linked for c in (*BOTH_LEGS, "step_time_asymmetry_pct")}
    rejected = table[~table["kept"]]["reason"].value_counts()
    lost = int(rejected.get(GAP_REASON, 0))
    if lost:  # say what the strides missing from a "not enough" were lost to
        gaps = f"; {lost} stride{'s' if lost > 1 else ''} lost to data gaps"
        withheld = {k: v + gaps if v.startswith("not enough") else v for k, v in withheld.items()}
    return GaitSummary(
        sides=sides,
        min_strides=MIN_STRIDES,
        cadence_steps_per_min=cadence,
        step_pairs=len(r),
        step_time_asymmetry_pct=asym,
        step_time_asymmetry_se_pct=asym_se,
        stride_time_cv_pct=cv,
        stride_time_cv_se_pct=cv_se,
        walking_speed_m_s=float(speed.mean()) if len(speed) >= MIN_STRIDES else np.nan,
        strides_kept=int(len(kept)),
        strides_rejected={str(k): int(v) for k, v in rejected.items()},
        withheld=withheld,
    )


def parameter_unit(parameter: str) -> str:
    """The unit a parameter's name ends in (``stride_time_s`` → ``s``)."""
    for suffix, unit in (("_steps_per_min", "steps/min"), ("_m_s", "m/s"), ("_pct", "%"),
                         ("_m", "m"), ("_s", "s")):  # fmt: skip
        if parameter.endswith(suffix):
            return unit
    return ""


def summary_rows(summ: GaitSummary) -> pd.DataFrame:
    """The summary as a table ``parameter, side, unit, mean, sd, cv_pct, se, median, q1, q3,
    count_n, count_of, note`` (for CSV and report): ``unit`` of the parameter's values (its
    name's suffix), ``count_n`` how many kept strides have a value of the parameter (what the
    mean is of; the walking speed's 0 where no stride has a length, not every kept stride),
    ``count_of`` of what (``strides``; ``step pairs`` for the step-time asymmetry), ``note`` why
    a bilateral number, or a per-side one of :data:`BOTH_LEGS`, is withheld (empty when given);
    the bilateral numbers have their ``se`` where known."""
    rows = []
    for side, cols in summ.sides.items():
        for c, s in cols.items():
            rows.append({"parameter": c, "side": side, "unit": parameter_unit(c), "mean": s.mean,
                         "sd": s.sd, "cv_pct": s.cv_pct, "se": s.se, "median": s.median,
                         "q1": s.q1, "q3": s.q3, "count_n": s.strides_n,
                         "count_of": "strides"})  # fmt: skip

    def valued(c: str) -> int:  # the kept strides with a value of c, both sides
        return sum(cols[c].strides_n for cols in summ.sides.values())

    both = (("cadence_steps_per_min", summ.cadence_steps_per_min, np.nan,
             valued("stride_time_s")),
            ("step_time_asymmetry_pct", summ.step_time_asymmetry_pct,
             summ.step_time_asymmetry_se_pct, summ.step_pairs),
            ("stride_time_cv_pct", summ.stride_time_cv_pct, summ.stride_time_cv_se_pct,
             valued("stride_time_s")),
            ("walking_speed_m_s", summ.walking_speed_m_s, np.nan,
             valued("walking_speed_m_s")))  # fmt: skip
    for c, value, se, n in both:
        of = "step pairs" if c == "step_time_asymmetry_pct" else "strides"
        rows.append({"parameter": c, "side": "both", "unit": parameter_unit(c), "mean": value,
                     "sd": np.nan, "cv_pct": np.nan, "se": se, "median": np.nan, "q1": np.nan,
                     "q3": np.nan, "count_n": n, "count_of": of})  # fmt: skip
    for row in rows:
        c = row["parameter"]
        row["note"] = summ.withheld.get(c, "") if row["side"] == "both" or c in BOTH_LEGS else ""
    return pd.DataFrame(rows)
