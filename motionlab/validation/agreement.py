"""Agreement between an estimate and a reference curve (joint angles, degrees).

Conventions: both curves are (N,) on one time base, in degrees; the error is
``d = estimate − reference``; NaN samples (either curve) are skipped.

- RMSE, bias (mean of d), SD of d (ddof 1), largest |d|, RMSE after removing the mean offset
  (the SD of d with ddof 0: the waveform error without the offset, as Bailes et al. 2024 report
  it), Pearson's r.
- Bland & Altman (1986, Lancet 327:307): bias and 95 % limits of agreement ``bias ± 1.96 SD``.
- Coefficient of multiple correlation between the two systems, as formulated by Ferrari,
  Cutti & Cappello (2010, Gait Posture 31:540, "CMC between protocols") after Kadaba et al.
  (1989, J Orthop Res 7:849), over G = 2 waveforms of F frames and N cycles::

      CMC = sqrt(1 − [Σ_n Σ_g Σ_f (Y_gnf − Ȳ_nf)² / (N F (G − 1))]
                     / [Σ_n Σ_g Σ_f (Y_gnf − Ȳ_n)² / (N (G F − 1))])

  with Ȳ_nf the mean over systems at frame f of cycle n and Ȳ_n the grand mean of cycle n.
  It is undefined (NaN) when the ratio exceeds 1 (Ferrari's "complex" CMC).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motionlab.kinematics.cycles import CURVE_POINTS, Cycles, find_repetitions, normalise

LOA_Z = 1.96


def cmc(curves: np.ndarray) -> float:
    """Ferrari's CMC of ``curves`` (N cycles, G systems, F frames); NaN when undefined."""
    y = np.asarray(curves, dtype=float)
    if y.ndim == 2:
        y = y[None]
    n, g, f = y.shape
    if g < 2 or f < 2 or not np.isfinite(y).all():
        return float("nan")
    within = np.sum((y - y.mean(axis=1, keepdims=True)) ** 2) / (n * f * (g - 1))
    total = np.sum((y - y.mean(axis=(1, 2), keepdims=True)) ** 2) / (n * (g * f - 1))
    if total <= 0:
        return float("nan")
    ratio = within / total
    return float(np.sqrt(1.0 - ratio)) if ratio <= 1.0 else float("nan")


def agreement(
    estimate: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None
) -> dict[str, Any]:
    """Agreement statistics of two curves (degrees); see the module docstring.

    Returns ``rmse_deg``, ``bias_deg``, ``sd_deg``, ``max_abs_deg``, ``rmse_centred_deg``,
    ``r``, ``cmc``, ``loa_deg`` ([lower, upper]) and ``n_samples``.
    """
    est = np.asarray(estimate, dtype=float)
    ref = np.asarray(reference, dtype=float)
    ok = np.isfinite(est) & np.isfinite(ref)
    if mask is not None:
        ok &= np.asarray(mask, dtype=bool)
    n = int(ok.sum())
    nan = float("nan")
    if n < 2:
        return {
            "rmse_deg": nan, "bias_deg": nan, "sd_deg": nan, "max_abs_deg": nan,
            "rmse_centred_deg": nan, "r": nan, "cmc": nan, "loa_deg": [nan, nan],
            "n_samples": n,
        }  # fmt: skip
    e, r = est[ok], ref[ok]
    d = e - r
    bias = float(d.mean())
    sd = float(d.std(ddof=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        pearson = float(np.corrcoef(e, r)[0, 1]) if e.std() > 0 and r.std() > 0 else nan
    return {
        "rmse_deg": float(np.sqrt(np.mean(d * d))),
        "bias_deg": bias,
        "sd_deg": sd,
        "max_abs_deg": float(np.abs(d).max()),
        "rmse_centred_deg": float(d.std(ddof=0)),
        "r": pearson,
        "cmc": cmc(np.stack([e, r])),
        "loa_deg": [bias - LOA_Z * sd, bias + LOA_Z * sd],
        "n_samples": n,
    }


def repetitions(reference: np.ndarray, rate: float) -> Cycles:
    """Repetitions of the movement in a reference curve (degrees) at ``rate`` Hz
    (:func:`motionlab.kinematics.cycles.find_repetitions`)."""
    return find_repetitions(reference, rate)


def per_repetition(
    estimate: np.ndarray, reference: np.ndarray, reps: Cycles, time: np.ndarray
) -> dict[str, Any]:
    """Agreement per repetition (start..end samples of ``reps``) and the CMC over them.

    Returns arrays ``start_s``, ``end_s``, ``rmse_deg``, ``bias_deg``, ``rom_error_deg``
    (range of motion of the estimate minus that of the reference), ``peak_error_deg`` (value at
    the reference's peak), and ``cmc`` of the time-normalised curves of the repetitions without
    gaps (Ferrari 2010).
    """
    est = np.asarray(estimate, dtype=float)
    ref = np.asarray(reference, dtype=float)
    rows, complete = [], []
    for i, (a, p, b) in enumerate(zip(reps.start, reps.peak, reps.end, strict=True)):
        e, r = est[a : b + 1], ref[a : b + 1]
        ok = np.isfinite(e) & np.isfinite(r)
        if ok.all():
            complete.append(i)
        if ok.sum() < 3:
            continue
        d = e[ok] - r[ok]
        rows.append(
            (
                time[a],
                time[b],
                np.sqrt(np.mean(d * d)),
                d.mean(),
                np.ptp(e[ok]) - np.ptp(r[ok]),
                est[p] - ref[p],
            )
        )
    cols = np.array(rows, dtype=float).reshape(-1, 6)
    kept = Cycles(reps.start[complete], reps.peak[complete], reps.end[complete])
    curves = np.stack([normalise(est, kept, CURVE_POINTS), normalise(ref, kept, CURVE_POINTS)], 1)
    return {
        "n": len(cols),
        "start_s": cols[:, 0],
        "end_s": cols[:, 1],
        "rmse_deg": cols[:, 2],
        "bias_deg": cols[:, 3],
        "rom_error_deg": cols[:, 4],
        "peak_error_deg": cols[:, 5],
        "cmc": cmc(curves) if complete else float("nan"),
    }
