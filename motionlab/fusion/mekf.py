"""Multiplicative (error-state) EKF with gyroscope- and accelerometer-bias states, and its RTS
smoother.

Registers ``mekf`` (the forward filter, causal) and ``smoother`` (the offline forward–backward
Rauch–Tung–Striebel smoother over the same filter, motionlab's default estimator).

Model (conventions of :mod:`motionlab.rotations`: scalar-first quaternions, sensor → ENU earth):

- state: orientation ``q``, gyroscope bias ``b`` (rad/s) and accelerometer bias ``a`` (m/s²,
  sensor frame); error state ``[δθ, δb, δa]`` with the attitude error a small rotation in the
  earth frame, ``q_true = exp(δθ/2) ⊗ q`` — the multiplicative EKF of Markley (J. Guid. Control
  Dyn. 26(2), 2003) with the quaternion correction applied multiplicatively (Liu thesis eq.
  (106), corrected form in the notes); biases as additive error states (Solà, *Quaternion
  kinematics for the error-state Kalman filter*, 2017, §5);
- process: ``q_k = q_{k-1} ⊗ exp((ω_k − b) dt/2)``, gyroscope white noise (angle random walk),
  and random walks of both biases (``bias_rw``, ``acc_bias_rw``); the accelerometer bias starts
  at 0 with standard deviation ``acc_bias_init``;
- rest: the gyroscope measures the bias directly, a strong bias update (the idea of VQF's rest
  bias estimation, Laidig & Seel 2023). ``mekf`` detects rest from past samples only
  (:func:`causal_rest`), the smoother with the centred window of
  :func:`motionlab.fusion.rest.fusion_rest`, and the smoother's bias update takes only the
  rest's **steady** stretches (:func:`motionlab.fusion.detect.steady_mask`, ``rest_sway``): a
  person sitting "still" sways and turns slowly at 0.3–0.7°/s, under the rest's 2°/s, and the
  mean of that movement was taken for the bias (the shared trunk recordings: a seated back's
  0.6°/s over a 2 s rest became a heading drift of 0.5°/s, 7° over the next 14 s against
  OptiTrack, where VQF, which found no rest there, kept 1°; Danique/trunkmovement_hs). Where
  a rest is not steady the bias comes from its prior and the movement, as in motion. A sensor
  set down is steady (BROAD's rests vary by 0.02°/s; its results are unchanged);
- accelerometer: the horizontal part of the earth-frame ``R (acc − a) / g`` against earth-up,
  two scalar rows ``e_z × δθ + R δa / g`` (the vertical row is not used: it would tie the bias
  to ``|acc| − g``, i.e. to scale errors and the local gravity), with a constant noise
  (``acc_noise`` in motion, ``acc_rest_noise`` at rest). Linear in ``acc`` and not gated by
  ``|acc|``: weighting samples by their own ``|acc|`` deviation biased the inclination on BROAD's
  translation trials, whereas a small constant gain lets zero-mean linear acceleration average
  out. The bias columns ``R δa / g`` are in the rows of rest samples only: in motion a limb's
  linear acceleration is correlated with its orientation in the sensor frame (the centripetal
  acceleration of a swinging shank points along it), and with the bias in the motion rows the
  filter took that for a bias (simulated walks, seeds 2, 3, 5: bias error 0.19–0.26 m/s² for
  a true σ of 0.1; BROAD: mean inclination error 0.56° → 3.9°). So the bias is what makes the
  rests agree with the attitude that the movement and the gyroscope carry to them: several
  rests in different poses, or one rest next to movement that fixes the inclination by itself
  (a walk with turns, whose horizontal bias turns in the earth frame and averages out). A
  sensor-to-segment calibration taken at such a rest is then less tilted by the bias (it reads
  ``acc − a`` with ``a`` from this smoother at the wider prior
  :data:`motionlab.fusion.stage.CALIBRATION_ACC_BIAS_INIT`,
  :func:`motionlab.fusion.stage.calibration_acc_bias`). How far the filter believes the
  movement over the rest is set by ``acc_bias_init`` against the gyroscope noise of the model
  (a catch-all tuned on BROAD, far above a MEMS gyroscope's): the default 0.1 m/s² (a
  datasheet-level offset, the simulator's ``typical`` σ) takes about a tenth of the stand's tilt
  error away on simulated stand + walk sessions (seeds 20–25, 30 sensors: mean 0.81° → 0.74°;
  0.5 m/s² → 0.45°) and leaves BROAD as it was (mean total 1.580° → 1.587°); larger priors help
  the simulator more and BROAD less (0.2: 0.62°, 1.603°; 0.5: 0.45°, 1.70°: on BROAD's
  translation trials the movement's inclination is the worse one). Where the recording does
  not determine the bias (one static pose) the innovations have zero mean and the bias stays at
  0: the orientation is that of the 6-state filter (``acc_bias_init = 0`` gives exactly the
  6-state filter). The estimate, (N, 3) m/s², is
  ``FusionResult.extra["acc_bias"]``. Cost when they came (``bench/throughput.py``, BROAD
  9-D, same run): smoother 465k → 275k samples/s, mekf 1.61M → 1.34M (see "Where the time
  goes" below for today's);
- the smoother's accelerometer is low-passed first (``acc_lowpass_tau``, :func:`lowpassed_acc`):
  in a frame the gyroscope carries (bias-corrected strapdown), where gravity stays put however
  the sensor turns and a limb's linear acceleration, which changes sign within a movement,
  averages out — VQF's accelerometer pre-filter (Laidig & Seel, Inf. Fusion 91, 2023), here
  zero-phase, with the biases of a first pass (the 9-D smoother's 6-D gate pass; in 6-D an
  extra pass at the update instants only) and its own, smaller noise ``acc_lowpass_noise``
  (the filtered signal holds less of the movement). Rest samples keep the raw accelerometer;
  a recording whose first pass reset keeps it throughout (accelerometer data that contradicted
  the state, low-passed, would be spread over seconds and trusted more: a 0.5-s wrong start
  left 20° at the start and 1.7° after a minute instead of a reset).
  Chosen on BROAD (the tuning set): over τ 0.5–2 s × noise 0.3–0.8 the mean total lies within
  1.519–1.527° and the inclination within 0.512–0.545°; τ = 1 s, 0.5: total 1.58 → 1.52°,
  heading 1.40 → 1.36°, inclination 0.56 → 0.51° (offline VQF 0.52°), worst trial 5.27 →
  5.32°. On the real trunk recordings (not tuned on, ``bench/real_trunk.py``) the lumbar
  rotation from rest's median 1.62 → 1.57°; the simulated benches are in
  docs/kinematics.md ("The smoother's accelerometer pre-filter");
- magnetometer: heading only — the angle of the horizontal part of the earth-frame field updates
  the vertical attitude error and the gyroscope bias, never the inclination (Joseph-form update
  with the gains of the inclination and of the accelerometer bias zeroed). Disturbances are
  judged per sample by the field norm and dip against a reference learned online; a new field
  that stays steady for as long as the reference was seen (between ``mag_new_field_min`` and
  ``mag_new_field_time``) becomes the reference (``mekf``).

The smoother (offline) gates the magnetometer from the whole recording instead: a 6-D smoother
pass (the same filter without the magnetometer) gives the inclination, under which each update
block's mean field (its samples' fields in the earth frame, averaged) is compared in norm and dip
with the recording's own robust (median) reference — scale-free, so a field in arbitrary units
or of any strength works (:func:`motionlab.fusion.detect.field_gate`, hysteresis and hold).
Gated blocks are not used (the gyroscope coasts, the RTS pass bridges them), the others get a
heading variance growing with their deviation (``mag_dev_weight``), heading resets are off, and
the 9-D pass starts from the 6-D estimate with a flat heading prior (``mag_heading_init``) so the
data, not the first sample, fix the heading. Rejection by norm and dip follows Roetenberg et al.
(IEEE TBME 52(3), 2005) and VQF (Laidig & Seel 2023). On the real RING rig (5 sensors,
uncalibrated magnetometers) this took the per-segment heading error from up to 36.5° to ≤ 6.3°
(VQF offline: 3.2–8.7°).

Recovery from a wrong state (a wrong start, or a gross error later): the measurement weights are
tuned for accuracy on BROAD and are weak, so on its own the filter would take tens of seconds to
undo a large error. An innovation monitor (:func:`._mekf_monitor.monitor`) low-passes the
earth-frame accelerometer (time constant ``reset_tau``) and the undisturbed field's horizontal
direction under the current estimate; a consistent filter keeps them near up and north. When one
stays further away than ``reset_tilt`` / ``reset_heading`` for ``reset_time`` /
``reset_heading_time`` (accelerometer updates are suspended meanwhile, being either outliers or
the evidence of a wrong state), the attitude is re-initialised from the vectors of that run — the
shortest rotation taking their mean acceleration to up, and the heading of their mean field if it
matches the reference norm and dip (TRIAD, gravity exact) — with the attitude covariance reset:
``att_init²`` is added to the prior as process noise and the correction enters as a measurement
of standard deviation ``reset_noise``. On BROAD no reset occurs; with the defaults a 90° error
falls below 1° about 1.2 s after the data start to contradict it.

The smoother is **multi-rate** (:mod:`._mekf_blocks`): the orientation is integrated at every
sample, but the covariance is propagated, the measurements applied and the RTS backward pass run
only every ``update_interval`` (40 ms: 4 samples at 100 Hz, 11 at BROAD's 286 Hz), with the block's
accumulated transition ``Φ = [[I, −dt Σ R_s, 0], [0, I, 0], [0, 0, I]]``; each block's measurements
enter as their means with the variance divided by their count (for a constant error state and the
same rows the same information as the per-sample updates). The backward pass runs on the error state
at those instants, both biases included (so a bias that later rests or movement determine reaches
the first rest) (Särkkä, *Bayesian Filtering and Smoothing*, 2013, eq. 8.6), and each sample between
two instants takes the forward estimate corrected by the smoothed correction interpolated between
them (the block's bias error turns the integrated orientation linearly in time). Against the same
smoother at every sample (``update_interval = 0``): within 0.003° on a simulated tumbling recording
(``tests/test_mekf_blocks.py``); BROAD's mean total 1.580° at every sample, 1.583° every 40 ms
(trials move by up to 0.03°, mostly through the gate's block-mean field). The inflated prior of a
reset decouples the two sides of it; after resets within ``early_reset_window`` of the start, the
samples before the last of them take its smoothed state carried back by the gyroscope, which makes
the smoother insensitive to a wrong start.

Where the time goes (BROAD, 8 trials, 425 595 samples, 9-D, µs of one thread's CPU per
sample, ``bench/smoother_passes.py``, 2 Dec 2026): rests (:func:`fusion_rest`) 0.23, steady
mask 0.05, the 6-D gate pass (forward and backward at the instants) 0.08, the field gate 0.02,
the accelerometer pre-filter 0.15, the 9-D pass (forward, backward, interpolation) 0.09, whole
``estimate`` 0.67; offlineVQF 0.86 in the same run (smoother 1.27 × its throughput). Per
sample the pass does the strapdown step (a series for the small rotation: no trigonometric
function), the rotation matrix, the accelerometer and field in the
earth frame and their sums, and in the backward pass a linear interpolation of two correction
quaternions; the 9 × 9 covariance arithmetic (about 500 floating-point operations and an
unrolled 9 × 9 Cholesky solve per update) runs once per block. Before the multi-rate smoother
(every sample, a 6-D and a 9-D smoother) the whole was 3.00 (0.44 × offlineVQF).
docs/performance.md has the rounds.

The default parameters were tuned on the 8 BROAD trials in ``../shared`` (Laidig et al. 2021),
which are also the trials the accuracy is reported on; they are not an independent test set.
Mean total RMSE there: smoother 1.52°, mekf 2.62° (offline VQF 2.38°, online VQF 2.54°).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from motionlab.dsp import butter, padlen, sosfiltfilt
from motionlab.errors import InputError
from motionlab.fusion import _mekf_blocks as blk
from motionlab.fusion import _mekf_kernels as kern
from motionlab.fusion import _mekf_monitor as mon_k
from motionlab.fusion.attitude import initial_orientation
from motionlab.fusion.detect import field_gate, steady_mask
from motionlab.fusion.registry import FusionResult, param, register
from motionlab.fusion.rest import fusion_rest
from motionlab.fusion.timegrid import GapNoise
from motionlab.rotations import (
    conj,
    from_axis_angle,
    integrate_gyro,
    make_continuous,
    mul,
    rotate,
)
from motionlab.timebase import interp_columns
from motionlab.units import STANDARD_GRAVITY


@dataclass
class MekfParams:
    """Tunables of the multiplicative EKF (and of the smoother built on it).

    Noise values are per-sample standard deviations unless a density is stated; the defaults
    were tuned on the 8 shared BROAD trials (see the module docstring).
    """

    gyr_noise: float = param(0.01, "rad/s/√Hz", "gyroscope noise density (angle random walk)")
    bias_rw: float = param(1e-4, "rad/s/√s", "gyroscope bias random walk")
    bias_init: float = param(0.02, "rad/s", "initial bias standard deviation")
    att_init: float = param(0.5, "rad", "initial attitude standard deviation")
    acc_noise: float = param(1.5, "1", "noise of the earth-frame acc/g in motion (per sample)")
    acc_rest_noise: float = param(0.1, "1", "noise of the earth-frame acc/g at rest")
    rest_noise: float = param(0.005, "rad/s", "gyroscope noise of the bias update at rest")
    mag_noise: float = param(10.0, "rad", "magnetometer heading noise in motion")
    mag_rest_noise: float = param(3.0, "rad", "magnetometer heading noise at rest")
    mag_norm_tol: float = param(0.1, "1", "disturbed when |m| differs from the reference by more")
    mag_dip_tol: float = param(
        np.deg2rad(10.0), "rad", "disturbed when the dip differs from the reference more"
    )
    mag_ref_tau: float = param(20.0, "s", "time constant of the reference field")
    mag_new_field_time: float = param(
        60.0, "s", "a steady new field becomes the reference after this"
    )
    mag_new_field_min: float = param(
        5.0, "s", "… or after as long as the reference was seen, ≥ this"
    )
    rest_gyr_threshold: float = param(
        np.deg2rad(2.0), "rad/s", "rest detection: moving-RMS rate threshold"
    )
    rest_acc_threshold: float = param(
        0.5, "m/s²", "rest detection: moving-RMS acc deviation threshold"
    )
    rest_min_duration: float = param(1.5, "s", "rest detection: minimum rest duration")
    reset_tilt: float = param(
        np.deg2rad(30.0), "rad", "reset when the low-passed acc is further from up"
    )
    reset_heading: float = param(
        np.deg2rad(45.0), "rad", "reset when the low-passed field is further from north"
    )
    reset_time: float = param(0.5, "s", "tilt inconsistency lasting this long resets")
    reset_heading_time: float = param(2.0, "s", "heading inconsistency lasting this long resets")
    reset_tau: float = param(1.0, "s", "low-pass time constant of the monitor")
    reset_noise: float = param(0.05, "rad", "noise of the reset's vector attitude")
    reset_agree: float = param(0.9, "1", "a heading reset needs the field directions to agree so")
    acc_bias_init: float = param(
        0.1, "m/s²", "prior standard deviation of the accelerometer bias (0: no bias states)"
    )
    acc_bias_rw: float = param(1e-3, "m/s²/√s", "accelerometer bias random walk")


@dataclass
class SmootherParams(MekfParams):
    """Tunables of the RTS smoother: those of the forward filter, and the carry-back rule."""

    mag_hysteresis: float = param(
        0.5, "1", "a gated stretch lasts while the field deviates by more than this × tolerance"
    )
    mag_hold: float = param(0.5, "s", "gated stretches are extended by this on both sides")
    mag_heading_tol: float = param(
        np.deg2rad(90.0),
        "rad",
        "gated when the field's heading under the 6-D pass is further from its median",
    )
    mag_heading_init: float = param(
        np.pi, "rad", "prior heading std of the 9-D pass (the field's data decide, not sample 1)"
    )
    mag_dev_weight: float = param(
        2.0, "1", "heading variance × (1 + this · (field deviation / tolerance)²)"
    )
    early_reset_window: float = param(
        10.0, "s", "before a reset this soon after the start, carry the smoothed state back"
    )
    rest_sway: float = param(
        np.deg2rad(0.2),
        "rad/s",
        "the bias update at rest only where the rate's 0.25 s mean "
        "varies less than this over 1 s (a person's sway is not a bias)",
    )
    update_interval: float = param(
        0.04, "s", "covariance, measurements and backward pass every this (0: every sample)"
    )
    acc_lowpass_tau: float = param(
        1.0, "s", "accelerometer low-passed in a gyroscope-carried frame (0: raw accelerometer)"
    )
    acc_lowpass_noise: float = param(
        0.5, "1", "noise of the low-passed earth-frame acc/g in motion (per sample)"
    )


def _pack(p: MekfParams) -> np.ndarray:
    """The forward kernel's parameter vector; the reference field is learnt online (the
    smoother's 9-D pass fixes it, :func:`_filter`)."""
    return kern.PRM.pack(
        p, gravity=STANDARD_GRAVITY, mag_fixed_norm=-1.0, mag_fixed_dip=0.0, mag_heading_reset=1.0
    )


