"""A knee's flexion axis from a stand and a walk: the principal axis of each segment's rotation.

Seel's hinge constraint (:mod:`.hinge`) holds for a mechanical hinge. A real knee is not one: it
abducts and rotates with flexion, and the thigh's soft tissue moves the sensor by several degrees.
On real walks (``bench/real_people.py``: Xsens DOT and Xsens MTw recordings of healthy adults) the
unconstrained fit leaves 43-70 % of the perpendicular rate unexplained and its axes settle 12-41°
from where the flexion axis can be, some 20-40° out of the horizontal plane of a standing leg.

Instead, as Vargas-Valencia et al. (Sensors 2016 16:2090) and, for a functional flexion axis,
Favre et al. (J Biomech 2009 42:2330) do, each segment's flexion axis is the axis its own angular
velocity turns about most over straight walking (first right singular vector of the rate),
restricted to the plane perpendicular to the segment's long axis, which the stand gives (gravity:
up along the leg). Thigh and shank swing in the sagittal plane; their rates about other axes
(pelvic rotation, ab/adduction, the soft tissue) are small beside it. Turns are left out: a turn
adds a rotation about the vertical that a swinging segment carries out of its long axis.

Three numbers judge the axis, each against what real walks give rather than a simulator:

- the part consistency: the axis of each of ``N_PARTS`` consecutive parts of the walk against the
  whole walk's (real walks: 0.6-4.9°); unmeasured (NaN, ``weak`` at best) when a part holds
  fewer than ``MIN_SAMPLES // 2`` samples of swing outside turns (a real DOT walk in circles,
  ``../shared/datasets/human/imt_dot/knee_tracking2`` from 20 s: 172 samples, its parts went
  unchecked and the knee read ``determined``);
- the dominance: second singular value over the first (real walks: 0.16-0.33; a segment with no
  preferred axis is near 1);
- the witness: Seel's constraint refitted with both axes held perpendicular to their long axes
  (two angles instead of four, started from the principal axes), whose axes lie within 1.5-4.4°
  of the principal ones on the real full-body walk and 9.7° on a real DOT walk
  (``witness_deg``; simulated walks: 8-11°), at a relative residual of 0.46-0.79 (simulated:
  0.2-0.4). A shank on the other leg is not told by the residual (both legs swing about
  parallel axes: 0.28-0.41 on the simulator) but by the signs (flexion no longer one way) or
  the witness (12°): ``weak``, never ``determined``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from motionlab import rotations as rot
from motionlab.dsp import butter, sosfiltfilt
from motionlab.segments import movement
from motionlab.segments.walk_forward import LOWPASS_HZ as TURN_LOWPASS_HZ
from motionlab.segments.walk_forward import TURN_RAD_S
from motionlab.session import estimate_rate
from motionlab.timebase import nominal_interval

N_PARTS = 4
MIN_SAMPLES = 100
ROBUST_SCALE_RAD_S = 0.1
LOWPASS_HZ = 3.0  # gait's segment rotations lie below it; soft-tissue wobble and impacts above
# the samples the axes come from: the joint turning at least this share of its 95th-percentile
# speed, i.e. the swings of the walk, not the slower movement around it (sitting down, standing
# up, shuffling; the 16-IMU recording cut to its first 10 s of walking: both knees `weak` at 0.1,
# the part fits 9-12° apart with the sit-to-stand in the first part; `determined` at 0.3)
SWING_FRACTION = 0.3
# verdicts: (determined up to, weak up to), each measured on real walks (module notes)
CONSISTENCY_DEG = (5.0, 15.0)
DOMINANCE = (0.5, 0.7)
WITNESS_DEG = (15.0, 25.0)  # the simulator's screw-home knee: 13°; flexion loses 1-cos 15° = 3 %
RESIDUAL = (0.9, 1.2)
# a knee extends little past its straight stand (real walks: 0.2-1°; hyperextension is rarely
# over 10°): more says thigh and shank do not share a knee (a sensor on the other leg)
EXTENSION_DEG = (10.0, 20.0)
# the thigh's angular speed over the shank's (95th percentiles over the swings, low-passed at
# LOWPASS_HZ): real walks 0.51-0.64 (the full-body walk's legs, the DOT thigh and shank: the shank
# adds the knee's rate to the thigh's); a stiff knee approaches 1, thigh and shank sensors
# swapped in the map give the inverse (1.56-1.96)
SWING_SPEED_RATIO = (1.0, 1.25)
REAL_WALK_SPEED_RATIO = (0.51, 0.64)
# the ratio is judged only when both segments turn at least this fast (95th percentile, rad/s;
# a walking thigh 3.7-4.2, a shank 7.2 on the real walk): a sensor that hardly turns is no
# swap but a sensor that was off, or a recording that is no walk
SWING_MIN_RAD_S = 1.0


class SwappedSensors(Exception):
    """A knee's thigh sensor turns faster over the walk than its shank sensor by more than
    ``SWING_SPEED_RATIO[1]`` (``ratio``): the two are the wrong way round (in the sensor map or
    on the leg), which no grade of this knee can say for the hip above it and the gait events
    below it."""

    def __init__(self, joint: str, ratio: float) -> None:
        super().__init__(f"{joint}: the thigh turns {ratio:.1f} times as fast as the shank")
        self.joint, self.ratio = joint, ratio


@dataclass
class PrincipalAxes:
    """The flexion axes of a joint's two segments from their own rotation (sensor frames).

    ``axis_proximal`` and ``axis_distal`` are unit (3,), perpendicular to ``long_proximal`` and
    ``long_distal`` (the segments' up directions in the reference pose), signs arbitrary;
    ``consistency_deg`` the largest angle between a part's axis and the whole's; ``dominance``
    the larger of the two segments' second-to-first singular value ratios; ``witness_proximal``
    / ``witness_distal`` the constrained hinge fit's axes (signs as the principal ones) and
    ``witness_deg`` the larger angle to them; ``relative_residual`` that fit's RMS residual over
    the RMS perpendicular rate; ``speed_ratio`` the proximal segment's 95th-percentile angular
    speed over the distal's (NaN where either is under ``SWING_MIN_RAD_S``); ``n_samples`` the
    samples used (moving, not turning).
    """

    axis_proximal: np.ndarray
    axis_distal: np.ndarray
    long_proximal: np.ndarray
    long_distal: np.ndarray
    consistency_deg: float
    dominance: float
    witness_proximal: np.ndarray
    witness_distal: np.ndarray
    witness_deg: float
    relative_residual: float
    residual_rad_s: float
    speed_ratio: float
    n_samples: int


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(float(a @ b)), 0.0, 1.0))))


def _plane(long_axis: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal basis of the plane perpendicular to ``long_axis``."""
    helper = np.eye(3)[int(np.argmin(np.abs(long_axis)))]
    e1 = np.cross(long_axis, helper)
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(long_axis, e1)])


