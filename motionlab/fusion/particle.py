"""Particle filter on unit quaternions (To 2012 §6.5; Liu 2014 §5.4); registers ``particle``.

Conventions of :mod:`motionlab.rotations`: scalar-first quaternions mapping sensor → ENU earth.

Model and design (the choices the theses leave open are stated here):

- **Particles.** Each particle is an orientation ``qᵢ = Lᵢ ⊗ G``: ``G`` is the gyroscope strapdown
  integral shared by all particles (To eq. 231, bias-compensated rates) and ``Lᵢ`` the particle's
  own offset. Propagating ``G`` once per sample moves every particle exactly, so the per-particle
  work is only noise, likelihood and weights.
- **Process noise.** Each sample every particle gets an independent rotation ``Lᵢ ← Lᵢ ⊗ exp(n)``
  with ``n`` of variance ``process_noise² · dt`` per axis; the components are drawn uniform
  (matched variance) — their sum over the filter's memory of hundreds of samples is Gaussian, and
  one uniform costs a tenth of a normal.
- **Likelihood** (bootstrap filter, generic weights eq. 151 with the previous weight kept — the
  Bayesian form rather than To's memoryless eq. 234). The measurements are scored as corrections
  of the prior mean, as To's residuals to ``q_obs`` (eqs. 232–233), in information form: each adds
  to ``J`` (3×3) and ``j`` so that a particle with earth-frame offset δᵢ from the prior mean has
  log-likelihood ``jᵀδᵢ − ½ δᵢᵀJδᵢ``. Gravity is a direction measurement (``δ × u = e_z − u``
  with ``u`` the earth-frame acc/g, linear in acc so that zero-mean linear accelerations average
  out instead of pulling with their magnitude); the magnetometer gives the heading only, the
  angle ψ of the field's horizontal part (inclination untouched). Widths ``acc_sigma`` and
  ``mag_sigma`` (smaller ``*_rest_sigma`` at rest) adapt: the acc width grows by
  ``acc_norm_gain · | |acc| − g |/g`` and the acc is ignored beyond ``acc_gate``; the mag weight
  is divided by ``1 + (Δnorm/tol)² + (Δdip/tol)²`` against the reference field of
  :func:`motionlab.fusion.detect.field_reference`, and samples flagged by
  :func:`~motionlab.fusion.detect.mag_disturbance` or by the in-loop dip test are gated. Without a
  usable magnetometer the filter is 6-D (heading from the gyroscope only).
- **Resampling** when the effective sample size ``1/Σwᵢ²`` (eq. 156) drops below
  ``ess_threshold · N``: systematic, residual, deterministic (Kitagawa's fixed offset ½) or
  auxiliary (To App. D-3: multinomial on flattened weights, with the importance correction so the
  estimate stays unbiased). It is followed by regularisation (Musso et al. 2001): every particle is
  moved by a kernel drawn from the **proposal density**, ``bingham`` (anisotropic, shaped by the
  cloud's covariance, band-limited at ``bingham_band`` Mahalanobis radii, To's NU density
  eq. 238–239) or ``vmf`` (isotropic, κ from the cloud's spread, To eq. 235–236), scaled by the
  optimal Gaussian kernel bandwidth for N particles in 3-D, after Liu–West shrinkage towards the
  mean so the cloud's covariance is kept. The default is ``bingham``: the cloud is far narrower
  in tilt (accelerometer) than in heading, and an isotropic kernel of the mean spread, after the
  shrinkage, narrows the heading spread at every resampling — the filter then follows the
  magnetometer too slowly (BROAD 9-D mean 2.26° with ``vmf``, 2.14° with ``bingham``; with the
  former ``mag_sigma`` of 10 rad 3.25° against 2.86°).
- **Gyroscope bias (To §6.5.7, "BC").** One bias estimate shared by the particles (not per
  particle: bias states would make the particles 6-D and need far more of them). At rest
  (:func:`~motionlab.fusion.rest.fusion_rest`) the gyroscope reading is averaged into ``b`` with
  ``bias_rest_tau``; optionally (``bias_tau`` finite, off by default because it cost accuracy on
  the fast BROAD trials) the Mahony-type integral of the filter's own correction: the posterior
  mean's rotation away from the gyro-propagated mean, in the sensor frame ``c``, gives
  ``b ← b − c/bias_tau``.
- **Marker reference vectors** (Liu 2010 §5.4; :mod:`motionlab.fusion.markers`): each marker
  pair seen adds a direction measurement like gravity (its body vector through the prior mean
  against the measured earth direction, width its own noise); a jump beyond that noise spreads
  the cloud first. With them the gyroscope enters as the interval mean
  (:func:`~motionlab.fusion.markers.interval_rates`) and the bias starts from the registration's.
- **Output:** Markley's weighted mean (:mod:`motionlab.fusion.sphere`) every sample.
- **Divergence reset** (To: "κ_post < κ_TH → reset at q_obs"), the monitor of
  :mod:`motionlab.fusion.mekf`: under the posterior mean the accelerometer averages to earth-up
  and the undisturbed field's horizontal part to north. Both earth-frame vectors are low-passed
  over ``reset_tau``; while one is further than ``reset_angle`` from its reference the vectors
  are summed, and a run longer than ``reset_time`` (tilt) or ``reset_heading_time`` (heading,
  field directions agreeing) redraws the cloud about the mean re-aligned with the sums.

Defaults were tuned by hand on the 8 BROAD trials of ``../shared`` (Laidig et al. 2021), which are
also the trials the accuracy is reported on — not an independent test set. With N = 1024 the
9-D mean total RMSE there is 2.14° (MEKF 2.63°, online VQF 2.54°, offline VQF 2.38°), 6-D mean
inclination 0.82° (MEKF 0.82°). The magnetometer weight in motion (``mag_sigma`` 2 rad, not 10)
matters most: fast rotation drifts the heading by up to 1°/5 s through the gyroscope's scale
errors, which only the magnetometer can remove. The reference field is the whole recording's
(:func:`~motionlab.fusion.detect.field_reference`); learning it online with the MEKF's rule did
not help there (trial 30: 2.2° against 2.05°; without the recording-wide disturbance flags the
attached magnet of trial 33 became the reference: 6.8°).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from motionlab.errors import InputError
from motionlab.fusion import _particle_kernels as kern
from motionlab.fusion import detect
from motionlab.fusion.attitude import initial_orientation
from motionlab.fusion.markers import MarkerReferences, interval_rates, scenario
from motionlab.fusion.registry import FusionResult, param, register
from motionlab.fusion.resampling import SCHEMES
from motionlab.fusion.rest import fusion_rest
from motionlab.rotations import make_continuous
from motionlab.units import STANDARD_GRAVITY

PROPOSALS = ("vmf", "bingham")


@dataclass
class ParticleParams:
    """Tunables of the quaternion particle filter."""

    n_particles: int = param(1024, "count", "number of particles N (128–4096)")
    proposal: str = param("bingham", "", "regularisation/reset density: bingham | vmf")
    resampling: str = param("systematic", "", "systematic | residual | deterministic | auxiliary")
    ess_threshold: float = param(0.5, "1", "resample when ESS < this · N")
    aux_alpha: float = param(2.0, "1", "auxiliary resampling flattening α ≥ 1")
    kernel_scale: float = param(1.0, "1", "regularisation kernel / optimal bandwidth")
    bingham_band: float = param(3.0, "1", "Bingham-band limit in Mahalanobis radii")
    process_noise: float = param(0.01, "rad/√s", "orientation random walk per particle")
    acc_sigma: float = param(1.5, "1", "noise of earth-frame horizontal acc/g, motion")
    acc_rest_sigma: float = param(0.1, "1", "noise of earth-frame horizontal acc/g, rest")
    acc_norm_gain: float = param(0.0, "1", "added acc noise per | |acc| − g | / g")
    acc_gate: float = param(20.0, "1", "ignore acc when | |acc| − g | / g exceeds this")
    mag_sigma: float = param(2.0, "rad", "magnetic heading noise per sample, motion")
    mag_rest_sigma: float = param(3.0, "rad", "magnetic heading noise per sample, rest")
    mag_norm_tolerance: float = param(2.0, "µT", "field norm deviation that halves mag weight")
    mag_dip_tolerance: float = param(0.05, "rad", "dip deviation that halves mag weight")
    mag_gate_dip: float = param(0.15, "rad", "dip deviation that gates the magnetometer")
    bias_tau: float = param(np.inf, "s", "time constant of the in-motion bias integral (inf: off)")
    bias_rest_tau: float = param(2.0, "s", "bias averaging time constant at rest")
    bias_max: float = param(0.1, "rad/s", "bound on the bias estimate (0: no BC)")
    init_sigma: float = param(0.1, "rad", "initial/reset cloud spread per axis")
    reset_angle: float = param(
        np.deg2rad(30.0), "rad", "misfit of low-passed gravity/north that starts a run"
    )
    reset_time: float = param(0.5, "s", "a tilt misfit run this long resets the cloud")
    reset_heading_time: float = param(2.0, "s", "a heading misfit run this long resets")
    reset_tau: float = param(1.0, "s", "low-pass time constant of the monitor")
    reset_agree: float = param(0.9, "1", "a heading reset needs the field directions to agree so")
    marker_process_noise: float = param(
        0.005, "rad/√s", "process_noise with marker references (bias known)"
    )
    marker_drift: float = param(
        np.deg2rad(1.0), "rad/s", "error growth while markers are hidden (widens cloud)"
    )
    seed: int = param(0, "", "random seed")


# ---------------------------------------------------------------- public interface


def _check(params: ParticleParams) -> None:
    if not 16 <= params.n_particles <= 1 << 16:
        raise InputError(f"n_particles={params.n_particles} is out of range", remedy="use 128–4096")
    if params.proposal not in PROPOSALS:
        raise InputError(f"unknown proposal {params.proposal!r}", remedy=f"use one of {PROPOSALS}")
    if params.resampling not in SCHEMES:
        raise InputError(
            f"unknown resampling scheme {params.resampling!r}", remedy=f"use one of {SCHEMES}"
        )
    positive = (
        "process_noise", "acc_sigma", "acc_rest_sigma", "acc_gate", "mag_sigma", "mag_rest_sigma",
        "mag_norm_tolerance", "mag_dip_tolerance", "bias_tau", "bias_rest_tau", "init_sigma",
        "reset_angle", "reset_time", "reset_heading_time", "reset_tau", "kernel_scale",
        "bingham_band", "marker_process_noise", "marker_drift",
    )  # fmt: skip
    for name in positive:
        if not getattr(params, name) > 0:
            raise InputError(f"parameter {name}={getattr(params, name)} must be positive")
    if params.aux_alpha < 1:
        raise InputError(f"aux_alpha={params.aux_alpha} must be ≥ 1")


def _pack(p: ParticleParams, g_ref: float, m_ref: float, dip_ref: float) -> np.ndarray:
    """The kernel's parameter vector (:data:`._particle_kernels.PRM`)."""
    return kern.PRM.pack(
        p, gravity=g_ref, ref_norm=m_ref, ref_dip=dip_ref,
        # the optimal Gaussian kernel bandwidth for N particles in d = 3 (Musso et al. 2001)
        kernel_h=p.kernel_scale * (4.0 / (5.0 * p.n_particles)) ** (1.0 / 7.0),
        bingham_zmax=0.5 * p.bingham_band**2,
    )  # fmt: skip


