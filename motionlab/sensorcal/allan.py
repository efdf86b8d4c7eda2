"""Overlapping Allan deviation and the noise terms read off its curve (IEEE Std 952-1997, Annex C).

For a rate signal ``y`` sampled every ``τ₀`` s (gyroscope rad/s, accelerometer m/s²), the
overlapping Allan variance at ``τ = m τ₀`` is (Ricci 2015, thesis eqs. 2.13–2.15, in its
overlapping form)::

    σ²(τ) = 1 / (2 (N − 2m + 1)) · Σ_j (ȳ_{j+m} − ȳ_j)²,   ȳ_j = mean of y_j … y_{j+m−1}

computed from the cumulative sum, one vector operation per ``τ``. The curve is fitted with the
IEEE Std 952 model, a sum of independent terms with slopes −1, −1/2, 0, +1/2, +1 on the
log–log plot (quantization, white noise, flicker, rate random walk, rate ramp), by
non-negative least squares in the variance domain (where the estimator is unbiased), and the
noise terms are read off it with the standard conventions:

- white noise (angle / velocity random walk) ``N``: the slope −1/2 line ``σ = N / √τ`` at
  τ = 1 s; unit·√s (= unit/√Hz).
- bias instability ``B``: the flat (flicker) level ``σ_flat = B · √(2 ln 2 / π) ≈ 0.664 B``;
  unit. When the fit shows no flat region (the curve turns up before flattening), the curve's
  minimum is used, ``B = σ_min / 0.664``, an upper bound, flagged.
- rate random walk ``K``: the slope +1/2 line ``σ = K √(τ/3)`` at τ = 3 s; unit/√s.

A term that never carries half of the fitted variance at any τ of the curve is reported as NaN:
the record does not show it (hours are needed to see the rate random walk of a MEMS gyroscope).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import nnls

from motionlab.errors import InputError
from motionlab.sensorcal._validate import positive_rate, samples3

BIAS_INSTABILITY_FACTOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))  # 0.664


@dataclass
class AllanResult:
    """Allan deviation curve and the noise terms read off it, per axis.

    Attributes
    ----------
    tau
        (M,) averaging times, s.
    adev
        (M, 3) overlapping Allan deviation, unit of the signal.
    white
        (3,) white-noise density ``N`` (slope −1/2 at τ = 1 s), unit·√s.
    bias_instability
        (3,) ``B = σ_flat / 0.664``, unit.
    bias_instability_tau
        (3,) τ of the curve's minimum, s.
    bias_instability_flat
        (3,) bool: True if ``B`` is the fitted flat level, False if it is the curve's minimum
        (an upper bound).
    random_walk
        (3,) rate random walk ``K`` (slope +1/2 at τ = 3 s), unit/√s; NaN if not visible.
    duration_s
        Length of the record, s.
    """

    tau: np.ndarray
    adev: np.ndarray
    white: np.ndarray
    bias_instability: np.ndarray
    bias_instability_tau: np.ndarray
    bias_instability_flat: np.ndarray
    random_walk: np.ndarray
    duration_s: float

    def quality(self) -> dict[str, Any]:
        """JSON-able noise figures in the signal's SI unit (NaN becomes None)."""

        def clean(a: np.ndarray) -> list:
            return [None if not np.isfinite(v) else float(v) for v in a]

        return {
            "white_density": clean(self.white),
            "bias_instability": clean(self.bias_instability),
            "bias_instability_tau_s": clean(self.bias_instability_tau),
            "bias_instability_flat": [bool(v) for v in self.bias_instability_flat],
            "rate_random_walk": clean(self.random_walk),
            "duration_s": self.duration_s,
        }