def principal_axis(gyr: np.ndarray, long_axis: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit axis perpendicular to ``long_axis`` that the rates ``gyr`` (N, 3) turn about most,
    and the ratio of the second singular value to the first (0: one axis only, 1: none
    preferred)."""
    plane = _plane(long_axis)
    s, vt = np.linalg.svd(gyr @ plane.T, full_matrices=False)[1:]
    return vt[0] @ plane, float(s[1] / s[0]) if s[0] > 0 else 1.0


def turning(t: np.ndarray, q: np.ndarray, gyr: np.ndarray) -> np.ndarray:
    """Samples (bool) where the segment with orientation ``q`` (sensor → earth, Z up) and rates
    ``gyr`` rad/s turns about the vertical: low-passed at ``TURN_LOWPASS_HZ`` (below the stride
    frequency, so the pelvis's swing in each stride averages out), above ``TURN_RAD_S`` (both
    the turn definition of :mod:`.walk_forward`)."""
    yaw = rot.rotate(q, gyr)[:, 2]
    ok = np.isfinite(yaw)
    yaw = np.where(ok, yaw, 0.0)
    rate = estimate_rate(t)
    if len(t) > 30 and rate > 2.5 * TURN_LOWPASS_HZ:
        yaw = sosfiltfilt(butter(2, TURN_LOWPASS_HZ, fs=rate), yaw)
    return np.abs(yaw) >= TURN_RAD_S


def _perp(g: np.ndarray, j: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.cross(g, j), axis=1)


def constrained_hinge(
    g1: np.ndarray, g2: np.ndarray, a1: np.ndarray, a2: np.ndarray, long1: np.ndarray,
    long2: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float, float]:  # fmt: skip
    """Seel's constraint ``‖g1 × j1‖ = ‖g2 × j2‖`` with each axis held in the plane perpendicular
    to its segment's long axis, started from ``a1``, ``a2`` (soft-L1 loss): ``(j1, j2, RMS
    residual rad/s, relative residual)``; signs follow ``a1``, ``a2``."""
    p1, p2 = _plane(long1), _plane(long2)

    def axes(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.cos(x[0]) * p1[0] + np.sin(x[0]) * p1[1],
                np.cos(x[1]) * p2[0] + np.sin(x[1]) * p2[1])  # fmt: skip

    def residual(x: np.ndarray) -> np.ndarray:
        j1, j2 = axes(x)
        return _perp(g1, j1) - _perp(g2, j2)

    x0 = np.array([np.arctan2(a1 @ p1[1], a1 @ p1[0]), np.arctan2(a2 @ p2[1], a2 @ p2[0])])
    fit = least_squares(residual, x0, loss="soft_l1", f_scale=ROBUST_SCALE_RAD_S, max_nfev=200)
    j1, j2 = axes(fit.x)
    j1, j2 = j1 * (np.sign(j1 @ a1) or 1.0), j2 * (np.sign(j2 @ a2) or 1.0)
    res = residual(fit.x)
    scale = float(np.sqrt(np.mean(0.5 * (_perp(g1, j1) ** 2 + _perp(g2, j2) ** 2))))
    rms = float(np.sqrt(np.mean(res**2)))
    return j1, j2, rms, (rms / scale if scale > 0 else float("inf"))


def principal_axes(
    t: np.ndarray,
    g1: np.ndarray,
    g2: np.ndarray,
    q1: np.ndarray,
    q2: np.ndarray,
    reference: np.ndarray,
    moving: np.ndarray,
) -> PrincipalAxes | None:
    """Both segments' flexion axes from their rotation over the straight walk (see the module
    notes); ``None`` when fewer than ``MIN_SAMPLES`` samples move without turning.

    ``g1``, ``g2`` (N, 3) rad/s are the rates on the time ``t`` (s; low-passed here at
    ``LOWPASS_HZ``), ``q1``, ``q2``
    the 6-D orientations (only their vertical is used), ``reference`` the samples of the
    reference pose (the stand: each segment's long axis vertical), ``moving`` the samples that
    move.
    """
    longs = [rot.rotate(rot.conj(rot.mean(q[reference])), np.array([0.0, 0.0, 1.0]))
             for q in (q1, q2)]  # fmt: skip
    turns = turning(t, q1, g1)
    rate = estimate_rate(t)
    if len(t) > 30 and rate > 2.5 * LOWPASS_HZ:
        sos = butter(2, LOWPASS_HZ, fs=rate)
        g1, g2 = sosfiltfilt(sos, g1, axis=0), sosfiltfilt(sos, g2, axis=0)
    use = moving & ~turns & np.isfinite(g1).all(axis=1) & np.isfinite(g2).all(axis=1)
    if use.sum() < MIN_SAMPLES:
        return None
    (a1, d1), (a2, d2) = (
        principal_axis(g[use], long) for g, long in zip((g1, g2), longs, strict=True)
    )
    parts = np.array_split(np.flatnonzero(use), N_PARTS)
    worst = float("nan")  # unmeasured: too little straight walking to compare its parts
    if min(len(part) for part in parts) >= MIN_SAMPLES // 2:
        worst = max(max(_angle_deg(principal_axis(g1[part], longs[0])[0], a1),
                        _angle_deg(principal_axis(g2[part], longs[1])[0], a2))
                    for part in parts)  # fmt: skip
    w1, w2, rms, relative = constrained_hinge(g1[use], g2[use], a1, a2, *longs)
    # over every swing, turns too: the turns are found on the proximal segment's rates, which
    # would make the ratio depend on which of the two is taken for the thigh
    swings = moving & np.isfinite(g1).all(axis=1) & np.isfinite(g2).all(axis=1)
    speed_1, speed_2 = (np.percentile(np.linalg.norm(g[swings], axis=1), 95) for g in (g1, g2))
    judged = min(speed_1, speed_2) >= SWING_MIN_RAD_S  # a segment that hardly turns says nothing
    return PrincipalAxes(
        axis_proximal=a1,
        axis_distal=a2,
        long_proximal=longs[0],
        long_distal=longs[1],
        consistency_deg=worst,
        dominance=max(d1, d2),
        witness_proximal=w1,
        witness_distal=w2,
        witness_deg=max(_angle_deg(a1, w1), _angle_deg(a2, w2)),
        relative_residual=relative,
        residual_rad_s=rms,
        speed_ratio=float(speed_1 / speed_2) if judged else float("nan"),
        n_samples=int(use.sum()),
    )


def recorded_on(t: np.ndarray, t_s: np.ndarray, gyr: np.ndarray) -> np.ndarray:
    """Samples of ``t`` (s) within one sample interval of a finite rate of a sensor recorded at
    ``t_s`` (``gyr`` rad/s): not in a gap the ingest kept, as missing samples or as NaN."""
    good = t_s[np.isfinite(gyr).all(axis=1)]
    if len(good) < 2:
        return np.zeros(len(t), bool)
    i = np.clip(np.searchsorted(good, t), 1, len(good) - 1)
    near = np.minimum(np.abs(t - good[i - 1]), np.abs(good[i] - t))
    return near <= 1.01 * nominal_interval(t_s)


def fit_knee(
    joint: str,
    proximal: tuple[np.ndarray, np.ndarray, np.ndarray],
    distal: tuple[np.ndarray, np.ndarray, np.ndarray],
    prior_p: np.ndarray,
    prior_d: np.ndarray,
    reference: tuple[float, float],
    walking: bool = True,
) -> movement.HingeFit:
    """A knee's flexion axis from a stand (``reference``, s) and a walk (see the module notes),
    as a :class:`~.movement.HingeFit` (``method`` ``principal``).

    ``proximal`` and ``distal`` are ``(time s, gyr rad/s (N, 3), q_sensor (N, 4))``; ``prior_*``
    the axis under the nominal placement (only used where the data cannot sign the axes). The
    axes are signed by :func:`.movement.signed_axes` (flexion from anatomy: the knee is straight
    in the stand and flexes one way). Where the movement is ``walking``, a thigh that turns
    about as fast as its shank makes the fit ``weak``, one that turns clearly faster raises
    :class:`SwappedSensors` (other movements, a leg raised with the knee bending as the hip
    flexes, turn the thigh faster).
    """
    t, g1, g2, q1, q2, speed = movement.shared_movement(joint, proximal, distal)
    ref = (t >= reference[0]) & (t <= reference[1])
    # the swings both sensors recorded: a gap is bridged for the filters, not for the axes
    # (a shank flat across a long gap looked still beside its walking thigh: "swapped")
    recorded = recorded_on(t, *proximal[:2]) & recorded_on(t, *distal[:2])
    if recorded.sum() < MIN_SAMPLES:
        return movement.failed(joint, "thigh and shank sensors recorded too little at one time")
    on = (speed >= SWING_FRACTION * np.percentile(speed[recorded], 95)) & recorded
    if ref.sum() < 5:
        return movement.failed(joint, "no stand with the knee straight before or after the walk")
    axes = principal_axes(t, g1, g2, q1, q2, ref, on)
    if axes is None:
        return movement.failed(
            joint, "the walk holds too little straight walking (turns are left out)"
        )
    if not walking:
        axes = replace(axes, speed_ratio=float("nan"))
    elif axes.speed_ratio > SWING_SPEED_RATIO[1]:
        raise SwappedSensors(joint, axes.speed_ratio)
    reasons: list[str] = []
    j_p, j_d, rel_source, sign_source, excursion = movement.signed_axes(
        t, q1, q2, axes.axis_proximal, axes.axis_distal, prior_p, prior_d, on, reference, True,
        reasons,
    )  # fmt: skip
    verdict = _verdict(axes, excursion[1], reasons, hinted="nominal" in (rel_source, sign_source))
    return movement.HingeFit(
        joint=joint,
        axis_proximal=j_p,
        axis_distal=j_d,
        residual_rad_s=axes.residual_rad_s,
        relative_residual=axes.relative_residual,
        consistency_deg=axes.consistency_deg,
        relative_sign=rel_source,
        sign=sign_source,
        excursion_deg=excursion,
        window_s=(float(t[0]), float(t[-1])),
        n_samples=axes.n_samples,
        verdict=verdict,
        reasons=reasons,
        method="principal",
        witness_deg=axes.witness_deg,
        dominance=axes.dominance,
        proximal_tilt_deg=tilt_deg(q1, axes.long_proximal),
        speed_ratio=axes.speed_ratio,
    )


def tilt_deg(q: np.ndarray, long_axis: np.ndarray) -> float:
    """How far (deg, 99th percentile over the samples) a segment's long axis (sensor
    coordinates, vertical in the stand) tilts from the vertical, with 6-D orientations ``q``
    (N, 4) sensor → earth."""
    up = rot.rotate(q, long_axis)
    return float(np.percentile(np.degrees(np.arccos(np.clip(up[:, 2], -1.0, 1.0))), 99))


def _verdict(axes: PrincipalAxes, extension_deg: float, reasons: list[str], hinted: bool) -> str:
    """``determined``, ``weak`` or ``not determined`` from the axes' numbers and the knee's
    extension past the stand (deg; limits at the top of the module); what falls short is said
    in ``reasons``."""
    checks = (
        (axes.consistency_deg, CONSISTENCY_DEG,
         f"the axis differs by up to {axes.consistency_deg:.0f}° between parts of the walk"),
        (axes.dominance, DOMINANCE,
         f"the segments turn about no single axis (second axis {100 * axes.dominance:.0f}% "
         "of the first)"),
        (axes.witness_deg, WITNESS_DEG,
         f"the hinge fit puts the axis {axes.witness_deg:.0f}° away"),
        (axes.relative_residual, RESIDUAL,
         f"thigh and shank do not move as one knee (hinge residual "
         f"{100 * axes.relative_residual:.0f}% of the rate)"),
        (extension_deg if np.isfinite(extension_deg) else 0.0, EXTENSION_DEG,
         f"the knee would extend {extension_deg:.0f}° past its straight stand: are thigh and "
         "shank sensors on the same leg?"),
        (axes.speed_ratio if np.isfinite(axes.speed_ratio) else 0.0, SWING_SPEED_RATIO,
         f"the thigh sensor turns {axes.speed_ratio:.1f} times as fast as the shank sensor in "
         "the walk (a shank turns faster): are the thigh and shank sensors swapped in the map?"),
    )  # fmt: skip
    worst = 0
    if not np.isfinite(axes.consistency_deg):  # an axis no part of the walk could check
        reasons.append(
            f"the walk holds too little straight walking to check the axis between its parts "
            f"({axes.n_samples} samples of swing outside turns; {N_PARTS * (MIN_SAMPLES // 2)} "
            "needed)"
        )
        worst = 1
    for value, (good, bad), why in checks:
        if value > good:
            reasons.append(why)
            worst = max(worst, 2 if value > bad else 1)
    if worst == 0 and hinted:
        worst = 1
    return ("determined", "weak", "not determined")[worst]