def particle_filter(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None,
    rate: float,
    params: ParticleParams | None = None,
    q0: np.ndarray | None = None,
    references: MarkerReferences | None = None,
) -> FusionResult:
    """Run the quaternion particle filter (see the module docstring for the model).

    Parameters
    ----------
    gyr, acc, mag
        (N, 3) rad/s, m/s², µT in the sensor frame; ``mag=None`` (or a magnetometer disturbed over
        most of the recording) gives a 6-D estimate.
    rate
        Sampling rate in Hz.
    params
        :class:`ParticleParams`; defaults if None.
    q0
        Initial orientation (4,); by default from the first samples
        (:func:`motionlab.fusion.attitude.initial_orientation`).
    references
        Marker reference vectors on the same samples (IMU + marker fusion), validated
        (:meth:`~motionlab.fusion.markers.MarkerReferences.validated`).

    Returns
    -------
    FusionResult with ``quat``, ``gyro_bias``, ``rest``, ``mag_disturbed`` and in ``extra``:
    ``ess`` (N,) effective sample size / N, ``resets`` (sample indices of divergence resets),
    ``six_d`` (bool), and with references ``scenario`` (Liu's Table 2, per sample).
    """
    p = params or ParticleParams()
    _check(p)
    gyr = np.ascontiguousarray(gyr, dtype=float)
    acc = np.ascontiguousarray(acc, dtype=float)
    n_s = len(gyr)
    dt = 1.0 / rate
    rest = fusion_rest(gyr, acc, rate)
    n0 = max(1, int(round(0.1 * rate)))
    use_mag = mag is not None
    flag = np.zeros(n_s, dtype=bool)
    m_ref, dip_ref = 0.0, 0.0
    if use_mag:
        mag = np.ascontiguousarray(mag, dtype=float)
        m_ref, dip_ref = detect.field_reference(mag, acc)
        flag = detect.mag_disturbance(mag, acc, None, rate, reference=(m_ref, dip_ref))
        use_mag = bool(np.isfinite(m_ref)) and detect.mag_usable(flag)
        if use_mag:
            good = np.flatnonzero(~flag[: max(n0, int(2 * rate))])
            init_mag = mag[good[:n0]] if len(good) else None
    if q0 is None:
        q0 = initial_orientation(acc[:n0], init_mag if use_mag else None, n=n0)
    q0 = np.asarray(q0, dtype=float) / np.linalg.norm(q0)
    g_ref = float(np.median(np.linalg.norm(acc[rest], axis=1))) if rest.any() else STANDARD_GRAVITY
    n = int(p.n_particles)
    quat = np.empty((n_s, 4))
    bias = np.empty((n_s, 3))
    ess = np.empty(n_s)
    resets = np.zeros(n_s, dtype=bool)
    gated = np.zeros(n_s, dtype=bool)
    used = np.empty(n_s, dtype=np.int8)
    refs = references if references is not None else MarkerReferences.none(n_s)
    if references is not None:
        p = dataclasses.replace(p, process_noise=p.marker_process_noise)
    kern.nb_filter(
        gyr if references is None else interval_rates(gyr, 0.0), acc, mag if use_mag else acc,
        use_mag, flag, rest, dt, q0, _pack(p, g_ref, m_ref, dip_ref), PROPOSALS.index(p.proposal),
        SCHEMES.index(p.resampling), int(p.seed), n, refs.body, refs.earth, refs.sigma**2,
        refs.gyro_bias, quat, bias, ess, resets, gated, used,
    )  # fmt: skip
    extra = {"ess": ess, "resets": np.flatnonzero(resets), "six_d": not use_mag}
    if references is not None:
        extra["scenario"] = scenario(used)
    return FusionResult(
        quat=make_continuous(quat),
        name="particle",
        params={},
        gyro_bias=bias,
        rest=rest,
        mag_disturbed=gated if use_mag else None,
        extra=extra,
    )


@register(
    "particle",
    ParticleParams,
    "Particle filter on S³ (To 2012): vMF/Bingham-band proposals, bias compensation, resets",
)
def run(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None,
    rate: float,
    params: ParticleParams,
    references: MarkerReferences | None = None,
) -> FusionResult:
    """Registry entry point: :func:`particle_filter` with the initial orientation from the data."""
    return particle_filter(gyr, acc, mag, rate, params, references=references)