def allan_deviation(
    y: np.ndarray, rate: float, per_decade: int = 10, max_fraction: float = 0.1
) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of the (N, 3) rate signal ``y`` sampled at ``rate`` Hz.

    τ runs over ``per_decade`` log-spaced cluster sizes per decade from one sample to
    ``max_fraction`` of the record. Returns ``(tau (M,), adev (M, 3))``.
    """
    rate = positive_rate(rate)
    y = samples3(y, "signal", 20, "record at least a minute at rest")
    n = len(y)
    m_max = max(1, int(n * max_fraction))
    n_points = int(np.ceil(np.log10(m_max) * per_decade)) + 1
    sizes = np.unique(np.round(np.logspace(0, np.log10(m_max), n_points)).astype(int))
    c = np.vstack((np.zeros((1, 3)), np.cumsum(y - y.mean(axis=0), axis=0)))
    adev = np.empty((len(sizes), 3))
    for i, m in enumerate(sizes):
        d = (c[2 * m :] - 2.0 * c[m:-m] + c[: -2 * m]) / m
        adev[i] = np.sqrt(0.5 * np.mean(d**2, axis=0))
    return sizes / rate, adev


def _fit_terms(tau: np.ndarray, adev: np.ndarray, n_samples: int, rate: float) -> np.ndarray:
    """Coefficients ``(Q, N, B', K, R)`` of the IEEE Std 952 five-term Allan variance model.

    ``σ² = 3Q²/τ² + N²/τ + B'² + K²τ/3 + R²τ²/2`` by non-negative least squares on the relative
    residuals, weighted by the square root of the number of independent clusters and
    re-weighted twice with the model (so a low point does not pull the fit down).
    """
    basis = np.column_stack((3.0 / tau**2, 1.0 / tau, np.ones_like(tau), tau / 3.0, tau**2 / 2.0))
    var = adev**2
    clusters = np.sqrt(n_samples / (tau * rate))
    model = var
    for _ in range(3):
        w = clusters / model
        coef, _ = nnls(basis * w[:, None], var * w)
        model = np.maximum(basis @ coef, var.min() * 1e-6)
    share = basis * coef / model[:, None]
    return np.where(share.max(axis=0) >= 0.5, np.sqrt(coef), np.nan)


def allan_analysis(y: np.ndarray, rate: float, per_decade: int = 10) -> AllanResult:
    """Allan deviation of a static recording and its white, bias-instability and random-walk terms.

    Parameters
    ----------
    y
        (N, 3) rate signal of a sensor at rest (gyroscope rad/s or accelerometer m/s²). Hours
        are needed to see the rate random walk of a MEMS gyroscope.
    rate
        Sampling rate, Hz.
    per_decade
        τ points per decade.

    Returns
    -------
    AllanResult
    """
    rate = positive_rate(rate)
    tau, adev = allan_deviation(y, rate, per_decade)
    if len(tau) < 5:
        raise InputError(
            f"{len(y)} samples give only {len(tau)} averaging times",
            where="signal",
            remedy="record longer at rest (minutes to hours)",
        )
    out = {k: np.full(3, np.nan) for k in ("white", "bias", "bias_tau", "walk")}
    flat = np.zeros(3, dtype=bool)
    for axis in range(3):
        a = adev[:, axis]
        if not (a > 0).all():
            raise InputError("the signal is constant", where=f"axis {axis}", remedy="check it")
        terms = _fit_terms(tau, a, len(y), rate)
        i_min = int(np.argmin(a))
        out["white"][axis] = terms[1]
        out["walk"][axis] = terms[3]
        flat[axis] = bool(np.isfinite(terms[2]))
        out["bias"][axis] = (terms[2] if flat[axis] else a[i_min]) / BIAS_INSTABILITY_FACTOR
        out["bias_tau"][axis] = tau[i_min]
    return AllanResult(
        tau=tau,
        adev=adev,
        white=out["white"],
        bias_instability=out["bias"],
        bias_instability_tau=out["bias_tau"],
        bias_instability_flat=flat,
        random_walk=out["walk"],
        duration_s=len(y) / rate,
    )
