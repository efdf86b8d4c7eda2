"""Pieces shared by the quaternion KF, the 7-state EKF and the quaternion UKF.

Conventions: quaternions scalar first, sensor → ENU earth; ``gyr`` rad/s, ``acc`` m/s², ``mag``
µT, (N, 3) sensor-frame arrays. Noise parameters are densities, so a filter behaves the same at
any sampling rate: a gyroscope noise density ``σ_g`` (rad/s/√Hz) adds ``σ_g² Δt`` rad² of
attitude variance per sample, a vector-measurement noise density ``σ`` (rad·√s) has per-sample
variance ``σ² / Δt``; the ratio ``σ / σ_g`` is then the correction time constant in seconds.

The numba helpers here work on scalars or preallocated arrays and allocate nothing.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from motionlab.fusion import detect
from motionlab.fusion._common import prepare_mag
from motionlab.fusion.markers import MarkerReferences, interval_rates, scenario
from motionlab.fusion.registry import FusionResult, KernelParams, param, register
from motionlab.fusion.rest import fusion_rest
from motionlab.rotations import make_continuous


@dataclass
class KalmanCommon:
    """Tunables shared by ``kf``, ``ekf`` and ``ukf`` (measurement weighting and detectors)."""

    gyr_noise: float = param(0.005, "rad/s/√Hz", "gyroscope noise density (angle random walk)")
    acc_noise: float = param(
        0.02, "rad·√s", "accelerometer direction noise density (÷gyr_noise = tilt time constant)"
    )
    mag_noise: float = param(
        0.2, "rad·√s", "magnetometer heading noise density (÷gyr_noise = heading time constant)"
    )
    acc_norm_gain: float = param(
        5.0, "rad·√s", "added acc noise per relative deviation of |acc| from g (linear acc.)"
    )
    acc_rate_gain: float = param(0.1, "rad·s^1.5", "added acc noise per rad/s of rotation rate")
    acc_gate: float = param(0.25, "1", "skip acc when | |acc| − g | / g exceeds this")
    att_init: float = param(0.3, "rad", "initial attitude standard deviation")
    startup_time: float = param(3.0, "s", "duration of the start-up phase of fast convergence")
    startup_noise: float = param(
        0.01, "x", "factor on the acc and mag noise during start-up (small: trust them more)"
    )
    mag_norm_tol: float = param(4.0, "µT", "field-norm deviation that marks a magnetic disturbance")
    mag_dip_tol: float = param(
        np.deg2rad(6.0), "rad", "dip-angle deviation that marks a magnetic disturbance"
    )
    rest_gyr_threshold: float = param(0.035, "rad/s", "rest detection: moving-RMS rate threshold")
    rest_acc_threshold: float = param(0.5, "m/s²", "rest detection: moving-RMS acc deviation")
    rest_min_duration: float = param(1.5, "s", "rest detection: minimum rest duration")
    gravity: float = param(9.81, "m/s²", "local gravity")


@dataclass
class Prepared:
    """Inputs of a filter kernel derived once from the whole recording."""

    q0: np.ndarray
    rest: np.ndarray
    mag: np.ndarray
    pre: np.ndarray
    use_mag: bool
    ref_norm: float
    ref_dip: float


def prepare(
    gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None, rate: float, p: KalmanCommon
) -> Prepared:
    """Rest mask, magnetometer reference and pre-flags, and the initial orientation
    (:func:`~motionlab.fusion._common.prepare_mag`)."""
    rest = fusion_rest(
        gyr, acc, rate, p.rest_gyr_threshold, p.rest_acc_threshold, p.rest_min_duration
    )
    q0, mag, pre, use_mag, ref = prepare_mag(gyr, acc, mag, rate, p.mag_norm_tol)
    return Prepared(q0, rest, mag, pre, use_mag, ref[0], ref[1])


def recording(
    gyr: np.ndarray, acc: np.ndarray, rate: float, prep: Prepared, params: KalmanCommon
) -> tuple:
    """The recording as every Kalman kernel takes it, one tuple (one numba argument):
    ``(gyr, acc, mag, use_mag, pre, rest, dt, q0, prm)``: rates rad/s and specific force m/s²
    (N, 3), the field µT (a dummy (1, 3) without one), whether it is used, its pre-flags and
    the rest mask (N,), the step ``dt`` s, the initial orientation and the common parameters
    (:func:`pack`)."""
    dt, prm = 1.0 / rate, pack(params, prep)
    return (gyr, acc, prep.mag, prep.use_mag, prep.pre, prep.rest, dt, prep.q0, prm)


def register_filter(
    name: str,
    params_cls: type,
    description: str,
    kernel: Callable[..., None],
    own: tuple[str, ...],
) -> Callable[..., FusionResult]:
    """Register the EKF's or the UKF's ``run(gyr, acc, mag, rate, params, references=None)``
    (:func:`~motionlab.fusion.registry.register`, estimator ``name``): ``kernel`` over the
    recording by :func:`run_with_markers`, the fields ``own`` of ``params`` as its own
    parameters."""

    @register(name, params_cls, description)
    def run(
        gyr: np.ndarray,
        acc: np.ndarray,
        mag: np.ndarray | None,
        rate: float,
        params: KalmanCommon,
        references: MarkerReferences | None = None,
    ) -> FusionResult:
        values = tuple(float(getattr(params, field)) for field in own)
        return run_with_markers(kernel, name, values, gyr, acc, mag, rate, params, references)

    run.__doc__ = f"{description}: see :mod:`motionlab.fusion.{name}` and :func:`run_with_markers`."
    return run


def run_with_markers(
    kernel: Callable[..., None],
    name: str,
    own: tuple[float, ...],
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None,
    rate: float,
    params: KalmanCommon,
    references: MarkerReferences | None,
) -> FusionResult:
    """Run the EKF's or the UKF's ``kernel`` over the recording (the estimator ``name``).

    The kernel takes four tuples: the recording (:func:`recording`), the filter's own
    parameters ``own`` (floats), the marker reference vectors ``(body (K, 3), earth (N, K, 3),
    NaN = not seen, variance (K,), initial bias (3,))`` (K = 0: IMU only) and the preallocated
    outputs ``(quat, bias, dist, used)``. With marker ``references`` the gyroscope enters as
    the interval mean (:func:`~motionlab.fusion.markers.interval_rates`), the start-up phase
    ends when the markers are first seen, and ``extra["scenario"]`` gives Liu's scenario
    (Table 2) per sample.
    """
    prep = prepare(gyr, acc, mag, rate, params)
    refs = references if references is not None else MarkerReferences.none(len(gyr))
    if references is not None:  # no start-up boost of acc and mag once the markers are seen
        first = np.flatnonzero(refs.visible)
        seen = first[0] / rate if len(first) else np.inf
        params = dataclasses.replace(params, startup_time=min(params.startup_time, seen))
    n = len(gyr)
    quat = np.empty((n, 4))
    bias = np.empty((n, 3))
    dist = np.empty(n, dtype=np.bool_)
    used = np.empty(n, dtype=np.int8)
    kernel(
        recording(gyr if references is None else interval_rates(gyr, 0.0), acc, rate, prep, params),
        own,
        (refs.body, refs.earth, refs.sigma**2, refs.gyro_bias),
        (quat, bias, dist, used),
    )
    extra = {"mag_used": prep.use_mag}
    if references is not None:
        extra["scenario"] = scenario(used)
    return FusionResult(
        make_continuous(quat), name, {}, gyro_bias=bias, rest=prep.rest,
        mag_disturbed=dist if prep.use_mag else None, extra=extra,
    )  # fmt: skip


@numba.njit(cache=True, inline="always")
def acc_variance(
    acc: np.ndarray,
    k: int,
    rate_norm: float,
    g: float,
    prm_noise: float,
    norm_gain: float,
    rate_gain: float,
    gate: float,
    dt: float,
) -> float:
    """Per-sample variance (rad²) of the accelerometer direction, or −1 when it is gated.

    The density ``prm_noise`` grows with the relative deviation of ``|acc|`` from ``g`` and with
    the rotation rate (linear and centripetal acceleration), then is divided by ``Δt``.
    """
    an = np.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
    dev = abs(an - g) / g
    if an <= 0.0 or dev > gate:
        return -1.0
    dens = prm_noise**2 + (norm_gain * dev) ** 2 + (rate_gain * rate_norm) ** 2
    return dens / dt


@numba.njit(cache=True, inline="always")
def mag_ok(q: np.ndarray, mag: np.ndarray, k: int, pre: np.ndarray, prm: np.ndarray) -> bool:
    """Whether sample ``k`` of the field is undisturbed (pre-flag and dip seen through ``q``,
    against the reference field and tolerances of ``prm``, :data:`PRM`)."""
    if pre[k]:
        return False
    return not detect.nb_field_disturbed(
        q[0], q[1], q[2], q[3], mag[k, 0], mag[k, 1], mag[k, 2],
        prm[REF_NORM], prm[REF_DIP], prm[MAG_NORM_TOL], prm[MAG_DIP_TOL],
    )  # fmt: skip


@numba.njit(cache=True, inline="always")
def horizontal_north(r: np.ndarray, mag: np.ndarray, k: int, out: np.ndarray) -> bool:
    """Sensor-frame direction of the field's horizontal part, seen through ``r`` = R(q).

    ``out ← Rᵀ normalise([m_e,x, m_e,y, 0])`` with ``m_e = R m``: a measurement of earth north
    that carries heading only, so a wrong dip angle cannot tilt the estimate. False when the
    field is vertical.
    """
    mx = r[0, 0] * mag[k, 0] + r[0, 1] * mag[k, 1] + r[0, 2] * mag[k, 2]
    my = r[1, 0] * mag[k, 0] + r[1, 1] * mag[k, 1] + r[1, 2] * mag[k, 2]
    h = np.sqrt(mx * mx + my * my)
    if h < 1e-9:
        return False
    mx /= h
    my /= h
    for i in range(3):
        out[i] = r[0, i] * mx + r[1, i] * my
    return True


#: the common float parameters passed to every kernel, and the field reference (see :func:`pack`)
PRM = KernelParams(
    "gyr_noise", "acc_noise", "mag_noise", "acc_norm_gain", "acc_rate_gain", "acc_gate",
    "mag_norm_tol", "mag_dip_tol", "ref_norm", "ref_dip", "gravity", "att_init", "startup_time",
    "startup_var",
)  # fmt: skip
GYR_NOISE, ACC_NOISE, MAG_NOISE, ACC_NORM_GAIN, ACC_RATE_GAIN, ACC_GATE = range(6)
MAG_NORM_TOL, MAG_DIP_TOL, REF_NORM, REF_DIP, GRAVITY, ATT_INIT = range(6, 12)
STARTUP_TIME, STARTUP_VAR = 12, 13


def pack(p: KalmanCommon, prep: Prepared) -> np.ndarray:
    """The common parameters and the field reference as one float array for the kernels."""
    return PRM.pack(p, ref_norm=prep.ref_norm, ref_dip=prep.ref_dip, startup_var=p.startup_noise**2)


@numba.njit(cache=True, inline="always")
def startup_scale(prm: np.ndarray, k: int, dt: float) -> float:
    """Factor on the measurement variances at sample ``k`` (small during the start-up phase)."""
    return prm[STARTUP_VAR] if k * dt < prm[STARTUP_TIME] else 1.0
