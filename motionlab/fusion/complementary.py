"""Complementary filters: Madgwick, Mahony, Liu's Gauss–Newton filter and the adaptive-gain filter.

All four integrate the gyroscope and pull the estimate towards the accelerometer (earth-up) and
magnetometer (north) observations; they differ in how the correction is computed and weighted.
Conventions: ``q`` maps sensor → ENU earth (scalar first); ``gyr`` rad/s, ``acc`` m/s², ``mag``
µT, (N, 3) sensor frame. Every filter starts from :func:`~motionlab.fusion.attitude.
initial_orientation`, runs ``startup_gain`` times its gain for the first ``startup_time`` s (fast
convergence from a poor start), and drops the magnetometer on samples flagged by the field-norm
detector (:func:`~motionlab.fusion.detect.mag_disturbance`) or whose dip, seen through the current
estimate, is off the reference (:func:`~motionlab.fusion.detect.nb_field_disturbed`); it then
carries the heading on the gyroscope. With ``mag=None``, or a magnetometer judged unusable, the
estimate is 6-D.

References
----------
Madgwick, Harrison, Vaidyanathan, "Estimation of IMU and MARG orientation using a gradient descent
algorithm", ICORR 2011, doi:10.1109/ICORR.2011.5975346 (eqs. (25)–(44)).
Mahony, Hamel, Pflimlin, "Nonlinear complementary filters on the special orthogonal group", IEEE
TAC 53(5) 2008, doi:10.1109/TAC.2008.923738 (explicit CF with bias, eq. (32)); To 2018, thesis
eqs. (207)–(211), corrected.
Liu 2010, MS thesis §5.1, eqs. (30), (45), (53)–(55) (reduced-order Gauss–Newton CF).
Tian, Wei, Tan, "An adaptive-gain complementary filter for real-time human motion tracking with
MARG sensors in free-living environments", IEEE TNSRE 21(2) 2013, doi:10.1109/TNSRE.2012.2205706;
defaults from Ricci 2015, thesis §4.2 (β = 0.0756 rad/s, ε_A = 0.25 m/s², ε_M = 2 µT).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motionlab.fusion._cf_kernels import (
    adaptive_kernel,
    liu_kernel,
    madgwick_kernel,
    mahony_kernel,
)
from motionlab.fusion._common import prepare_mag
from motionlab.fusion.markers import MarkerReferences, interval_rates, scenario
from motionlab.fusion.registry import FusionResult, param, register
from motionlab.fusion.rest import fusion_rest
from motionlab.fusion.timegrid import GapNoise, gap_variance


@dataclass
class _Common:
    startup_time: float = param(2.0, "s", "duration of the raised-gain start-up phase")
    startup_gain: float = param(10.0, "x", "gain multiplier during start-up")
    mag_norm_tol: float = param(4.0, "uT", "field-norm deviation that marks a magnetic disturbance")
    mag_dip_tol: float = param(
        np.deg2rad(6.0), "rad", "dip-angle deviation that marks a magnetic disturbance"
    )


@dataclass
class MadgwickParams(_Common):
    beta: float = param(0.1, "rad/s", "gradient-descent gain (gyro error rate), paper eq. (33)")


@dataclass
class MahonyParams(_Common):
    kp: float = param(0.3, "1/s", "proportional gain on the vector-measurement error")
    ki: float = param(0.002, "1/s^2", "integral gain of the gyro-bias estimate")
    mag_weight: float = param(1.0, "1", "weight of the (heading-only) magnetometer error")


@dataclass
class LiuParams(_Common):
    gain: float = param(
        0.3, "1/s", "filter gain g of eq. (45); g*dt = 1 is a full Gauss-Newton step"
    )
    acc_sigma: float = param(1.0, "1", "std of the normalised accelerometer residual (W = 1/sigma)")
    mag_sigma: float = param(1.0, "1", "std of the normalised magnetometer residual (W = 1/sigma)")
    acc_tol: float = param(0.5, "m/s^2", "skip the accelerometer when | |a| - g | exceeds this")
    gravity: float = param(9.81, "m/s^2", "local gravity")
    marker_gain: float = param(1.5, "1/s", "gain g on samples with marker vectors (least)")
    marker_drift: float = param(
        np.deg2rad(1.0),
        "rad/s",
        "error growth while markers are hidden (larger gain when they return)",
    )


@dataclass
class AdaptiveParams(_Common):
    beta: float = param(0.0756, "rad/s", "gyro divergence rate bounding the correction (Ricci)")
    eps_acc: float = param(0.25, "m/s^2", "| |a| - g | above which acc is not used (eps_A)")
    eps_mag: float = param(2.0, "uT", "field-norm deviation above which mag is not used (eps_M)")
    bias_gain: float = param(0.02, "1/s", "rate of the gyro-bias estimate (1/time constant)")
    gravity: float = param(9.81, "m/s^2", "local gravity")


def _prepare(gyr, acc, mag, rate, p: _Common):
    """Initial orientation, start-up length, magnetometer gating inputs and rest mask."""
    rest = fusion_rest(gyr, acc, rate)
    q0, mag, pre, use_mag, ref = prepare_mag(gyr, acc, mag, rate, p.mag_norm_tol)
    n_start = int(round(p.startup_time * rate))
    gating = (ref[0], ref[1], p.mag_norm_tol, p.mag_dip_tol)
    return q0, n_start, mag, pre, use_mag, gating, rest


def _result(quat, dist, use_mag, rest, bias=None, **extra) -> FusionResult:
    # the kernels move q by small normalised increments, so it is already sign-continuous
    return FusionResult(
        quat=quat,
        name="",
        params={},
        gyro_bias=bias,
        rest=rest,
        mag_disturbed=dist if use_mag else None,
        extra={"mag_used": use_mag, **extra},
    )


@register("madgwick", MadgwickParams, "Madgwick gradient-descent filter (IMU and MARG)")
def run_madgwick(gyr, acc, mag, rate, params: MadgwickParams) -> FusionResult:
    """Madgwick's filter: ``q̇ = ½ q ⊗ ω − β ∇f/|∇f|`` (paper eqs. (42)–(44)), ENU references."""
    q0, n_start, mag, pre, use_mag, gating, rest = _prepare(gyr, acc, mag, rate, params)
    quat, dist = madgwick_kernel(
        gyr, acc, mag, pre, q0, 1.0 / rate, params.beta, n_start, params.startup_gain, gating
    )
    return _result(quat, dist, use_mag, rest)