def causal_rest(gyr: np.ndarray, acc: np.ndarray, rate: float, p: MekfParams) -> np.ndarray:
    """Rest flags (N,) bool from past samples only, for the online filter.

    The trailing-window form of :func:`motionlab.fusion.detect.rest_mask`: the mean square rate
    and the accelerometer's variance over the last 0.5 s are below the thresholds, and have been
    for ``rest_min_duration``; and the newest sample agrees with its window (so rest ends with
    the first moving sample). A rest phase is therefore flagged ``rest_min_duration`` after
    the window becomes still.
    """
    rest = np.empty(len(gyr), dtype=np.bool_)
    mon_k.trailing_rest(
        gyr, acc, max(1, int(round(0.5 * rate))), max(1, int(round(p.rest_min_duration * rate))),
        p.rest_gyr_threshold**2, p.rest_acc_threshold**2, rest,
    )  # fmt: skip
    return rest


def _filter(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None,
    rate: float,
    p: MekfParams,
    rest: np.ndarray,
) -> dict[str, np.ndarray]:
    """Run the online filter's kernel from the orientation of the first samples, the
    magnetometer's reference learnt online."""
    n = len(gyr)
    use_mag = mag is not None
    prm = _pack(p)
    if p.acc_bias_init == 0.0:
        prm[kern.ACC_BIAS_RW] = 0.0  # no accelerometer-bias states: the 6-state filter exactly
    out = {
        "quat": np.empty((n, 4)),
        "bias": np.empty((n, 3)),
        "acc_bias": np.empty((n, 3)),
        "dist": np.empty(n, dtype=np.bool_),
        "reset": np.empty(n, dtype=np.int8),
    }
    kern.forward(
        gyr, acc, mag if use_mag else np.zeros((1, 3)), use_mag, rest, np.ones(n, dtype=np.bool_),
        1.0 / rate, initial_orientation(acc, mag), _p0(p), prm, out["quat"], out["bias"],
        out["acc_bias"], out["dist"], out["reset"],
    )  # fmt: skip
    return out


