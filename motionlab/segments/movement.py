"""Hinge axes from ordinary movement: gait, free arm movement, a rig's motion.

A recording made as people make them holds a stand and a task, not the protocol's functional
movements. The flexion axis of a knee, an elbow or a generic hinge is then taken from whatever
the two segments did, with Seel's constraint (Seel, Raisch & Schauer, Sensors 2014 14:6891;
:func:`~motionlab.segments.hinge.hinge_axes`) fitted with a robust loss (soft-L1, so that the
knee's small ab/adduction and rotation, soft-tissue wobble and impacts weigh less than the
flexion) on gyroscopes low-passed at ``LOWPASS_HZ``.

The constraint leaves the sign of each axis free. They are fixed in two steps:

1. **Relative sign** (both axes the same physical direction): the axis seen from both segments
   is one vector, so its *vertical* component is the same from both sides at every sample,
   whatever the (6-D, unknown) headings. Of ``±j_distal`` the one whose vertical component
   follows the proximal's is kept (:func:`relative_sign`); where the axis stays horizontal
   (a seated knee flexion) the test cannot tell and the nominal placement decides.
2. **Absolute sign** (which way is flexion): for joints the table marks anatomical (knee,
   elbow), the angle about the axis, integrated from the reference pose (standing: knee straight,
   arm hanging), is one-sided: the knee and elbow flex far one way and hardly hyperextend. The
   direction with the larger excursion is flexion (:func:`anatomical_sign`). Otherwise the
   nominal placement (the protocol's ``sensor_axes`` hint) decides.

A verdict comes from the fit's own numbers: the RMS residual relative to the RMS of the
perpendicular angular rate, and the consistency of the axes fitted on ``N_PARTS`` consecutive
parts of the movement (largest angle to the whole fit).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import butter, sosfiltfilt

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.segments.hinge import hinge_axes
from motionlab.session import estimate_rate

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


@dataclass
class HingeFit:
    """Hinge axis of one joint from movement, in the two sensors' coordinates.

    ``axis_proximal`` / ``axis_distal`` are unit vectors (3,) pointing along the positive
    (flexion) direction of the joint angle; ``verdict`` is ``determined``, ``weak`` or
    ``not determined`` and ``reasons`` says why in plain words.
    """

    joint: str
    axis_proximal: np.ndarray
    axis_distal: np.ndarray
    residual_rad_s: float
    relative_residual: float
    consistency_deg: float
    relative_sign: str  # "measured" | "nominal"
    sign: str  # "anatomy" | "nominal"
    excursion_deg: tuple[float, float] = (float("nan"), float("nan"))
    window_s: tuple[float, float] = (float("nan"), float("nan"))
    n_samples: int = 0
    verdict: str = "determined"
    reasons: list[str] = field(default_factory=list)

    def to_tree(self) -> dict:
        """The HDF5 results layout (plain numbers, lists and strings)."""
        return {
            "joint": self.joint,
            "axis_proximal": np.asarray(self.axis_proximal, float),
            "axis_distal": np.asarray(self.axis_distal, float),
            "residual_rad_s": self.residual_rad_s,
            "relative_residual": self.relative_residual,
            "consistency_deg": self.consistency_deg,
            "relative_sign": self.relative_sign,
            "sign": self.sign,
            "excursion_deg": list(self.excursion_deg),
            "window_s": list(self.window_s),
            "n_samples": self.n_samples,
            "verdict": self.verdict,
            "reasons": list(self.reasons),
        }


def _lowpass(x: np.ndarray, rate: float) -> np.ndarray:
    if len(x) < 30 or not rate > 2.5 * LOWPASS_HZ:
        return x
    return sosfiltfilt(butter(2, LOWPASS_HZ, fs=rate, output="sos"), x, axis=0)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(float(a @ b)), 0.0, 1.0))))


def _on(t: np.ndarray, td: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, td, x[:, k]) for k in range(x.shape[1])])


def relative_sign(
    q_p: np.ndarray, q_d: np.ndarray, j_p: np.ndarray, j_d: np.ndarray
) -> tuple[float, float]:
    """Sign (±1) to give ``j_d`` so that it is the same physical axis as ``j_p``, and the margin.

    ``q_p``, ``q_d`` (N, 4) are the sensors' orientations on one clock (only their tilt matters).
    The margin (0 to 1) is ``(bad - good) / (bad + good)`` of the mean squared difference of the
    axis' vertical components from both sides.
    """
    up_p = rot.rotate(q_p, np.broadcast_to(j_p, (len(q_p), 3)))[:, 2]
    up_d = rot.rotate(q_d, np.broadcast_to(j_d, (len(q_d), 3)))[:, 2]
    ok = np.isfinite(up_p) & np.isfinite(up_d)
    same = float(np.mean((up_p[ok] - up_d[ok]) ** 2))
    flip = float(np.mean((up_p[ok] + up_d[ok]) ** 2))
    good, bad = min(same, flip), max(same, flip)
    margin = (bad - good) / (bad + good) if bad + good > 0 else 0.0
    return (1.0 if same <= flip else -1.0), margin


def anatomical_sign(
    t: np.ndarray,
    q_p: np.ndarray,
    q_d: np.ndarray,
    j_p: np.ndarray,
    j_d: np.ndarray,
    reference: tuple[float, float],
) -> tuple[float | None, tuple[float, float]]:
    """Sign (±1) making the joint angle about ``j`` flex the way anatomy allows, or ``None``.

    ``q_p``, ``q_d`` (N, 4) are the sensors' 6-D orientations on the time ``t`` (s). The distal
    heading is tied to the proximal one by the hinge (:func:`.heading.hinge_anchors`), and the
    angle about ``j_p`` of the relative rotation since the ``reference`` window (a still pose
    with the joint straight) is taken at every sample: unlike an integrated gyroscope it does
    not drift with turns. The excursions (98th percentile each way, degrees: flexion then
    extension) are returned with the sign. ``None`` (and the excursions along ``+j``, then
    ``-j``) when neither dominates (see ``FLEXION_MIN_DEG``, ``FLEXION_RATIO``).
    """
    from motionlab.segments import heading

    sel = (t >= reference[0]) & (t <= reference[1])
    if sel.sum() < 5:
        return None, (float("nan"), float("nan"))
    times, deltas = heading.hinge_anchors(t, q_p, q_d, j_p, j_d)
    if len(times):
        q_d = heading.apply_heading(q_d, heading.heading_track(times, deltas, t))
    q_rel = rot.mul(rot.conj(q_p), q_d)
    r = rot.mul(q_rel, rot.conj(rot.mean(q_rel[sel])))
    theta = np.degrees(2.0 * np.arctan2(r[:, 1:] @ j_p, np.abs(r[:, 0])) * np.sign(r[:, 0] + 1e-12))
    after = (t >= reference[0]) & np.isfinite(theta)
    up = float(np.percentile(theta[after], 98))
    down = float(-np.percentile(theta[after], 2))
    big, small = max(up, down), max(min(up, down), 0.0)
    if big < FLEXION_MIN_DEG or big < FLEXION_RATIO * small:
        return None, (up, down)
    return (1.0 if up >= down else -1.0), (big, small)


def fit_hinge(
    joint: str,
    proximal: tuple[np.ndarray, np.ndarray, np.ndarray],
    distal: tuple[np.ndarray, np.ndarray, np.ndarray],
    prior_p: np.ndarray,
    prior_d: np.ndarray,
    window: tuple[float, float] | None = None,
    reference: tuple[float, float] | None = None,
    anatomical: bool = False,
) -> HingeFit:
    """Hinge axis of ``joint`` from the movement of its two segments (see the module notes).

    ``proximal`` and ``distal`` are ``(time s, gyr rad/s (N, 3), q_sensor (N, 4))``; ``prior_*``
    are the axis (positive direction) in sensor coordinates under the nominal placement;
    ``window`` limits the samples used (s); ``reference`` is a still window in the joint's zero
    pose (for the anatomical sign).
    """
    tp, gp, qp = proximal
    td, gd, qd = distal
    sel = np.ones(len(tp), bool)
    if window is not None:
        sel = (tp >= window[0]) & (tp <= window[1])
    sel &= (tp >= td[0]) & (tp <= td[-1])
    t = tp[sel]
    if len(t) < 3 * MIN_PART_SAMPLES:
        raise InputError(
            f"joint {joint}: too little shared movement for the hinge axis ({len(t)} samples)",
            remedy="record a longer movement of the joint",
        )
    rate = estimate_rate(t)
    g1 = _lowpass(gp[sel], rate)
    g2 = _lowpass(_on(t, td, gd), rate)
    q1 = qp[sel]
    q2 = rot.resample(td, qd, t)
    active = np.maximum(np.linalg.norm(g1, axis=1), np.linalg.norm(g2, axis=1))
    if not np.percentile(active, 95) >= MIN_ACTIVE_RAD_S:
        raise InputError(
            f"joint {joint}: its segments hardly turn (95th percentile "
            f"{np.percentile(active, 95):.2f} rad/s)",
            remedy="record a movement of the joint",
        )
    j_p, j_d, _ = hinge_axes(g1, g2, prior_p, prior_d, loss="soft_l1", f_scale=ROBUST_SCALE_RAD_S)
    reasons: list[str] = []
    # consistency over consecutive parts of the movement
    worst = 0.0
    bounds = np.linspace(0, len(t), N_PARTS + 1).astype(int)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        part_active = active[a:b] >= 0.1 * np.percentile(active, 95)
        if part_active.sum() < MIN_PART_SAMPLES:
            continue
        try:
            pp, pd_, _ = hinge_axes(
                g1[a:b], g2[a:b], j_p, j_d, n_starts=0, loss="soft_l1", f_scale=ROBUST_SCALE_RAD_S
            )
        except InputError:
            continue
        worst = max(worst, _angle_deg(pp, j_p), _angle_deg(pd_, j_d))
    # residual of the whole fit, relative to the perpendicular rate
    perp1 = np.linalg.norm(np.cross(g1, j_p), axis=1)
    perp2 = np.linalg.norm(np.cross(g2, j_d), axis=1)
    on = active >= 0.1 * np.percentile(active, 95)
    residual = float(np.sqrt(np.mean((perp1[on] - perp2[on]) ** 2)))
    scale = float(np.sqrt(np.mean(0.5 * (perp1[on] ** 2 + perp2[on] ** 2))))
    relative = residual / scale if scale > 0 else float("inf")
    # signs
    s_rel, margin = relative_sign(q1[on], q2[on], j_p, j_d)
    if margin >= SIGN_MARGIN:
        j_d = s_rel * j_d
        rel_source = "measured"
    else:
        j_d = j_d if (j_p @ prior_p) * (j_d @ prior_d) >= 0 else -j_d
        rel_source = "nominal"
        reasons.append(
            "the two segments' axis stayed horizontal, so which way it points on the distal "
            "segment is taken from the nominal placement"
        )
    sign, excursion = None, (float("nan"), float("nan"))
    if anatomical and reference is not None:
        sign, excursion = anatomical_sign(t, q1, q2, j_p, j_d, reference)
    if sign is not None:
        j_p, j_d, sign_source = sign * j_p, sign * j_d, "anatomy"
    else:
        s = 1.0 if j_p @ prior_p + j_d @ prior_d >= 0 else -1.0
        j_p, j_d, sign_source = s * j_p, s * j_d, "nominal"
        if anatomical:
            reasons.append(
                "the direction of flexion could not be told from the movement (no stand with "
                "the joint straight, or no clear flexion), so it follows the nominal placement"
            )
    verdict = "determined"
    if worst > WEAK_DEG or relative > WEAK_RESIDUAL:
        verdict = "not determined"
    elif worst > DETERMINED_DEG or relative > DETERMINED_RESIDUAL or rel_source == "nominal":
        verdict = "weak"
    if worst > DETERMINED_DEG:
        reasons.append(f"the axis differs by up to {worst:.0f}° between parts of the movement")
    if relative > DETERMINED_RESIDUAL:
        reasons.append(
            f"the movement is not about one axis (residual {100 * relative:.0f}% of the rate)"
        )
    if anatomical and sign_source == "nominal" and verdict == "determined":
        verdict = "weak"
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


def _heading_rot(delta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` (N, 3) turned about the vertical by ``delta`` (N,) rad."""
    c, s = np.cos(delta), np.sin(delta)
    return np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]])