@register("mahony", MahonyParams, "Mahony explicit complementary filter with gyro-bias estimate")
def run_mahony(gyr, acc, mag, rate, params: MahonyParams) -> FusionResult:
    """Mahony's explicit CF: ``ω = ω_gyr − b̂ + Kp e``, ``ḃ = −Ki e``, ``e = Σ v × v̂``.

    The magnetometer error is restricted to the heading (rotation about the estimated vertical)
    so a disturbed field cannot tilt the estimate.
    """
    q0, n_start, mag, pre, use_mag, gating, rest = _prepare(gyr, acc, mag, rate, params)
    quat, bias, dist = mahony_kernel(
        gyr, acc, mag, pre, q0, 1.0 / rate, params.kp, params.ki, params.mag_weight, n_start,
        params.startup_gain, gating,
    )  # fmt: skip
    return _result(quat, dist, use_mag, rest, bias)


@register("liu_gn", LiuParams, "Liu's reduced-order Gauss-Newton complementary filter")
def run_liu(
    gyr, acc, mag, rate, params: LiuParams, references: MarkerReferences | None = None,
    gaps: GapNoise | None = None,
) -> FusionResult:  # fmt: skip
    """Liu (2010) §5.1: predict ``q⁻ = q + Δt/2 q ⊗ ω`` (30), reduced-order Gauss–Newton step
    ``p = (X_pᵀWᵀWX_p)⁻¹X_pᵀWᵀε`` (55) with ``X_p = 2[ŷ]×``, update ``q = q⁻ + gΔt q⁻ ⊗ p`` (45).

    The field reference ``[0, cos δ, −sin δ]`` uses the dip ``δ`` of the undisturbed data.
    Marker ``references`` (:mod:`motionlab.fusion.markers`) add the rows of Table 4 for the
    marker vectors (``X_p = −2R[a]×``, weight ``1/σ²``) where they are seen. There the step
    ``gΔt`` follows a scalar Kalman schedule: the prediction's variance grows by
    ``marker_drift`` while the markers are hidden and shrinks with each marker step
    ``var/(var + r)`` (``r`` the marker solution's variance), never below ``marker_gain·Δt``; so
    the first samples after a gap take nearly full Gauss–Newton steps (Liu's ``gΔt = 1``) and the
    steady state averages the marker noise. The gyroscope enters as the interval mean less the
    registration's bias (:func:`~motionlab.fusion.markers.interval_rates`: the filter has no bias
    state). ``extra["scenario"]`` gives Liu's scenario (Table 2) per sample.

    ``gaps`` (packet-loss gaps bridged in the inputs, :func:`~motionlab.fusion.timegrid.gap_noise`)
    add the rotation each bridge may have missed to that variance at the first recorded sample
    after the gap (it changes nothing without markers): a 0.13-s gap in a simulated shank's
    swing left the estimate 4° off, still 1° 0.8 s later with the markers in view.
    """
    q0, n_start, mag, pre, use_mag, gating, rest = _prepare(gyr, acc, mag, rate, params)
    refs = references if references is not None else MarkerReferences.none(len(gyr))
    quat, dist, used = liu_kernel(
        gyr if references is None else interval_rates(gyr, refs.gyro_bias), acc, mag, pre, q0,
        1.0 / rate, params.gain, 1.0 / params.acc_sigma**2, 1.0 / params.mag_sigma**2,
        params.acc_tol, params.gravity, n_start, params.startup_gain, gating, refs.body,
        refs.earth, 1.0 / refs.sigma**2, params.marker_gain, params.marker_drift,
        gap_variance(gaps, len(gyr)),
    )  # fmt: skip
    if references is None:
        return _result(quat, dist, use_mag, rest)
    return _result(quat, dist, use_mag, rest, scenario=scenario(used))