def _result(out: dict, name: str, rest: np.ndarray, use_mag: bool, **extra) -> FusionResult:
    """The result of a pass ``out``; its quaternions' signs made continuous unless
    ``out["continuous"]`` says they are."""
    quat = out["quat"] if out.get("continuous") else make_continuous(out["quat"])
    return FusionResult(
        quat, name, {}, gyro_bias=out["bias"], rest=rest,
        mag_disturbed=out["dist"] if use_mag else None,
        extra={
            "resets": np.flatnonzero(out["reset"]).tolist(), "acc_bias": out["acc_bias"], **extra
        },
    )  # fmt: skip


@register("mekf", MekfParams, "multiplicative EKF with gyro-bias states (online, 6-D and 9-D)")
def run_mekf(
    gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None, rate: float, params: MekfParams
) -> FusionResult:
    """Forward error-state EKF (causal); see the module docstring for the model."""
    rest = causal_rest(gyr, acc, rate, params)
    out = _filter(gyr, acc, mag, rate, params, rest)
    return _result(out, "mekf", rest, mag is not None)


def _carry_back(
    quat: np.ndarray, bias: np.ndarray, acc_bias: np.ndarray, gyr: np.ndarray, k: int, rate: float
) -> None:
    """Overwrite samples ``0 … k−1`` with the state of sample ``k`` carried back by the gyroscope
    (both biases constant).

    ``q_j = q_k ⊗ D_kᵀ ⊗ D_j`` with ``D_j`` the strapdown rotation from sample 0 to ``j`` of
    the bias-corrected rate (bias of sample ``k``).
    """
    d = integrate_gyro(np.array([1.0, 0.0, 0.0, 0.0]), gyr[: k + 1] - bias[k], 1.0 / rate)
    quat[:k] = mul(mul(quat[k], conj(d[k])), d[:k])
    bias[:k] = bias[k]
    acc_bias[:k] = acc_bias[k]


