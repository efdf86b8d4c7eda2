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

Summaries per side: mean, SD (ddof 1) and CV (% = 100 SD/mean). Both sides: cadence from the mean
stride time of all kept strides; step-time asymmetry as the symmetry index of Robinson et al.
(1987, J Manipulative Physiol Ther 10:172), ``100 |R − L| / ((R + L)/2)`` of the mean step times;
stride-time variability as the CV of the stride time (Hausdorff 2005, J NeuroEng Rehabil 2:19).

Walking speed and stride length are **not** computed: the shank and thigh sensors of the walk
protocol give no measured displacement, and a shank-pendulum model's error could not be measured
against a truth here (the simulator's feet slide: it has no foot-floor contact model).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from motionlab.kinematics.gait_events import Strides

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
)


def _last_before(x: np.ndarray, t: float) -> float:
    m = x < t
    return float(x[m][-1]) if m.any() else np.nan


def _first_after(x: np.ndarray, t: float) -> float:
    m = x > t
    return float(x[m][0]) if m.any() else np.nan


def stride_table(
    sides: dict[str, Strides], events: dict[str, dict[str, np.ndarray]]
) -> pd.DataFrame:
    """One row per stride of both sides: ``side, start_s, kept, reason`` and :data:`STRIDE_COLUMNS`.

    ``events`` ``{side: {"ic": (K,), "fc": (M,)}}`` of all detected events (s), for the other
    side's contacts.
    """
    rows = []
    for side, st in sides.items():
        other = "l" if side == "r" else "r"
        ic_o = np.asarray(events.get(other, {}).get("ic", np.zeros(0)))
        fc_o = np.asarray(events.get(other, {}).get("fc", np.zeros(0)))
        for k in range(len(st)):
            t0, fc, t1 = st.ic[k], st.fc[k], st.next_ic[k]
            stride = t1 - t0
            stance = fc - t0
            ic_other = _first_after(ic_o, t0)
            ic_other = ic_other if ic_other < t1 else np.nan
            initial = _first_after(fc_o, t0) - t0
            terminal = fc - ic_other
            ds = initial + terminal
            rows.append(
                {
                    "side": side,
                    "start_s": t0,
                    "kept": bool(st.kept[k]),
                    "reason": st.reason[k],
                    "stride_time_s": stride,
                    "step_time_s": t0 - _last_before(ic_o, t0),
                    "stance_time_s": stance,
                    "swing_time_s": stride - stance,
                    "stance_pct": 100 * stance / stride,
                    "swing_pct": 100 * (stride - stance) / stride,
                    "double_support_pct": 100 * ds / stride if 0 <= ds < stride else np.nan,
                    "cadence_steps_per_min": 120.0 / stride,
                }
            )
    cols = ["side", "start_s", "kept", "reason", *STRIDE_COLUMNS]
    return pd.DataFrame(rows, columns=cols).sort_values("start_s", ignore_index=True)


def _stats(x: pd.Series) -> dict[str, float]:
    x = x.dropna().to_numpy(dtype=float)
    if len(x) == 0:
        return {"mean": np.nan, "sd": np.nan, "cv_pct": np.nan, "strides_n": 0}
    sd = float(np.std(x, ddof=1)) if len(x) > 1 else 0.0
    mean = float(np.mean(x))
    return {
        "mean": mean,
        "sd": sd,
        "cv_pct": 100 * sd / mean if mean else np.nan,
        "strides_n": len(x),
    }


def summary(table: pd.DataFrame) -> dict[str, Any]:
    """Per side ``{column: {mean, sd, cv_pct, n}}`` of kept strides, and the bilateral numbers:
    ``cadence_steps_per_min``, ``step_time_asymmetry_pct``, ``stride_time_cv_pct``,
    ``strides_kept``, ``strides_rejected`` ``{reason: count}``."""
    kept = table[table["kept"]]
    out: dict[str, Any] = {"sides": {}}
    for side in ("r", "l"):
        part = kept[kept["side"] == side]
        out["sides"][side] = {c: _stats(part[c]) for c in STRIDE_COLUMNS}
    stride = kept["stride_time_s"].dropna()
    out["cadence_steps_per_min"] = 120.0 / float(stride.mean()) if len(stride) else np.nan
    r = out["sides"]["r"]["step_time_s"]["mean"]
    left = out["sides"]["l"]["step_time_s"]["mean"]
    out["step_time_asymmetry_pct"] = 100 * abs(r - left) / (0.5 * (r + left))
    out["stride_time_cv_pct"] = _stats(stride)["cv_pct"]
    out["strides_kept"] = int(len(kept))
    rejected = table[~table["kept"]]["reason"].value_counts()
    out["strides_rejected"] = {str(k): int(v) for k, v in rejected.items()}
    return out


def summary_rows(summ: dict[str, Any]) -> pd.DataFrame:
    """The summary as a table ``parameter, side, mean, sd, cv_pct, n`` (for CSV and report)."""
    rows = []
    for side, cols in summ["sides"].items():
        for c, s in cols.items():
            rows.append({"parameter": c, "side": side} | s)
    for c in ("cadence_steps_per_min", "step_time_asymmetry_pct", "stride_time_cv_pct"):
        rows.append({"parameter": c, "side": "both", "mean": summ[c], "sd": np.nan,
                     "cv_pct": np.nan, "strides_n": summ["strides_kept"]})  # fmt: skip
    return pd.DataFrame(rows)