@register("adaptive_cf", AdaptiveParams, "Adaptive-gain Gauss-Newton complementary filter (Tian)")
def run_adaptive(gyr, acc, mag, rate, params: AdaptiveParams) -> FusionResult:
    """Adaptive-gain CF after Tian et al. (2013) with gyro-bias estimate.

    One Gauss–Newton step from the gyro prediction gives the correction ``δθ`` (rotation vector,
    angle μ) that would fit acc and mag exactly; the filter applies ``γ δθ`` with the adaptive gain
    ``γ = βΔt / (μ + βΔt)`` (convergence rate μ/Δt against gyro divergence rate β, as Madgwick
    2011 eq. (41)). Measurement selection: acc only if ``| |a| − g | < ε_A``, mag only if its norm
    is within ``ε_M`` of the reference and its dip is consistent; with mag alone only the heading
    is corrected. The bias follows ``b̂ ← b̂ − k_b γ δθ``.
    """
    q0, n_start, mag, pre, use_mag, gating, rest = _prepare(gyr, acc, mag, rate, params)
    quat, bias, dist = adaptive_kernel(
        gyr, acc, mag, pre, q0, 1.0 / rate, params.beta, params.eps_acc, params.eps_mag,
        params.bias_gain, params.gravity, n_start, params.startup_gain, gating,
    )  # fmt: skip
    return _result(quat, dist, use_mag, rest, bias)


__all__ = [
    "AdaptiveParams",
    "LiuParams",
    "MadgwickParams",
    "MahonyParams",
    "run_adaptive",
    "run_liu",
    "run_madgwick",
    "run_mahony",
]