def _unit(phi: float, theta: float) -> np.ndarray:
    return np.array([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])


def _sph(v: np.ndarray) -> tuple[float, float]:
    v = v / np.linalg.norm(v)
    return float(np.arcsin(np.clip(v[2], -1, 1))), float(np.arctan2(v[1], v[0]))


@dataclass
class TwoAxisFit:
    """Flexion axis in the proximal sensor and long (pronation) axis in the distal sensor of a
    two-degree-of-freedom joint (the elbow), unit (3,), with the heading offsets fitted with them
    and a verdict as for :class:`HingeFit`."""

    joint: str
    axis_proximal: np.ndarray
    axis_distal: np.ndarray
    residual_rad_s: float
    relative_residual: float
    consistency_deg: float
    carrying_deg: float  # 90° less the angle between the two axes in the reference pose
    verdict: str = "determined"
    reasons: list[str] = field(default_factory=list)


def fit_two_axes(
    joint: str,
    proximal: tuple[np.ndarray, np.ndarray, np.ndarray],
    distal: tuple[np.ndarray, np.ndarray, np.ndarray],
    j1_start: np.ndarray,
    j2_prior: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Axes ``j1`` (proximal sensor) and ``j2`` (distal sensor) of a joint that turns about one
    axis fixed in each segment (the elbow: flexion fixed in the upper arm, pronation in the
    forearm), and the RMS residual (rad/s).

    After Laidig, Müller & Seel (Curr Dir Biomed Eng 2017 3:167): the relative angular velocity
    lies in the plane of the two axes, so its component along ``j1 × j2`` (all in the earth
    frame) is zero. The sensors' 6-D orientations (``proximal``, ``distal`` = ``(time, gyr,
    q)``, one clock) give that frame up to a heading offset between them, fitted per window of
    ``TWO_AXIS_WINDOW_S`` (it drifts). Starts: ``j1_start`` (a hinge fit) with ``±j2_prior`` and
    random ``j2``; the heading of each window by a grid; then a soft-L1 least-squares refinement.
    """
    from scipy.optimize import least_squares

    tp, gp, qp = proximal
    td, gd, qd = distal
    sel = (tp >= td[0]) & (tp <= td[-1])
    t = tp[sel]
    rate = estimate_rate(t)
    w1 = rot.rotate(qp[sel], _lowpass(gp[sel], rate))
    q2 = rot.resample(td, qd, t)
    w2 = rot.rotate(q2, _lowpass(_on(t, td, gd), rate))
    active = np.maximum(np.linalg.norm(w1, axis=1), np.linalg.norm(w2, axis=1))
    keep = np.flatnonzero(active >= 0.1 * np.percentile(active, 95))
    keep = keep[np.linspace(0, len(keep) - 1, min(len(keep), TWO_AXIS_MAX_SAMPLES)).astype(int)]
    m1 = rot.to_matrix(qp[sel][keep])
    m2 = rot.to_matrix(q2[keep])
    w1, w2, tk = w1[keep], w2[keep], t[keep]
    win = ((tk - tk[0]) // TWO_AXIS_WINDOW_S).astype(int)
    n_win = int(win.max()) + 1

    def residual(x: np.ndarray) -> np.ndarray:
        j1, j2 = _unit(x[0], x[1]), _unit(x[2], x[3])
        delta = x[4:][win]
        a = m1 @ j1
        b = _heading_rot(delta, m2 @ j2)
        n = np.cross(a, b)
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-9)[:, None]
        return np.einsum("ij,ij->i", n, w1 - _heading_rot(delta, w2))

    def init_deltas(j1: np.ndarray, j2: np.ndarray) -> np.ndarray:
        grid = np.linspace(-np.pi, np.pi, 72, endpoint=False)
        a, b0 = m1 @ j1, m2 @ j2
        out = np.zeros(n_win)
        for k in range(n_win):
            s = win == k
            costs = []
            for d in grid:
                n = np.cross(a[s], _heading_rot(np.full(s.sum(), d), b0[s]))
                n /= np.maximum(np.linalg.norm(n, axis=1), 1e-9)[:, None]
                e = np.einsum("ij,ij->i", n, w1[s] - _heading_rot(np.full(s.sum(), d), w2[s]))
                costs.append(np.sum(np.abs(e)))
            out[k] = grid[int(np.argmin(costs))]
        return out

    rng = np.random.default_rng(0)
    starts = [(j1_start, j2_prior)] + [
        (rng.normal(size=3), rng.normal(size=3)) for _ in range(TWO_AXIS_STARTS)
    ]
    best = None
    for j1, j2 in starts:
        j1, j2 = j1 / np.linalg.norm(j1), j2 / np.linalg.norm(j2)
        x0 = np.r_[_sph(j1), _sph(j2), init_deltas(j1, j2)]
        fit = least_squares(
            residual, x0, method="trf", loss="soft_l1", f_scale=ROBUST_SCALE_RAD_S, max_nfev=200
        )
        if best is None or fit.cost < best.cost:
            best = fit
    j1, j2 = _unit(best.x[0], best.x[1]), _unit(best.x[2], best.x[3])
    return j1, j2, float(np.sqrt(np.mean(residual(best.x) ** 2)))