def _blocks(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None,
    rate: float,
    p: SmootherParams,
    rest: np.ndarray,
    steady: np.ndarray,
    gaps: GapNoise | None,
    q0: np.ndarray,
    p0: np.ndarray,
    gate: tuple[np.ndarray, float, float] | None = None,
    field: bool = False,
    instants_only: bool = False,
) -> dict[str, np.ndarray]:
    """The multi-rate forward pass (:func:`._mekf_blocks.forward`) and its RTS backward pass
    at the update instants, every ``update_interval`` s.

    ``gate`` ``(scale (B,), ref_norm, ref_dip)``: the blocks' heading-variance factors
    (infinite: not used) and the fixed reference field; without it the magnetometer is not
    used. ``q0``, ``p0``: the initial orientation and error covariance (9 × 9). With ``field`` only
    the instants are smoothed and ``out["field"]`` (B×3) holds each block's mean field in the
    earth frame of the smoothed estimate (for the gate); with ``instants_only`` only the instants
    are smoothed (their biases ``bias_blk``, ``acc_bias_blk``); otherwise every sample is.
    """
    n = len(gyr)
    if not np.isfinite(p.update_interval) or p.update_interval < 0.0:
        raise InputError(
            f"smoother parameter update_interval={p.update_interval!r} s is not a duration ≥ 0",
            remedy="give 0 (every sample) or a few hundredths of a second (default 0.04)",
        )
    m = max(1, min(n, int(round(p.update_interval * rate))))
    at = blk.instants(n, m)
    nb = len(at)
    prm = _pack(p)
    if p.acc_bias_init == 0.0:
        prm[kern.ACC_BIAS_RW] = 0.0  # no accelerometer-bias states: the 6-state filter exactly
    if gate is not None:
        prm[kern.MAG_FIXED_NORM], prm[kern.MAG_FIXED_DIP] = gate[1], gate[2]
        prm[kern.MAG_HEADING_RESET] = 0.0
    extra = np.zeros(1)
    if gaps is not None:
        inside = (gaps.after > 0) & (gaps.after < n)
        if inside.any():
            per_sample = np.zeros(n)
            per_sample[gaps.after[inside].astype(int)] = gaps.sigma[inside] ** 2
            extra = np.add.reduceat(per_sample, np.concatenate([[0], at[:-1] + 1]))
    out = block_outputs(n, nb, field) | {"at": at, "prm": prm}
    use_mag = mag is not None and gate is not None
    blk.forward(
        gyr, acc, mag if (use_mag or field) else np.zeros((1, 3)), use_mag,
        gate[0] if use_mag else np.ones(1), rest, steady, extra, 1.0 / rate, m, q0, p0, prm,
        out["quat"], out["qprior"], out["gsum"], out["bias_blk"], out["acc_bias_blk"],
        out["reset_blk"], out["p_post"], out["field"],
    )  # fmt: skip
    out["end_cov"] = _unpacked(out["p_post"][-1])[6:, 6:]
    every_sample = not (field or instants_only)
    out["bias"] = np.empty((n if every_sample else 1, 3))
    out["acc_bias"] = np.empty((n if every_sample else 1, 3))
    blk.backward(
        1.0 / rate, m, out["quat"], out["qprior"], out["gsum"], out["bias_blk"],
        out["acc_bias_blk"], out["p_post"], out["reset_blk"], extra, prm, every_sample,
        out["bias"], out["acc_bias"], out["field"],
    )  # fmt: skip
    out["p_post"] = None  # no longer needed: free it
    out["reset"] = np.zeros(n, dtype=np.int8)
    out["reset"][at] = out["reset_blk"]
    return out


