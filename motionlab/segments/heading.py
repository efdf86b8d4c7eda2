"""Heading alignment of adjacent segments without the magnetometer.

A 6-D orientation estimate has an arbitrary heading per sensor: each sensor's "earth" frame is the
true ENU frame turned about the vertical by an unknown angle, which drifts slowly (gyroscope bias
and scale-factor errors while the subject turns). For joint angles, the distal segment's
orientation is turned about the earth vertical by ``δ(t)`` (``q ← q_z(δ) ⊗ q``) so that it shares
the proximal segment's heading. ``δ`` is measured at *anchors* and interpolated linearly in time
between them (held before the first and after the last):

- a movement of both segments about one axis (the protocol names the same axis for both: a
  straight-leg hip flexion, a straight-arm shoulder flexion, trunk flexion over the pelvis): their
  earth-frame angular velocities are parallel, so ``δ`` is the 2-D Procrustes angle between their
  horizontal components (:func:`heading_from_rates`);
- the reference pose (standing): the two segment frames coincide, so ``δ`` maximises
  ``tr(R_prox,kᵀ R_z(δ) R_dist,k)`` over the still window (:func:`heading_from_pose`); later rests
  in the same pose (both segments still for ``REST_MIN_S``, their vertical axes within
  ``REST_TILT_DEG`` of vertical) re-reference it, which removes the drift between tasks (To 2012
  §8.2 re-references at pauses). The reference pose ties first; the movements' ties and the
  later rests join in time order where they keep to the track so far, carried on at the drift
  rate its anchors measured (:func:`drift_rate`), within ``REST_JUMP_DEG`` plus the drift the
  turning since the last anchor can explain (``DRIFT_PER_TURN`` of the proximal segment's
  accumulated turning about the vertical) plus ``DRIFT_CHANGE`` per second since it; one that
  does not is a held pose (a turned trunk) or a movement's tie that imperfect gyroscopes threw
  off, and is skipped (:func:`on_track`);
- the hinge constraint (:func:`heading_from_hinge`): the joint axis seen from both segments
  (after Laidig et al., Sensors 2022 22:9850). For a joint whose axis was calibrated from
  movement it holds at every sample, so :func:`hinge_anchors` measures δ over the whole
  recording in windows of ``HINGE_WINDOW_S`` every ``HINGE_STEP_S``, each weighted by how
  horizontal the axis is (a vertical axis carries no heading information; windows where its
  horizontal part stays under ``HINGE_MIN_HORIZONTAL`` on average are left out).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import binary_opening, uniform_filter1d

from motionlab import rotations as rot
from motionlab.timebase import runs

if TYPE_CHECKING:
    pass

UP = np.array([0.0, 0.0, 1.0])
RIGHT = np.array([0.0, 0.0, 1.0])  # a segment's z (ISB): to the subject's right
REST_RATE_RAD_S = 0.15
REST_TILT_DEG = 10.0
REST_MIN_S = 2.0
REST_JUMP_DEG = 6.0
DRIFT_PER_TURN = 0.02  # heading drift allowed per turn of the segment (gyro scale errors)
#: a rest is compared with the track carried on at the drift rate its anchors so far measured
#: (:func:`drift_rate`), and may lie this much (rad/s) times the time since the last anchor
#: further off it: how fast that rate may change (0.3°/s). The skin preset's relative trunk
#: heading drifted 14° in the 37 s of an axial-rotation task after anchors that had measured
#: 0.01°/s; with the harsh preset's gyroscopes (0.1-0.4°/s about the vertical apart after the
#: fusion) neutral rests 40 s after the last anchor lay 9-20° off it and were refused, while
#: end-range holds of the axial rotation whose ±35° the drift had half made up were taken:
#: lumbar rotation 21-27° RMS off, graded determined
DRIFT_CHANGE = np.radians(0.3)
#: anchors spanning less than this (s) measure no drift rate (their own scatter would be one)
DRIFT_SPAN_MIN_S = 20.0
HINGE_WINDOW_S = 4.0
HINGE_STEP_S = 1.0
HINGE_MIN_HORIZONTAL = 0.3  # mean horizontal part of the unit axis, at least
HINGE_MEDIAN_WINDOWS = 5  # anchors are median-filtered over this many windows
# a joint that also turns about the distal long axis (the knee): only samples this close to the
# reference pose (straight) tie the headings, where its coupled rotation (screw home) is small
HINGE_STRAIGHT_DEG = 10.0
CENTRE_MIN_M_S2 = 0.5  # mean horizontal joint-centre acceleration a window needs
WALK_MIN_RATE_RAD_S = 0.7  # mean thigh rate of a walking window (slow walkers: about 0.75)
WALK_MIN_FLEXION_SHARE = 0.6  # of the thigh's squared rate about its z (simulated walks 0.75-0.9)
WALK_MAX_TURN_DEG_S = 15.0  # the pelvis's mean turning rate a window allows (a turn: 50-100)
WALK_NEAR_POSE_S = 30.0  # walk anchors this close to a pose tie the walk's mean hip rotation to it
WALK_FAR_S = 60.0  # walk anchors are used this far from every pose (half grades.HEADING_HOLD_S)


def heading_from_pose(q_proximal: np.ndarray, q_distal: np.ndarray) -> float:
    """Heading offset δ (rad) making the distal segment frame equal the proximal one on average."""
    b = np.einsum("nij,nkj->ik", rot.to_matrix(q_distal), rot.to_matrix(q_proximal))
    return float(np.arctan2(b[0, 1] - b[1, 0], b[0, 0] + b[1, 1]))


def _procrustes_2d(a: np.ndarray, d: np.ndarray) -> float:
    """Angle δ (rad) about z turning the horizontal parts of ``d`` (N, 3) onto those of ``a``."""
    cross = np.sum(d[:, 0] * a[:, 1] - d[:, 1] * a[:, 0])
    dot = np.sum(d[:, 0] * a[:, 0] + d[:, 1] * a[:, 1])
    return float(np.arctan2(cross, dot))


def heading_from_hinge(
    q_proximal: np.ndarray, q_distal: np.ndarray, axis_proximal: np.ndarray, axis_distal: np.ndarray
) -> float:
    """Heading offset δ (rad) aligning the joint axis seen from both segments (segment coords).

    Samples where the axis is near vertical carry little heading information and weigh little.
    """
    a = rot.rotate(q_proximal, np.broadcast_to(axis_proximal, (len(q_proximal), 3)))
    d = rot.rotate(q_distal, np.broadcast_to(axis_distal, (len(q_distal), 3)))
    return _procrustes_2d(a, d)


def hinge_anchors(
    t: np.ndarray,
    q_proximal: np.ndarray,
    q_distal: np.ndarray,
    axis_proximal: np.ndarray,
    axis_distal: np.ndarray,
    long_axis: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and heading offsets δ (rad) from the hinge constraint over the whole recording.

    ``q_*`` are segment orientations on the common time ``t``; the axes are the hinge axis in
    each segment's coordinates. One anchor per window whose axis is horizontal enough (the
    mean of its horizontal part at least ``HINGE_MIN_HORIZONTAL``; see the module notes).

    ``long_axis`` (segment coordinates, both segments; vertical in the reference pose): for a
    joint that also turns about the distal segment's long axis with flexion (a knee's screw
    home), only the samples within ``HINGE_STRAIGHT_DEG`` of straight count; otherwise each
    window's δ takes in the mean coupled rotation (on simulated gait, 0.12°/° of a 22° mean
    flexion: the whole 2.7° mean knee rotation was lost). How straight is told without the
    headings: each segment's pitch about its own hinge axis, in its own earth frame.
    """
    a = rot.rotate(q_proximal, np.broadcast_to(axis_proximal, (len(t), 3)))
    d = rot.rotate(q_distal, np.broadcast_to(axis_distal, (len(t), 3)))
    strength = np.sqrt(np.minimum(a[:, 0] ** 2 + a[:, 1] ** 2, d[:, 0] ** 2 + d[:, 1] ** 2))
    select = None
    if long_axis is not None:
        pitch = []
        for q, axis in ((q_proximal, a), (q_distal, d)):
            u = rot.rotate(q, np.broadcast_to(long_axis, (len(t), 3)))
            forward = np.cross(axis, UP)
            forward /= np.maximum(np.linalg.norm(forward, axis=1), 1e-9)[:, None]
            pitch.append(np.arctan2(np.einsum("ij,ij->i", u, forward), u[:, 2]))
        bend = np.abs((pitch[0] - pitch[1] + np.pi) % (2 * np.pi) - np.pi)
        select = bend <= np.radians(HINGE_STRAIGHT_DEG)
    return _window_anchors(t, a, d, strength, HINGE_MIN_HORIZONTAL, select)


