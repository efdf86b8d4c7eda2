"""Hinge axes from ordinary movement: gait, free arm movement, a rig's motion.

A recording made as people make them holds a stand and a task, not the protocol's functional
movements. The flexion axis of an elbow or a generic hinge (and of a knee without a stand before
its walk; a knee with one: :mod:`.gait_axes`) is then taken from whatever the two segments did,
with Seel's constraint (Seel, Raisch & Schauer, Sensors 2014 14:6891;
:func:`~motionlab.segments.hinge.hinge_axes`) fitted with a robust loss (soft-L1, so that the
knee's small ab/adduction and rotation, soft-tissue wobble and impacts weigh less than the
flexion) on gyroscopes low-passed at ``LOWPASS_HZ``.

The constraint leaves the sign of each axis free. They are fixed in two steps:

1. **Relative sign** (both axes the same physical direction), whichever of two tests is surer:
   the axis' vertical components seen from both sensors rise and fall together whatever the
   (6-D, unknown) headings (:func:`relative_sign`); and with the wrong sign the hinge-tied
   headings are half a turn off, so the relative rotation swings off the axis as the proximal
   segment tilts (:func:`swing_sign`). When neither tells (an axis that stays horizontal, as in
   a seated knee flexion), the nominal placement decides.
2. **Absolute sign** (which way is flexion): for joints that flex one way (knee, elbow), the
   angle about the axis since the reference pose (standing: knee straight, arm hanging), from
   the hinge-tied relative orientation, reaches far one way and hardly the other; that way is
   flexion (:func:`anatomical_sign`). Otherwise the nominal placement (the protocol's
   ``sensor_axes`` hint) decides.

The elbow turns about two axes, flexion fixed in the upper arm and pronation in the forearm:
:func:`fit_two_dof` fits both with the heading offsets between the two sensors.

A verdict comes from the fit's own numbers: the RMS residual relative to the RMS of the
perpendicular angular rate, and the consistency of the axes fitted on ``N_PARTS`` consecutive
parts of the movement (largest angle to the whole fit).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from motionlab import rotations as rot
from motionlab.dsp import butter, correlate, sosfiltfilt
from motionlab.errors import InputError
from motionlab.results import HingeFit, TwoAxisFit
from motionlab.segments import heading
from motionlab.segments.hinge import hinge_axes
from motionlab.session import estimate_rate
from motionlab.timebase import interp_columns

LOWPASS_HZ = 6.0
ROBUST_SCALE_RAD_S = 0.1
N_PARTS = 4
MIN_PART_SAMPLES = 100
MIN_ACTIVE_RAD_S = 0.3  # a joint must turn at least this fast (95th percentile) to fit an axis
DETERMINED_DEG = 5.0  # consistency of the part fits
WEAK_DEG = 15.0
DETERMINED_RESIDUAL = 0.35  # RMS residual / RMS perpendicular rate
WEAK_RESIDUAL = 0.6
SIGN_MARGIN = 0.3  # relative-sign test: (bad - good) / (bad + good)
FLEXION_MIN_DEG = 15.0  # anatomical sign: the larger excursion at least this
FLEXION_RATIO = 2.0  # ... and this many times the other
SIGN_EXCURSION_DEG = 5.0  # the other relative sign turns the joint this much further back
NOMINAL_DISTAL = "the movement did not tell which way the axis points on the distal segment"


def _lowpass(x: np.ndarray, rate: float) -> np.ndarray:
    if len(x) < 30 or not rate > 2.5 * LOWPASS_HZ:
        return x
    return sosfiltfilt(butter(2, LOWPASS_HZ, fs=rate), x, axis=0)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(float(a @ b)), 0.0, 1.0))))


def relative_sign(
    q_p: np.ndarray, q_d: np.ndarray, j_p: np.ndarray, j_d: np.ndarray
) -> tuple[float, float]:
    """Sign (±1) to give ``j_d`` so that it is the same physical axis as ``j_p``, and the margin.

    ``q_p``, ``q_d`` (N, 4) are the sensors' orientations on one clock (only their tilt matters).
    The axis' vertical components seen from both sides rise and fall together; the sign is that
    of their correlation and the margin its size (0 to 1). Centred, so that the small constant
    tilt an axis fitted from an imperfect hinge carries (a knee's rotation and ab/adduction
    coupled to flexion) does not count.
    """
    up_p = rot.rotate(q_p, np.broadcast_to(j_p, (len(q_p), 3)))[:, 2]
    up_d = rot.rotate(q_d, np.broadcast_to(j_d, (len(q_d), 3)))[:, 2]
    ok = np.isfinite(up_p) & np.isfinite(up_d)
    a, b = up_p[ok] - up_p[ok].mean(), up_d[ok] - up_d[ok].mean()
    den = float(np.sqrt(np.sum(a**2) * np.sum(b**2)))
    corr = float(np.sum(a * b) / den) if den > 0 else 0.0
    return (1.0 if corr >= 0 else -1.0), abs(corr)


def swing_sign(
    t: np.ndarray, q_p: np.ndarray, q_d: np.ndarray, j_p: np.ndarray, j_d: np.ndarray
) -> tuple[float, float]:
    """Sign (±1) to give ``j_d`` so that it is the same physical axis as ``j_p``, and the margin,
    from the whole orientations: with the right sign, the distal heading tied to the proximal one
    by the hinge (:func:`.heading.hinge_anchors`) leaves a relative rotation that turns about the
    axis only; with the wrong one the ties are half a turn off and, as the proximal segment
    tilts, the relative rotation swings off the axis. The margin is ``(bad - good) / (bad +
    good)`` of the RMS swing angle (rad).
    """
    swings = []
    for sign in (1.0, -1.0):
        times, deltas = heading.hinge_anchors(t, q_p, q_d, j_p, sign * j_d)
        if not len(times):
            return 1.0, 0.0
        q = heading.apply_heading(q_d, heading.heading_track(times, deltas, t))
        rel = rot.mul(rot.conj(q_p), q)
        r = rot.mul(rel, rot.conj(rel[len(rel) // 2]))
        v = r[:, 1:] - np.outer(r[:, 1:] @ j_p, j_p)  # the part off the axis
        swing = 2.0 * np.arcsin(np.clip(np.linalg.norm(v, axis=1), 0.0, 1.0))
        swings.append(float(np.sqrt(np.nanmean(swing**2))))
    good, bad = min(swings), max(swings)
    margin = (bad - good) / (bad + good) if bad + good > 0 else 0.0
    return (1.0 if swings[0] <= swings[1] else -1.0), margin


def anatomical_sign(
    t: np.ndarray,
    q_p: np.ndarray,
    q_d: np.ndarray,
    j_p: np.ndarray,
    j_d: np.ndarray,
    reference: tuple[float, float],
    align: bool = True,
) -> tuple[float | None, tuple[float, float]]:
    """Sign (±1) making the joint angle about ``j`` flex the way anatomy allows, or ``None``.

    ``q_p``, ``q_d`` (N, 4) are the sensors' 6-D orientations on the time ``t`` (s). The distal
    heading is tied to the proximal one by the hinge (:func:`.heading.hinge_anchors`), and the
    angle about ``j_p`` of the relative rotation from the ``reference`` window (a still pose
    with the joint straight) is taken at every other sample, before and after it: unlike an
    integrated gyroscope it does not drift with turns. The excursions (98th percentile each
    way, degrees: flexion then extension) are returned with the sign. ``None`` (and the
    excursions along ``+j``, then ``-j``) when neither dominates (see ``FLEXION_MIN_DEG``,
    ``FLEXION_RATIO``).
    """
    sel = (t >= reference[0]) & (t <= reference[1])
    if sel.sum() < 5:
        return None, (float("nan"), float("nan"))
    times, deltas = heading.hinge_anchors(t, q_p, q_d, j_p, j_d) if align else ([], [])
    if len(times):
        q_d = heading.apply_heading(q_d, heading.heading_track(times, deltas, t))
    q_rel = rot.mul(rot.conj(q_p), q_d)
    r = rot.mul(q_rel, rot.conj(rot.mean(q_rel[sel])))
    theta = np.degrees(2.0 * np.arctan2(r[:, 1:] @ j_p, np.abs(r[:, 0])) * np.sign(r[:, 0] + 1e-12))
    moved = ~sel & np.isfinite(theta)  # before the pose too: a walk may end with its stand
    if not moved.any():
        return None, (float("nan"), float("nan"))
    up = float(np.percentile(theta[moved], 98))
    down = float(-np.percentile(theta[moved], 2))
    big, small = max(up, down), max(min(up, down), 0.0)
    if big < FLEXION_MIN_DEG or big < FLEXION_RATIO * small:
        return None, (up, down)
    return (1.0 if up >= down else -1.0), (big, small)


def signed_axes(
    t: np.ndarray,
    q1: np.ndarray,
    q2: np.ndarray,
    j_p: np.ndarray,
    j_d: np.ndarray,
    prior_p: np.ndarray,
    prior_d: np.ndarray,
    on: np.ndarray,
    reference: tuple[float, float] | None,
    anatomical: bool,
    reasons: list[str],
) -> tuple[np.ndarray, np.ndarray, str, str, tuple[float, float]]:
    """Hinge axes ``j_p``, ``j_d`` (sensor frames, either sign) signed as the module notes say:
    ``(j_p, j_d, relative-sign source, sign source, excursions deg)``. The relative sign from
    :func:`relative_sign` or :func:`swing_sign` (samples ``on``), else the priors (the nominal
    placement); the absolute sign from :func:`anatomical_sign` for a joint that flexes one way
    (``anatomical``) with a ``reference`` window (s) in its zero pose, else the priors. There,
    of the two relative signs the one under which the joint flexes more nearly one way from its
    straight pose is taken (relative-sign source ``anatomy`` where that overrules the rates):
    axes of opposite relative sign turn the joint both ways (a 14-s simulated walk whose rates
    gave the wrong sign: 47° and 48°, against 58° and 0°). Where the rates did not tell and the
    priors' sign is the one that flexes one way (the other turning the joint at least
    ``SIGN_EXCURSION_DEG`` further back), the source is ``anatomy`` too, not a hint.
    What came from the priors is said in ``reasons``."""
    s_rel, margin = relative_sign(q1[on], q2[on], j_p, j_d)
    s_swing, margin_swing = swing_sign(t, q1, q2, j_p, j_d)
    if margin_swing > margin:
        s_rel, margin = s_swing, margin_swing
    if margin >= SIGN_MARGIN:
        j_d = s_rel * j_d
        rel_source = "measured"
    else:
        j_d = j_d if (j_p @ prior_p) * (j_d @ prior_d) >= 0 else -j_d
        rel_source = "nominal"
        reasons.append(NOMINAL_DISTAL + ", so it is taken from the nominal placement")
    sign, excursion = None, (float("nan"), float("nan"))
    if anatomical and reference is not None:
        sign, excursion = anatomical_sign(t, q1, q2, j_p, j_d, reference)
        # a wrong relative sign turns the joint both ways from its straight pose
        flipped, other = anatomical_sign(t, q1, q2, j_p, -j_d, reference)
        if flipped is not None and (sign is None or other[1] < excursion[1]):
            sign, excursion, j_d, rel_source = flipped, other, -j_d, "anatomy"
        elif rel_source == "nominal" and sign is not None:
            # the anatomy tells the relative sign as surely when it confirms the placement's
            # guess as when it overrules it (a 14-s real walk: 78° one way and 1° the other,
            # against 70° and 59° with the other sign)
            if flipped is None or other[1] >= excursion[1] + SIGN_EXCURSION_DEG:
                rel_source = "anatomy"
        if rel_source == "anatomy":
            reasons[:] = [r for r in reasons if not r.startswith(NOMINAL_DISTAL)]
    if sign is not None:
        return sign * j_p, sign * j_d, rel_source, "anatomy", excursion
    s = 1.0 if j_p @ prior_p + j_d @ prior_d >= 0 else -1.0
    if anatomical:
        reasons.append(
            "the direction of flexion could not be told from the movement (no stand with "
            "the joint straight, or no clear flexion), so it follows the nominal placement"
        )
    return s * j_p, s * j_d, rel_source, "nominal", excursion


def _verdict(
    worst_deg: float, relative: float, hinted: bool, reasons: list[str], axes: str, model: str
) -> str:
    """``determined``, ``weak`` or ``not determined`` from the part fits' largest disagreement
    (deg), the relative residual and whether a direction came from the hint; the reasons are
    appended to ``reasons`` in plain words (``axes``: "the axis differs", ``model``: what the
    movement should turn about)."""
    if not np.isfinite(worst_deg):  # the movement too short or too sparse to compare parts
        reasons.append("too little movement in the parts of the recording to compare their axes")
    elif worst_deg > DETERMINED_DEG:
        reasons.append(f"{axes} by up to {worst_deg:.0f}° between parts of the movement")
    if relative > DETERMINED_RESIDUAL:
        reasons.append(
            f"the movement is not about {model} (residual {100 * relative:.0f}% of the rate)"
        )
    if worst_deg > WEAK_DEG or relative > WEAK_RESIDUAL:
        return "not determined"
    if not np.isfinite(worst_deg) or worst_deg > DETERMINED_DEG:
        return "weak"
    if relative > DETERMINED_RESIDUAL or hinted:
        return "weak"
    return "determined"


def _consistency(
    n: int,
    refit: Callable[[int, int], tuple[np.ndarray, np.ndarray] | None],
    axis_1: np.ndarray,
    axis_2: np.ndarray,
) -> float:
    """The largest angle (deg) between the two axes and their refits (``refit(a, b)``: the
    axes from samples ``a:b``, ``None`` for too little there) on ``N_PARTS`` consecutive
    parts of the ``n`` samples: how consistent the movement is about them. NaN when fewer
    than two parts could be refitted: nothing was compared."""
    angles = []
    bounds = np.linspace(0, n, N_PARTS + 1).astype(int)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        axes = refit(a, b)
        if axes is not None:
            angles.append(max(_angle_deg(axes[0], axis_1), _angle_deg(axes[1], axis_2)))
    return max(angles) if len(angles) >= 2 else float("nan")


def shared_movement(
    joint: str,
    proximal: tuple[np.ndarray, np.ndarray, np.ndarray],
    distal: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, ...]:
    """``(t s, g1, g2 rad/s, q1, q2, speed rad/s)``: both segments on the proximal sensor's
    samples that the distal one covers; gyroscopes low-passed in their sensor frames
    (interpolated across NaN spans first: a filter would spread them), orientations, and the
    faster segment's angular speed per sample. Refuses too few samples, or segments that hardly
    turn (95th percentile of the speed under ``MIN_ACTIVE_RAD_S``)."""
    tp, gp, qp = proximal
    td, gd, qd = distal
    sel = (tp >= td[0]) & (tp <= td[-1])
    t = tp[sel]
    if len(t) < 3 * MIN_PART_SAMPLES:
        raise InputError(
            f"joint {joint}: too little shared movement for its axes ({len(t)} samples)",
            remedy="record a longer movement of the joint",
        )
    rate = estimate_rate(t)
    g1 = _lowpass(interp_columns(t, tp, gp), rate)
    g2 = _lowpass(interp_columns(t, td, gd), rate)
    speed = np.maximum(np.linalg.norm(g1, axis=1), np.linalg.norm(g2, axis=1))
    if not np.percentile(speed, 95) >= MIN_ACTIVE_RAD_S:
        raise InputError(
            f"joint {joint}: its segments hardly turn (95th percentile "
            f"{np.percentile(speed, 95):.2f} rad/s)",
            remedy="record a movement of the joint",
        )
    return t, g1, g2, qp[sel], rot.resample(td, qd, t), speed


def fit_hinge(
    joint: str,
    proximal: tuple[np.ndarray, np.ndarray, np.ndarray],
    distal: tuple[np.ndarray, np.ndarray, np.ndarray],
    prior_p: np.ndarray,
    prior_d: np.ndarray,
    reference: tuple[float, float] | None = None,
    anatomical: bool = False,
) -> HingeFit:
    """Hinge axis of ``joint`` from the movement of its two segments (see the module notes).

    ``proximal`` and ``distal`` are ``(time s, gyr rad/s (N, 3), q_sensor (N, 4))``; ``prior_*``
    are the axis (positive direction) in sensor coordinates under the nominal placement;
    ``reference`` is a still window (s) in the joint's zero pose (for the anatomical sign). A
    knee with a stand and a walk takes its axes from :func:`.gait_axes.fit_knee` instead.
    """
    t, g1, g2, q1, q2, active = shared_movement(joint, proximal, distal)
    j_p, j_d, _ = hinge_axes(g1, g2, prior_p, prior_d, loss="soft_l1", f_scale=ROBUST_SCALE_RAD_S)
    reasons: list[str] = []

    def refit(a: int, b: int) -> tuple[np.ndarray, np.ndarray] | None:
        if (active[a:b] >= 0.1 * np.percentile(active, 95)).sum() < MIN_PART_SAMPLES:
            return None
        try:
            pp, pd_, _ = hinge_axes(
                g1[a:b], g2[a:b], j_p, j_d, n_starts=0, loss="soft_l1", f_scale=ROBUST_SCALE_RAD_S
            )
        except InputError:
            return None
        return pp, pd_

    worst = _consistency(len(t), refit, j_p, j_d)
    # residual of the whole fit, relative to the perpendicular rate
    perp1 = np.linalg.norm(np.cross(g1, j_p), axis=1)
    perp2 = np.linalg.norm(np.cross(g2, j_d), axis=1)
    on = active >= 0.1 * np.percentile(active, 95)
    residual = float(np.sqrt(np.mean((perp1[on] - perp2[on]) ** 2)))
    scale = float(np.sqrt(np.mean(0.5 * (perp1[on] ** 2 + perp2[on] ** 2))))
    relative = residual / scale if scale > 0 else float("inf")
    j_p, j_d, rel_source, sign_source, excursion = signed_axes(
        t, q1, q2, j_p, j_d, prior_p, prior_d, on, reference, anatomical, reasons
    )
    hinted = rel_source == "nominal" or (anatomical and sign_source == "nominal")
    verdict = _verdict(worst, relative, hinted, reasons, "the axis differs", "one axis")
    return HingeFit(
        joint=joint,
        axis_proximal=j_p,
        axis_distal=j_d,
        residual_rad_s=residual,
        relative_residual=relative,
        consistency_deg=worst,
        relative_sign=rel_source,
        sign=sign_source,
        excursion_deg=excursion,
        window_s=(float(t[0]), float(t[-1])),
        n_samples=int(on.sum()),
        verdict=verdict,
        reasons=reasons,
    )


def failed(joint: str, why: str) -> HingeFit:
    """The record of a hinge fit that could not be made (``not determined``, with the reason)."""
    nan3 = np.full(3, np.nan)
    return HingeFit(
        joint=joint,
        axis_proximal=nan3,
        axis_distal=nan3,
        residual_rad_s=float("nan"),
        relative_residual=float("nan"),
        consistency_deg=float("nan"),
        relative_sign="none",
        sign="none",
        verdict="not determined",
        reasons=[why],
    )


TWO_AXIS_WINDOW_S = 10.0
TWO_AXIS_MAX_SAMPLES = 3000
TWO_AXIS_STARTS = 6
#: How fast the heading offset between two 6-D estimates wanders (deg/√s, a random walk): on
#: the simulated arm (``bench/elbow_sources.py``) the true offset moved by about 2° from one
#: 10-s window to the next.
TWO_AXIS_DRIFT_DEG_S = 0.6
#: The skin on the upper arm follows only part of the humerus' axial rotation (0.64-0.74 of it
#: for a mid-arm cluster, less proximally: docs/simulator.md, "The upper arm under the skin"),
#: so the humerus turns about its long axis ``1 + k`` times as fast as a sensor strapped on it
#: (``k = 1/follow - 1``: 0.35-0.56 there). ``k`` is fitted with the axes, from this start and
#: within ``[0, AXIAL_LAG_MAX]`` (a sensor that follows at least 40 %).
AXIAL_LAG_START = 0.3
AXIAL_LAG_MAX = 1.5
#: The elbow's flexion axis lies across the humerus: the trochlea's axis is 4-8° off the
#: perpendicular to the shaft (the humeral part of the carrying angle). A fitted flexion axis
#: further than this from the perpendicular to the stand's long axis is not an elbow's (the real
#: 16-IMU recording of ``bench/real_people.py``: 4-7° from the long axis, i.e. 83-86° off).
ACROSS_LONG_AXIS_DEG = 30.0


def autocorrelation_time(x: np.ndarray, c: float = 5.0) -> float:
    """Integrated autocorrelation time (samples, ≥ 1) of the series ``x``, with Sokal's
    automatic window (the first lag ``M ≥ c·τ(M)``; Sokal, Monte Carlo methods in statistical
    mechanics, 1997): how many samples carry the information of one independent sample."""
    x = np.asarray(x, float) - np.mean(x)
    n = len(x)
    if n < 4 or not np.any(x):
        return 1.0
    acf = correlate(x, x)[n - 1 :]  # lags 0 … n − 1
    acf /= acf[0]
    tau = 1.0 + 2.0 * np.cumsum(acf[1:])
    lags = np.arange(1, n)
    stop = np.flatnonzero(lags >= c * tau)
    return float(max(1.0, tau[stop[0]] if len(stop) else tau[-1]))


def _heading_rot(delta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` (N, 3) turned about the vertical by ``delta`` (N,) rad."""
    c, s = np.cos(delta), np.sin(delta)
    return np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]])