def block_outputs(n: int, nb: int, field: bool = False) -> dict[str, np.ndarray]:
    """The arrays :func:`._mekf_blocks.forward` writes for ``n`` samples and ``nb`` update
    instants: ``quat`` per sample; per instant the prior orientation ``qprior``, the block's
    summed rotation ``gsum``, the biases ``bias_blk`` and ``acc_bias_blk``, ``reset_blk`` and the
    posterior covariance's upper triangle ``p_post``; with ``field`` each block's mean earth-frame
    field (else one unused row)."""
    return {
        "quat": np.empty((n, 4)),
        "qprior": np.empty((nb, 4)),
        "gsum": np.empty((nb, 3, 3)),
        "bias_blk": np.empty((nb, 3)),
        "acc_bias_blk": np.empty((nb, 3)),
        "reset_blk": np.empty(nb, dtype=np.int8),
        "p_post": np.empty((nb, kern.N_PACKED)),
        "field": np.empty((nb if field else 1, 3)),
    }


def _p0(p: MekfParams) -> np.ndarray:
    return np.diag([p.att_init**2] * 3 + [p.bias_init**2] * 3 + [p.acc_bias_init**2] * 3)


@register("smoother", SmootherParams, "RTS smoother over the multiplicative EKF (offline, default)")
def run_smoother(
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None,
    rate: float,
    params: SmootherParams,
    gaps: GapNoise | None = None,
) -> FusionResult:
    """Multi-rate forward error-state EKF, then the Rauch–Tung–Striebel backward pass.

    The orientation is integrated at every sample; the covariance, the measurements and the
    backward pass run every ``update_interval`` s (:mod:`._mekf_blocks`), and the samples between
    two update instants take the smoothed correction interpolated between them.

    ``gaps``: the packet-loss gaps bridged in the inputs and how uncertain each bridge is
    (:func:`motionlab.fusion.timegrid.gap_noise`; given by :func:`motionlab.fusion.estimate`
    with ``time=``): the attitude variance of the prior after each gap grows by the gap's
    ``sigma²``, so that the accelerometer on either side decides where a bridge may have missed
    rotation.

    ``extra["acc_lowpassed"]``: whether the accelerometer was low-passed (:func:`lowpassed_acc`;
    not when ``acc_lowpass_tau`` is 0, nor when the first pass reset).

    ``extra["acc_bias_end_cov"]`` (3 × 3, m²/s⁴) is the accelerometer bias's covariance at the
    last sample, where the filter's posterior holds all the data (what
    :func:`motionlab.fusion.stage.calibration_acc_bias` joins its windows by).

    The backward pass does not cross a reset (its inflated prior decouples the two sides).
    Resets within ``early_reset_window`` of the start mean the initial state was wrong: the
    samples before the last of them take its smoothed state, carried back by the gyroscope.
    """
    p = params
    rest = fusion_rest(
        gyr, acc, rate, p.rest_gyr_threshold, p.rest_acc_threshold, p.rest_min_duration
    )
    steady = steady_mask(gyr, rate, rest, p.rest_sway)
    q0 = initial_orientation(acc, mag)
    p0 = _p0(p)
    gate = None
    dist = None
    if mag is not None:
        six = _blocks(gyr, acc, mag, rate, p, rest, steady, gaps, q0, p0, field=True)
        at = six["at"]
        blk_rate = rate * (len(at) - 1) / max(1, at[-1])
        gated, dev, ref_n, ref_d = field_gate(
            six["field"], blk_rate, p.mag_norm_tol, p.mag_dip_tol, p.mag_hysteresis,
            hold=p.mag_hold, heading_tol=p.mag_heading_tol,
        )  # fmt: skip
        dist = np.repeat(gated, np.diff(np.concatenate([[-1], at])))
        if np.isfinite(ref_n):
            gate = (np.where(gated, np.inf, 1.0 + p.mag_dev_weight * dev**2), ref_n, ref_d)
            q0 = _start(six["quat"][0], six["field"], ~gated)
            p0[0, 0] = p0[1, 1] = p.reset_noise**2
            p0[2, 2] = p.mag_heading_init**2
    lowpassed = False
    if p.acc_lowpass_tau > 0.0:
        if mag is None:
            six = _blocks(gyr, acc, None, rate, p, rest, steady, gaps, q0, p0, instants_only=True)
        # a first pass that had to reset met accelerometer data contradicting the gyroscope:
        # low-passed, they would be spread over seconds and trusted more, so they stay raw
        lowpassed = not six["reset_blk"].any()
        if lowpassed:
            acc = lowpassed_acc(gyr, acc, rate, six, rest, p.acc_lowpass_tau)
            p = replace(p, acc_noise=p.acc_lowpass_noise)
    out = _blocks(gyr, acc, mag, rate, p, rest, steady, gaps, q0, p0, gate=gate)
    early = np.flatnonzero(out["reset"][: int(p.early_reset_window * rate) + 1])
    carried = int(early[-1]) if len(early) else 0
    if carried:
        _carry_back(out["quat"], out["bias"], out["acc_bias"], gyr, carried, rate)
    out["dist"] = dist
    out["continuous"] = not carried  # the backward pass made them so
    return _result(
        out, "smoother", rest, mag is not None, carried_back=carried,
        acc_bias_end_cov=out["end_cov"], acc_lowpassed=lowpassed,
    )  # fmt: skip