def centre_anchors(
    t: np.ndarray,
    q_proximal: np.ndarray,
    q_distal: np.ndarray,
    f_proximal: np.ndarray,
    f_distal: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and heading offsets δ (rad) from the acceleration of a shared joint centre.

    ``f_*`` (N, 3) are the specific force at the joint centre in each sensor's frame
    (:func:`~motionlab.clocksync.joint_centre.joint_centre_forces`) and ``q_*`` the sensors' 6-D
    orientations on ``t``: in the earth frame the two are one vector, so the turn about the
    vertical that brings the distal's horizontal part onto the proximal's is δ (after Weygers et
    al. 2020 and Laidig et al. 2017, for joints without a hinge). One anchor per window whose
    horizontal acceleration is at least ``CENTRE_MIN_M_S2`` on average.
    """
    a = rot.rotate(q_proximal, f_proximal)
    d = rot.rotate(q_distal, f_distal)
    return _window_anchors(t, a, d, np.hypot(a[:, 0], a[:, 1]), CENTRE_MIN_M_S2)


def walk_anchors(
    t: np.ndarray, q_proximal: np.ndarray, q_distal: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and heading offsets δ (rad) of a hip from straight walking.

    ``q_*`` are the pelvis's and the thigh's segment orientations on the common time ``t``.
    In walking the thigh swings about its own z (its flexion axis, from the walk itself,
    :mod:`.gait_axes`) and the pelvis's z stays across the walking direction: over a window of
    several strides, the hip's rotation and ab/adduction swing about their mean, so the two
    z axes share one horizontal direction turned by the hip's mean rotation in walking. δ per
    window of ``HINGE_WINDOW_S`` in which the thigh turns at ``WALK_MIN_RATE_RAD_S`` on average,
    at least ``WALK_MIN_FLEXION_SHARE`` of it (squared) about its z, and the pelvis turns by no
    more than ``WALK_MAX_TURN_DEG_S`` (a straight or gently curved path, no turn), as
    :func:`hinge_anchors` does for a hinge's axis (after Laidig et al. 2022, whose constraint
    the hip keeps only on average). The mean hip rotation in walking is in δ: the caller ties
    it to a pose (:func:`pose_offset`)."""
    a = rot.rotate(q_proximal, np.broadcast_to(RIGHT, (len(t), 3)))
    d = rot.rotate(q_distal, np.broadcast_to(RIGHT, (len(t), 3)))
    w_earth = earth_rates(t, q_distal)
    rate = np.linalg.norm(w_earth, axis=1)
    flexing = rot.rotate(rot.conj(q_distal), w_earth)[:, 2] ** 2  # about the thigh's own z
    forward = np.arctan2(a[:, 1], a[:, 0])  # the pelvis's heading, from its z
    finite = np.isfinite(forward)
    forward[finite] = np.unwrap(forward[finite])  # (a NaN would spread through the unwrap)
    times, deltas = [], []
    for start in np.arange(t[0], t[-1] - HINGE_WINDOW_S / 2, HINGE_STEP_S) if len(t) else []:
        w = slice(*np.searchsorted(t, [start, start + HINGE_WINDOW_S]))
        ok = np.isfinite(rate[w]) & np.isfinite(forward[w]) & np.all(np.isfinite(d[w]), axis=1)
        if ok.sum() < 3 or np.mean(rate[w][ok]) < WALK_MIN_RATE_RAD_S:
            continue
        if np.sum(flexing[w][ok]) < WALK_MIN_FLEXION_SHARE * np.sum(rate[w][ok] ** 2):
            continue  # not a swinging thigh: the axes need not be parallel
        if abs(np.degrees(np.polyfit(t[w][ok], forward[w][ok], 1)[0])) > WALK_MAX_TURN_DEG_S:
            continue  # a turn (the pelvis's swing from stride to stride averages out in the fit)
        times.append(float(np.mean(t[w][ok])))
        deltas.append(_procrustes_2d(a[w][ok], d[w][ok]))
    if not times:
        return np.empty(0), np.empty(0)
    return np.array(times), np.unwrap(deltas)


def pose_offset(
    pose_times: np.ndarray, pose_deltas: np.ndarray, times: np.ndarray, deltas: np.ndarray
) -> float | None:
    """The turn (rad) that puts anchors ``(times, deltas)`` (e.g. :func:`walk_anchors`) on the
    pose anchors' track: at each pose anchor with anchors within ``WALK_NEAR_POSE_S``, the
    pose's δ less their straight-line trend carried to the pose (a steady drift since the pose
    taken out); the median over the poses. ``None`` without such anchors near a pose."""
    offsets = []
    for at, delta in zip(pose_times, pose_deltas, strict=True):
        near = np.abs(times - at) <= WALK_NEAR_POSE_S
        if not near.any():
            continue
        if near.sum() > 1 and np.ptp(times[near]) > 0:
            line = np.polyval(np.polyfit(times[near], deltas[near], 1), at)
        else:
            line = float(np.mean(deltas[near]))
        offsets.append(float(np.angle(np.exp(1j * (delta - line)))))
    return float(np.median(offsets)) if offsets else None


def with_walk_anchors(
    pose_times: np.ndarray, pose_deltas: np.ndarray, times: np.ndarray, deltas: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """The pose anchors joined by the walk's (:func:`walk_anchors`) farther than
    ``WALK_FAR_S`` from every pose, put on the poses' track (:func:`pose_offset`), in time
    order; ``None`` where the walk gives none (no walking near a pose, or none away from one).
    Near a pose its own tie is the better one (the heading has had little time to drift; a
    walk's carries the hip's rotation swinging from window to window: used from 30 s on, they
    cost up to 1° of hip rotation on simulated 60-s walks and 0.25° on average on 74-s ones),
    farther away the walk's (its error does not grow). ``WALK_FAR_S`` is half the time the
    grades trust a pose's tie for (``grades.HEADING_HOLD_S``): a walk is never farther from an
    anchor than that."""
    pose_times, pose_deltas = np.asarray(pose_times, float), np.asarray(pose_deltas, float)
    offset = pose_offset(pose_times, pose_deltas, times, deltas)
    if offset is None:
        return None
    far = np.min(np.abs(times[:, None] - pose_times[None, :]), axis=1) > WALK_FAR_S
    if not far.any():
        return None
    all_times = np.concatenate([pose_times, times[far]])
    order = np.argsort(all_times)
    return all_times[order], np.concatenate([pose_deltas, deltas[far] + offset])[order]


def _window_anchors(
    t: np.ndarray,
    a: np.ndarray,
    d: np.ndarray,
    strength: np.ndarray,
    minimum: float,
    select: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """δ turning the horizontal parts of ``d`` onto those of ``a`` (N, 3, earth frame) in
    windows of ``HINGE_WINDOW_S`` every ``HINGE_STEP_S`` whose ``strength`` (N,) has a mean of
    at least ``minimum``; unwrapped and median-filtered over ``HINGE_MEDIAN_WINDOWS`` windows
    against outliers; only the samples in ``select`` (N,) bool, if given. Returns the windows'
    mean times (s) and δ (rad)."""
    times, deltas = [], []
    finite = np.isfinite(strength) & np.all(np.isfinite(d), axis=1)
    if select is not None:
        finite &= select
    for start in np.arange(t[0], t[-1] - HINGE_WINDOW_S / 2, HINGE_STEP_S) if len(t) else []:
        w = slice(*np.searchsorted(t, [start, start + HINGE_WINDOW_S]))
        ok = finite[w]
        if ok.sum() < 3 or np.mean(strength[w][ok]) < minimum:
            continue
        times.append(float(np.mean(t[w][ok])))
        deltas.append(_procrustes_2d(a[w][ok], d[w][ok]))
    if not times:
        return np.empty(0), np.empty(0)
    # the window shrinks at the ends (scipy's padded median filter repeated the first anchors,
    # which on the rig's vertical hinge cost 0.2-0.3° offset-free RMSE)
    unwrapped, half = np.unwrap(deltas), HINGE_MEDIAN_WINDOWS // 2
    smooth = np.array([np.median(unwrapped[max(0, i - half) : i + half + 1])
                       for i in range(len(unwrapped))])  # fmt: skip
    return np.array(times), smooth


def earth_rates(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angular velocity (N, 3) in rad/s in the earth frame, from an orientation series."""
    step = rot.to_rotvec(rot.mul(q[1:], rot.conj(q[:-1]))) / np.diff(t)[:, None]
    return np.vstack([step, step[-1:]]) if len(step) else np.zeros((len(q), 3))


def heading_from_rates(w_proximal: np.ndarray, w_distal: np.ndarray) -> float:
    """Heading offset δ (rad) making parallel earth-frame angular velocities (N, 3) agree."""
    return _procrustes_2d(w_proximal, w_distal)


def reference_rests(
    t: np.ndarray,
    q_proximal: np.ndarray,
    q_distal: np.ndarray,
    axis_proximal: np.ndarray,
    axis_distal: np.ndarray,
    loose_distal: bool = False,
) -> list[slice]:
    """Still windows (≥ ``REST_MIN_S``) in which both segments' given axes point up.

    ``q_*`` are segment orientations on the common time ``t``; the axes are the reference pose's
    vertical segment axes. ``loose_distal`` doubles the tilt tolerance of the distal segment
    (for one the protocol does not declare vertical, e.g. a forearm with its carrying angle).
    """
    if len(t) < 3:
        return []
    rate = 1.0 / np.median(np.diff(t))
    win = max(1, int(0.5 * rate))
    ok = np.ones(len(t), bool)
    tilts = (REST_TILT_DEG, REST_TILT_DEG * (2.0 if loose_distal else 1.0))
    for q, axis, tilt in zip(
        (q_proximal, q_distal), (axis_proximal, axis_distal), tilts, strict=True
    ):
        speed = uniform_filter1d(np.linalg.norm(earth_rates(t, q), axis=1), win)
        up = rot.rotate(q, np.broadcast_to(axis, (len(q), 3)))[:, 2]
        ok &= (speed < REST_RATE_RAD_S) & (up > np.cos(np.radians(tilt)))
    ok = binary_opening(ok, np.ones(max(1, int(REST_MIN_S * rate)), bool))
    return [slice(a, b) for a, b in runs(ok)]


def on_track(
    times: list[float],
    deltas: list[float],
    at: float,
    delta: float,
    turned: np.ndarray,
    t: np.ndarray,
) -> bool:
    """Whether a rest's ``delta`` at time ``at`` fits the anchors so far (see the module notes):
    within ``REST_JUMP_DEG`` of their track carried on from the last anchor at the drift rate
    they measured (:func:`drift_rate`), plus ``DRIFT_PER_TURN`` of the proximal segment's
    turning about the vertical since the last anchor (``turned``, rad on ``t``: accumulated),
    plus ``DRIFT_CHANGE`` times the time since the last anchor.
    """
    last = max(times)
    ahead = max(at - last, 0.0)
    pred = heading_track(np.array(times), np.array(deltas), np.array([at]))[0]
    pred += drift_rate(times, deltas) * ahead
    since = np.interp(at, t, turned) - np.interp(last, t, turned)
    allowed = np.radians(REST_JUMP_DEG) + DRIFT_PER_TURN * max(since, 0.0) + DRIFT_CHANGE * ahead
    return abs(float(np.angle(np.exp(1j * (delta - pred))))) <= allowed


def drift_rate(times: np.ndarray | list[float], deltas: np.ndarray | list[float]) -> float:
    """How fast (rad/s, signed) two 6-D headings drifted apart by their anchors ``(times s,
    deltas rad)``: the change from the first anchor to the last over the time between them (0
    when they span less than ``DRIFT_SPAN_MIN_S``)."""
    if not len(times):
        return 0.0
    order = np.argsort(times)
    t, d = np.asarray(times, float)[order], np.unwrap(np.asarray(deltas, float)[order])
    span = float(t[-1] - t[0])
    return float(d[-1] - d[0]) / span if span >= DRIFT_SPAN_MIN_S else 0.0


def heading_track(times: np.ndarray, deltas: np.ndarray, t: np.ndarray) -> np.ndarray:
    """δ(t) (rad): the anchors ``(times, deltas)`` unwrapped and interpolated linearly."""
    order = np.argsort(times)
    times, deltas = np.asarray(times, float)[order], np.unwrap(np.asarray(deltas, float)[order])
    return np.interp(t, times, deltas)


def outlying_anchors(deltas: np.ndarray, span: int = 3, limit_deg: float = 45.0) -> np.ndarray:
    """Which heading offsets (rad) lie further than ``limit_deg`` from the middle of their
    ``span`` neighbours on each side (itself left out; the middle: the neighbour nearest the
    others round the circle, a circular median): a window whose fit settled on
    another solution (the two-axis fit's heading half a turn off), not a drift, which moves a
    few degrees a minute. Fewer than two neighbours tell nothing (``False``)."""
    d = np.asarray(deltas, float)
    out = np.zeros(len(d), bool)
    for k in range(len(d)):
        near = np.r_[d[max(0, k - span) : k], d[k + 1 : k + 1 + span]]
        if len(near) < 2:
            continue
        spread = np.abs((near[:, None] - near[None, :] + np.pi) % (2 * np.pi) - np.pi)
        centre = near[np.argmin(spread.sum(axis=1))]  # the neighbour closest to the others
        out[k] = abs((d[k] - centre + np.pi) % (2 * np.pi) - np.pi) > np.radians(limit_deg)
    return out


def smoothed_track(
    times: np.ndarray, deltas: np.ndarray, variances: np.ndarray, drift: float
) -> np.ndarray:
    """Heading offsets (rad) at ``times`` (s) smoothed as a random walk: each measured ``δ_k``
    (unwrapped) has variance ``variances[k]`` (rad²) and the true offset wanders by ``drift``
    (rad/√s) between them (the relative heading drift of two 6-D estimates); a scalar
    Rauch-Tung-Striebel smoother over the anchors (Rauch, Tung & Striebel, AIAA J 1965 3:1445).
    Offsets that :func:`outlying_anchors` flags are left out (given their nearest kept
    neighbour's value and no weight).
    """
    times = np.asarray(times, float)
    z = np.asarray(deltas, float).copy()
    r = np.maximum(np.asarray(variances, float), 1e-12)
    bad = outlying_anchors(z)
    if bad.any() and not bad.all():  # left out: weighed as nothing, unwrapped as a neighbour
        keep = np.flatnonzero(~bad)
        z[bad] = z[keep[np.abs(keep[None, :] - np.flatnonzero(bad)[:, None]).argmin(axis=1)]]
        r = np.where(bad, 1e6, r)
    z = np.unwrap(z)
    n = len(z)
    if n < 2:
        return z
    x_f, p_f, p_p = np.empty(n), np.empty(n), np.empty(n)
    x_f[0] = z[0]  # the first window alone: no prior
    p_f[0] = p_p[0] = r[0]
    for k in range(1, n):
        p_p[k] = p_f[k - 1] + drift**2 * (times[k] - times[k - 1])
        gain = p_p[k] / (p_p[k] + r[k])
        x_f[k] = x_f[k - 1] + gain * (z[k] - x_f[k - 1])
        p_f[k] = (1.0 - gain) * p_p[k]
    out = x_f.copy()
    for k in range(n - 2, -1, -1):
        out[k] = x_f[k] + p_f[k] / p_p[k + 1] * (out[k + 1] - x_f[k])
    return out


def apply_heading(q: np.ndarray, delta: float | np.ndarray) -> np.ndarray:
    """Orientations turned by ``delta`` (rad, scalar or per sample) about the earth vertical."""
    return rot.mul(rot.from_axis_angle(UP, delta), q)