def _unit(phi: float, theta: float) -> np.ndarray:
    return np.array([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])


def _sph(v: np.ndarray) -> tuple[float, float]:
    v = v / np.linalg.norm(v)
    return float(np.arcsin(np.clip(v[2], -1, 1))), float(np.arctan2(v[1], v[0]))


class _TwoAxisProblem:
    """Samples and residual of the two-axis constraint (see :func:`fit_two_dof`).

    ``spin`` (N, 3), when given, is the proximal sensor's rate about the proximal segment's long
    axis times that axis, both in the earth frame: the segment turns about its long axis
    ``1 + k`` times as fast as the sensor on its skin, ``k`` fitted (parameter 4, bounded by
    ``AXIAL_LAG_MAX``)."""

    def __init__(self, t, w1, w2, m1, m2, spin=None):
        self.t, self.w1, self.w2, self.m1, self.m2, self.spin = t, w1, w2, m1, m2, spin
        # windows numbered over those that hold samples (a pause longer than a window leaves
        # one empty: its heading would be free, its time undefined)
        raw = ((t - t[0]) // TWO_AXIS_WINDOW_S).astype(int) if len(t) else np.zeros(0, int)
        self.win = np.unique(raw, return_inverse=True)[1].ravel()
        self.n_win = int(self.win.max()) + 1 if len(t) else 0
        self.n_axes = 4 if spin is None else 5  # parameters before the windows' headings

    def part(self, a: int, b: int, lag: float) -> _TwoAxisProblem:
        """The problem on samples ``a:b`` with ``k`` held at ``lag`` (a property of where the
        sensor sits, the same in every part of the movement)."""
        w1 = self.w1[a:b] if self.spin is None else self.w1[a:b] + lag * self.spin[a:b]
        return _TwoAxisProblem(self.t[a:b], w1, self.w2[a:b], self.m1[a:b], self.m2[a:b])

    def lag(self, x: np.ndarray) -> float:
        """The fitted ``k`` (0 without ``spin``)."""
        return float(x[4]) if self.spin is not None else 0.0

    def residual(self, x: np.ndarray) -> np.ndarray:
        j1, j2 = _unit(x[0], x[1]), _unit(x[2], x[3])
        delta = x[self.n_axes :][self.win]
        a = self.m1 @ j1
        b = _heading_rot(delta, self.m2 @ j2)
        n = np.cross(a, b)
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-9)[:, None]
        w1 = self.w1 if self.spin is None else self.w1 + self.lag(x) * self.spin
        return np.einsum("ij,ij->i", n, w1 - _heading_rot(delta, self.w2))

    def delta_variances(self, x: np.ndarray) -> np.ndarray:
        """Variance (rad²) of each window's fitted heading offset at the solution ``x``: the
        residuals' robust variance, times their integrated autocorrelation time (neighbouring
        residuals are not independent: skin and fusion errors last), over the window's
        information about its offset (the robust weights times the residuals' slope in it)."""
        r = self.residual(x)
        weight = 1.0 / np.sqrt(1.0 + (r / ROBUST_SCALE_RAD_S) ** 2)  # soft-L1's IRLS weights
        sigma2 = float(np.sum(weight * r**2) / np.sum(weight))
        h = np.zeros_like(x)
        h[self.n_axes :] = 1e-4  # a sample's residual depends on its own window's offset only
        slope = (self.residual(x + h) - r) / 1e-4
        info = np.bincount(self.win, weight * slope**2, minlength=self.n_win)
        tau = [autocorrelation_time(r[self.win == k]) for k in range(self.n_win)]
        return sigma2 * np.asarray(tau) / np.maximum(info, 1e-12)

    def deltas(self, j1: np.ndarray, j2: np.ndarray) -> np.ndarray:
        """The best heading offset of each window for given axes, from a 5° grid."""
        grid = np.linspace(-np.pi, np.pi, 72, endpoint=False)
        a, b0 = self.m1 @ j1, self.m2 @ j2
        out = np.zeros(self.n_win)
        for k in range(self.n_win):
            s = self.win == k
            costs = []
            for d in grid:
                dd = np.full(s.sum(), d)
                n = np.cross(a[s], _heading_rot(dd, b0[s]))
                n /= np.maximum(np.linalg.norm(n, axis=1), 1e-9)[:, None]
                e = np.einsum("ij,ij->i", n, self.w1[s] - _heading_rot(dd, self.w2[s]))
                costs.append(np.sum(np.abs(e)))
            out[k] = grid[int(np.argmin(costs))]
        return out

    def solve(self, starts: list[tuple[np.ndarray, np.ndarray]], lag: float = AXIAL_LAG_START):
        from scipy.optimize import least_squares

        lo = np.full(self.n_axes + self.n_win, -np.inf)
        hi = np.full(self.n_axes + self.n_win, np.inf)
        if self.spin is not None:
            lo[4], hi[4] = 0.0, AXIAL_LAG_MAX
        best = None
        for j1, j2 in starts:
            j1, j2 = j1 / np.linalg.norm(j1), j2 / np.linalg.norm(j2)
            x0 = np.r_[_sph(j1), _sph(j2), [lag] * (self.n_axes - 4), self.deltas(j1, j2)]
            fit = least_squares(
                self.residual, x0, bounds=(lo, hi), method="trf", loss="soft_l1",
                f_scale=ROBUST_SCALE_RAD_S, max_nfev=200,
            )  # fmt: skip
            if best is None or fit.cost < best.cost:
                best = fit
        return best


