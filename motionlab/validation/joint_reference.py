"""Joint angles from a reference system's segment orientations, clock offset, and agreement.

For rigs and optical systems that export one orientation per segment (a quaternion CSV with
columns ``<segment>_quat_{w,x,y,z}``, NaN where tracking was lost):

- :func:`read_orientation_csv` reads them with the generic reader (rate from ``rate_hz`` or a
  comment line such as ``# sampling frequency: 30``; time = row / rate, s);
- their joint angles come from :func:`motionlab.kinematics.joint_angles.decompose`, as the
  IMU's do (a hinge's angle about its axis; a ball joint's with its sequence);
- :func:`fit_clock_offset` finds the constant offset between two clocks from signals both see
  (angles or angular speeds) by correlation over a bounded search;
- :func:`agreement_metrics` gives RMSE, offset-free RMSE, max error, Pearson r and the sign.

Angles are in rad unless the function says otherwise; times in s.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from motionlab.errors import InputError
from motionlab.io import generic
from motionlab.io.delimited import first_content_line, read_lines

_QUAT = re.compile(r"^(.+)_quat_w$")


def read_orientation_csv(
    path: str | Path, labels: list[str] | None = None, rate_hz: float | None = None
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Time (N,) s and ``{label: quaternion (N, 4)}`` from a CSV of ``<label>_quat_{w,x,y,z}``.

    ``labels`` default to every ``<label>_quat_w`` column of the header. The rate is ``rate_hz``
    or the file's comment line. Rows with a missing quaternion stay NaN.
    """
    path = Path(path)
    if labels is None:
        lines = read_lines(path)
        header = lines[first_content_line(lines)] if lines else ""
        names = [n.strip().strip('"') for n in re.split(r"[,;\t]", header)]
        labels = [m.group(1) for n in names if (m := _QUAT.match(n))]
        if not labels:
            raise InputError(
                "no <segment>_quat_w columns", path, "header", "give the labels explicitly"
            )
    sensors = [
        {"label": lab, "quat": {"columns": [f"{lab}_quat_{c}" for c in "wxyz"]}} for lab in labels
    ]
    options: dict = {"format": "generic", "sensors": sensors}
    if rate_hz is not None:
        options["rate_hz"] = rate_hz
    rec = generic.read(path, options)
    return rec.sensors[0].time, {s.label: s.quat for s in rec.sensors}


def _as_2d(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    return x[:, None] if x.ndim == 1 else x


def fit_clock_offset(
    t_a: np.ndarray,
    x_a: np.ndarray,
    t_b: np.ndarray,
    x_b: np.ndarray,
    max_lag_s: float = 0.2,
    step_s: float = 0.001,
) -> tuple[float, float]:
    """Offset ``d`` (s) with ``x_b(t + d) ≈ x_a(t)`` (so ``t_b = t_a + d``), and its correlation.

    ``x_a`` (N,) or (N, K) and ``x_b`` (M,) or (M, K) are sampled at ``t_a``, ``t_b``; NaN
    samples are left out. Every lag in ±``max_lag_s`` at ``step_s`` is tried; the score is the
    mean over channels of the Pearson correlation on the overlapping finite samples.
    """
    a, b = _as_2d(x_a), _as_2d(x_b)
    if a.shape[1] != b.shape[1]:
        raise InputError(f"{a.shape[1]} and {b.shape[1]} channels do not match")
    lags = np.arange(-max_lag_s, max_lag_s + step_s / 2, step_s)
    scores = np.full(len(lags), -np.inf)
    for i, lag in enumerate(lags):
        rs = []
        for k in range(a.shape[1]):
            bi = np.interp(t_a + lag, t_b, b[:, k], left=np.nan, right=np.nan)
            ok = np.isfinite(bi) & np.isfinite(a[:, k])
            if ok.sum() > 10 and np.std(a[ok, k]) > 0 and np.std(bi[ok]) > 0:
                rs.append(np.corrcoef(a[ok, k], bi[ok])[0, 1])
        if rs:
            scores[i] = float(np.mean(rs))
    k = int(np.argmax(scores))
    if not np.isfinite(scores[k]):
        raise InputError("no overlap between the two signals", remedy="check the time bases")
    return float(lags[k]), float(scores[k])


def wrap_deg(x: np.ndarray) -> np.ndarray:
    """Angles in degrees wrapped to (-180, 180]."""
    return -((-np.asarray(x, dtype=float) + 180.0) % 360.0 - 180.0)


def agreement_metrics(estimate: np.ndarray, reference: np.ndarray) -> dict[str, float | bool]:
    """Agreement of two angle series in degrees on one time base (NaN samples skipped).

    When they are anti-correlated (r < 0: the estimate's axis is flipped) the estimate is
    negated first and ``flipped`` is True. Returns ``rmse_deg``, ``rmse_offset_free_deg`` (mean
    difference removed), ``max_abs_offset_free_deg``, ``mean_diff_deg``, ``r`` (before any
    flip), ``flipped`` and ``n``.
    """
    est = np.asarray(estimate, dtype=float)
    ref = np.asarray(reference, dtype=float)
    ok = np.isfinite(est) & np.isfinite(ref)
    nan = float("nan")
    if ok.sum() < 3:
        return {"rmse_deg": nan, "rmse_offset_free_deg": nan, "max_abs_offset_free_deg": nan,
                "mean_diff_deg": nan, "r": nan, "flipped": False, "n": int(ok.sum())}  # fmt: skip
    e, f = est[ok], ref[ok]
    r = float(np.corrcoef(e, f)[0, 1]) if np.std(e) > 0 and np.std(f) > 0 else nan
    flipped = bool(r < 0)
    d = wrap_deg((-e if flipped else e) - f)
    mean = float(np.degrees(np.angle(np.mean(np.exp(1j * np.radians(d))))))
    free = wrap_deg(d - mean)
    return {
        "rmse_deg": float(np.sqrt(np.mean(d**2))),
        "rmse_offset_free_deg": float(np.sqrt(np.mean(free**2))),
        "max_abs_offset_free_deg": float(np.max(np.abs(free))),
        "mean_diff_deg": mean,
        "r": r,
        "flipped": flipped,
        "n": int(ok.sum()),
    }