def lowpassed_acc(
    gyr: np.ndarray,
    acc: np.ndarray,
    rate: float,
    first: dict[str, np.ndarray],
    rest: np.ndarray,
    tau: float,
) -> np.ndarray:
    """The accelerometer (N×3, m/s²) low-passed in a frame the gyroscope carries: VQF's
    accelerometer pre-filter (Laidig & Seel, Inf. Fusion 91, 2023, §IV-B), zero-phase.

    The rate less the gyroscope bias of a first smoother pass ``first`` (its instants' smoothed
    ``bias_blk``, ``acc_bias_blk``, interpolated) is integrated from the identity; the
    accelerometer less its bias is turned into that frame, low-passed there (second-order
    Butterworth, cut-off ``1 / (2π tau)`` Hz, forward and backward), turned back and its bias
    added. Linear acceleration, which changes sign within a movement, averages out while
    gravity, fixed in the earth frame, is kept however the sensor turns. Rest samples keep the
    raw accelerometer. The cut-off is at most 0.45 × ``rate`` (a ``tau`` under a sample); a
    recording too short to filter is returned as it is.
    """
    n = len(gyr)
    sos = butter(2, min(1.0 / (2.0 * np.pi * tau), 0.45 * rate), fs=rate)
    if n <= padlen(sos):
        return acc
    k = np.arange(n)
    at = first["at"]
    gyr_bias = interp_columns(k, at, first["bias_blk"])
    acc_bias = interp_columns(k, at, first["acc_bias_blk"])
    carried = integrate_gyro(np.array([1.0, 0.0, 0.0, 0.0]), gyr - gyr_bias, 1.0 / rate)
    low = sosfiltfilt(sos, rotate(carried, acc - acc_bias), axis=0)
    out = rotate(conj(carried), low) + acc_bias
    out[rest] = acc[rest]
    return out


def _start(q6: np.ndarray, field: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Start of the 9-D pass: the 6-D smoothed orientation of sample 0 ``q6`` turned about
    earth-up by the heading of the first usable block's field (B×3, earth frame under the 6-D
    estimate, which carries that heading back by the gyroscope, so a wrong or disturbed start
    does not matter)."""
    k = int(np.argmax(usable)) if usable.any() else 0
    em = field[k]
    psi = float(np.arctan2(em[0], em[1])) if np.isfinite(em).all() else 0.0
    return mul(from_axis_angle(np.array([0.0, 0.0, 1.0]), psi), q6)


def _unpacked(packed: np.ndarray) -> np.ndarray:
    """The symmetric N_ERR × N_ERR matrix of a stored upper triangle (row by row)."""
    m = np.zeros((kern.N_ERR, kern.N_ERR))
    m[np.triu_indices(kern.N_ERR)] = packed
    return m + np.triu(m, 1).T