def fit_two_dof(
    joint: str,
    proximal: tuple[np.ndarray, np.ndarray, np.ndarray],
    distal: tuple[np.ndarray, np.ndarray, np.ndarray],
    prior_1: np.ndarray,
    prior_2: np.ndarray,
    reference: tuple[float, float] | None = None,
    axial_lag: bool = False,
) -> TwoAxisFit:
    """Flexion axis (proximal sensor) and long axis (distal sensor) of a joint that turns about
    one axis fixed in each segment: the elbow, flexion fixed in the upper arm and pronation in
    the forearm.

    After Laidig, Müller & Seel (Curr Dir Biomed Eng 2017 3:167): the relative angular velocity
    lies in the plane of the two axes, so its component along ``j1 × j2`` (all in the earth
    frame) is zero at every sample. The sensors' 6-D orientations (``proximal``, ``distal`` =
    ``(time s, gyr rad/s, q)``) give that frame up to a heading offset between them, fitted per
    window of ``TWO_AXIS_WINDOW_S`` (it drifts). Starts: the nominal placement and random
    directions, each window's heading by a grid; then a soft-L1 least-squares refinement.

    ``axial_lag`` (the proximal segment's long axis vertical in the ``reference`` pose, as the
    upper arm hanging in the stand): the proximal sensor sits on skin that follows only part of
    the segment's rotation about that axis, so the segment's rate is the sensor's plus ``k``
    times its part about the axis, ``k`` fitted with the axes (``AXIAL_LAG_START``,
    ``AXIAL_LAG_MAX``; the fraction followed, ``1 / (1 + k)``, is kept as ``axial_follow``).
    Without it the skin's lag is read as a turn off the two axes, which tilts them: on the
    simulated arm (``bench/elbow_sources.py``) the flexion axis lay up to 20° from the truth and
    the parts of the movement disagreed by up to 20°.

    Signs: the long axis points proximally (up in the ``reference`` pose, arms hanging); the
    flexion axis by anatomy as for :func:`fit_hinge`, else by the nominal placement. Verdict from
    the residual relative to the relative angular rate and the consistency of ``N_PARTS`` part
    fits, as for :func:`fit_hinge`; with ``axial_lag``, a flexion axis further than
    ``ACROSS_LONG_AXIS_DEG`` from the perpendicular to the stand's long axis (kept as
    ``across_deg``) is refused as no elbow's (``not determined``).
    """
    t, g1, g2, q1, q2, speed = shared_movement(joint, proximal, distal)
    w1, w2 = rot.rotate(q1, g1), rot.rotate(q2, g2)
    active = np.linalg.norm(w1 - w2, axis=1)  # heading offsets do not matter for a threshold
    keep = np.flatnonzero(speed >= 0.1 * np.percentile(speed, 95))
    keep = keep[np.linspace(0, len(keep) - 1, min(len(keep), TWO_AXIS_MAX_SAMPLES)).astype(int)]
    ref = None
    if reference is not None and ((t >= reference[0]) & (t <= reference[1])).sum() >= 5:
        ref = (t >= reference[0]) & (t <= reference[1])
    spin = None
    if axial_lag and ref is not None:
        long_p = rot.rotate(rot.conj(rot.mean(q1[ref])), np.array([0.0, 0.0, 1.0]))
        spin = rot.rotate(q1[keep], np.outer(g1[keep] @ long_p, long_p))
    prob = _TwoAxisProblem(
        t[keep], w1[keep], w2[keep], rot.to_matrix(q1[keep]), rot.to_matrix(q2[keep]), spin
    )
    rng = np.random.default_rng(0)
    starts = [(prior_1, prior_2)] + [
        (rng.normal(size=3), rng.normal(size=3)) for _ in range(TWO_AXIS_STARTS)
    ]
    best = prob.solve(starts)
    j1, j2 = _unit(best.x[0], best.x[1]), _unit(best.x[2], best.x[3])
    res = prob.residual(best.x)
    residual = float(np.sqrt(np.mean(res**2)))
    scale = float(np.sqrt(np.mean(active[keep] ** 2)))
    relative = residual / scale if scale > 0 else float("inf")
    win_times = np.array([prob.t[prob.win == k].mean() for k in range(prob.n_win)])
    deltas = heading.smoothed_track(
        win_times, best.x[prob.n_axes :], prob.delta_variances(best.x),
        np.radians(TWO_AXIS_DRIFT_DEG_S),
    )  # fmt: skip
    lag = prob.lag(best.x)

    def refit(a: int, b: int) -> tuple[np.ndarray, np.ndarray] | None:
        if b - a < MIN_PART_SAMPLES:
            return None
        fit = prob.part(a, b, lag).solve([(j1, j2)])
        return _unit(fit.x[0], fit.x[1]), _unit(fit.x[2], fit.x[3])

    worst = _consistency(len(prob.t), refit, j1, j2)
    # the distal orientation with its heading tied to the proximal one
    q2_aligned = heading.apply_heading(q2, heading.heading_track(win_times, deltas, t))
    reasons: list[str] = []
    sign_source = "nominal"
    flex_d = np.full(3, np.nan)
    excursion = (float("nan"), float("nan"))
    if ref is not None:
        up_d = rot.rotate(rot.conj(rot.mean(q2[ref])), np.array([0.0, 0.0, 1.0]))
        j2 = j2 if j2 @ up_d >= 0 else -j2
        sign, excursion = anatomical_sign(t, q1, q2_aligned, j1, j1, reference, align=False)
        if sign is not None:
            j1, sign_source = sign * j1, "anatomy"
    else:
        j2 = j2 if j2 @ prior_2 >= 0 else -j2
    if sign_source == "nominal":
        j1 = j1 if j1 @ prior_1 >= 0 else -j1
        reasons.append(
            "the direction of flexion could not be told from the movement (no stand with the "
            "joint straight, or no clear flexion), so it follows the nominal placement"
        )
    if ref is not None:
        r_d = rot.to_matrix(q2_aligned[ref])
        r_p = rot.to_matrix(q1[ref])
        flex_d = np.mean(np.einsum("nji,njk,k->ni", r_d, r_p, j1), axis=0)
        flex_d /= np.linalg.norm(flex_d)
    verdict = _verdict(
        worst, relative, sign_source == "nominal", reasons, "the axes differ", "the two axes"
    )
    across = float("nan")
    if spin is not None:
        across = 90.0 - _angle_deg(j1, long_p)
        if across > ACROSS_LONG_AXIS_DEG:
            verdict = "not determined"
            reasons.append(
                f"the flexion axis lies {90.0 - across:.0f}° from the long axis the stand gives "
                "the proximal segment; a joint of this kind flexes across it"
            )
    return TwoAxisFit(
        joint=joint,
        axis_proximal=j1,
        axis_distal=j2,
        residual_rad_s=residual,
        relative_residual=relative,
        consistency_deg=worst,
        relative_sign="measured",
        sign=sign_source,
        excursion_deg=excursion,
        window_s=(float(t[0]), float(t[-1])),
        n_samples=len(keep),
        verdict=verdict,
        reasons=reasons,
        flexion_distal=flex_d,
        heading_times=win_times,
        heading_deltas=deltas,
        axial_follow=1.0 / (1.0 + lag) if spin is not None else float("nan"),
        across_deg=across,
    )
