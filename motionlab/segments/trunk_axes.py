"""Trunk calibration from recordings as people make them (protocol ``lumbar_seated``).

A protocol whose functional step says ``axis_method: trunk`` is calibrated here instead of by
finding its steps in order (:func:`motionlab.segments.calibrate_segments` hands it over). The
recording needs only a **rest** somewhere (start, end or between movements; standing or seated)
and **trunk movement** in any order, also as one continuous block:

1. **Rest:** the stillest stretch of at least :data:`REST_MIN_S` (``SHORTEST_POSE_S``), by the
   mean angular speed of the joint's sensors over a sliding second, grown while they stay as
   still; refused when even the stillest second turns faster than :data:`REST_MAX_DEG_S`, and
   every angle ``weak`` when it turns faster than :data:`REST_SLOW_DEG_S` (slow movement, not
   a rest: the zero and the verticals are of a moving posture).
   Each segment's vertical (its y) is gravity seen by its sensor over the rest.
2. **Heading between the sensors** (6-D fusions have one each): the angle about the vertical
   that turns the thorax's earth-frame angular velocity onto the pelvis's over the whole
   recording (:func:`motionlab.segments.heading.heading_from_rates`; trunk movement turns both
   about parallel axes: the pelvis tilts with the thorax). When the rest is still (under
   :data:`STILL_DEG_S`) and both fusions are 6-D with their gyroscope bias reported, the
   headings' drift apart is followed too: each gyroscope's mean over the rest's steady samples
   (a seated back's sway is movement, not bias), less the bias its fusion removed there,
   integrated about the vertical (:func:`_heading_drift`); gyroscopes calibrated per serial
   before the fusion (``motionlab sensorcal``) have no bias left to follow.
3. **Flexion axis:** of the two perpendicular axes about which the thorax's angular velocity
   relative to the pelvis turns most often (in the thorax sensor frame, perpendicular to the rest's
   vertical, over the recording; :func:`_horizontal_axes`), the one it turns about most (not
   the more one-sided one, which depends on the rest's posture: docs/kinematics.md). Its
   direction (flexion about −z, ISB) is the side of the longer tail from the thorax's median
   posture (:func:`_flexion_side`): people lean forward further than back (a backrest, gravity).
   The pelvis's flexion axis is the thorax's carried through the rest's relative orientation
   (the rest is the zero of all three angles: lateral bending and axial rotation of the rest
   are taken as none), made perpendicular to its own vertical. x = y × z in both; no
   ``sensor_axes`` hint is used.
4. **Grades** (:func:`trunk_grades`): flexion and lateral bending are ``determined`` when the
   movement about the chosen axis is at least :data:`AXIS_RATIO_MIN` times as one-sided as about
   the other (people bend about as far to either side), the thorax moved at least
   :data:`SIGN_RATIO_MIN` times further one way than the other about it from the rest, at
   least :data:`BEND_MIN_DEG` (a sway is no bend), and that way is the flexion side (the
   rest's extremes and the median's tails agree);
   ``weak`` otherwise; axial rotation when the heading from the movement explains at least
   :data:`HEADING_RHO_MIN` of the horizontal rates and the headings' drift apart is followed
   (a still rest, step 2) or calibrated away (both gyroscopes calibrated per serial before the
   fusion, :func:`_gyros_calibrated`). Without either, a seated person's sway hides the
   gyroscope biases: an unseen 0.2-0.3°/s about the pelvis sensor's vertical cost the three
   real trials without a still rest 0.1-0.5° of their rotation from the rest
   (docs/kinematics.md).
   Every angle is at best ``weak`` when the lumbar spine extended as the thorax leaned forward
   over the movement (:func:`_lean_coupling` under :data:`LEAN_COUPLING_MIN`) or twisted
   against the thorax's own turning about the vertical (:func:`_twist_coupling` under
   :data:`TWIST_COUPLING_MIN`): a spine flexes as the trunk leans and the thorax turns further
   than the pelvis, and thorax and pelvis sensors swapped in the sensor map read the inverse
   (the inverse relative rotation: every angle's sign turned), which the warning names.
5. **Chair** (optional segment of a ``trunk_lean`` joint): its vertical from the rest; its
   heading is tied to the thorax's at the rest, so the trunk's lean is measured from the rest
   posture about the thorax's own flexion axis, relative to the chair.

The thresholds were set on the five trials of the trunk data set (``bench/real_trunk.py``, the
tuning set; docs/kinematics.md). The segment headings are stored as one anchor per joint at the
rest (``centres[joint]``, the
store :func:`motionlab.segments.segment_orientations` reads for headings fitted at calibration).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.errors import InputError
from motionlab.fusion.detect import steady_mask
from motionlab.kinematics.joint_types import joint_type
from motionlab.protocol import Protocol
from motionlab.results import (
    AxisMeasurement,
    CentreHeading,
    JointGrades,
    SegmentCalibration,
    SegmentQuality,
    SegmentRecord,
    TrunkMovement,
)
from motionlab.segments import grades as grading
from motionlab.segments import heading
from motionlab.segments.sensors import sensor_quats, streams_of
from motionlab.segments.steps import SHORTEST_POSE_S, TRUNK_MOVEMENT_S, TRUNK_MOVING_DEG_S
from motionlab.session import Session
from motionlab.timebase import interp_columns

METHOD = "trunk"
REST_MIN_S = SHORTEST_POSE_S
REST_MAX_S = 5.0  # a rest is grown up to this long
REST_MAX_DEG_S = 20.0  # the stillest second turning faster than this (mean per sensor): no rest
REST_SLOW_DEG_S = 15.0  # a rest turning faster than this gives every angle ``weak``
REST_GROW = 1.5  # the rest grows while the 0.2 s speed stays within this × the stillest second's
STILL_DEG_S = 1.0  # a rest this still (mean deg/s) shows the gyroscope biases
#: a still stretch turned this much less (deg, about the vertical) from the trunk movement than
#: the stillest one is the rest (:func:`find_rest`): the harsh simulated preset's 2 % scale and
#: 1° misalignment carried 6-8° of the two sensors' relative heading through a 93° turn
REST_TURN_DEG = 45.0
MOVING_DEG_S = 5.0  # the thorax turning faster than this relative to the pelvis is moving
MOVEMENT_MIN_S = TRUNK_MOVEMENT_S  # the least trunk movement (s) that can give the axes
AXIS_RATIO_MIN = 1.5  # the flexion axis's one-sidedness over the other axis's
SIGN_RATIO_MIN = 1.3  # the thorax's excursion one way / the other, about the flexion axis
# the thorax's larger excursion about the flexion axis (deg) for its sign to count: a seated
# person's sway and the lean of a wheelchair's turn reach 5-6° (Aag/pivot_hs's first 5 s: 1° /
# 6°, one-sided 6.2×, took the backward lean for flexion: r −0.94, graded determined); the
# trials' bends reach 12-52°
BEND_MIN_DEG = 10.0
HEADING_RHO_MIN = 0.5  # share of the horizontal rates the heading fit explains
#: below this correlation of the lumbar flexion with the thorax's lean about the flexion axis
#: over the movement the spine extended as the trunk leaned forward, as sensors swapped in the
#: map read (:func:`_lean_coupling`): the five real trials as recorded and cut
#: (``bench/trunk_cuts.py``) +0.10 to +0.92, simulated seated sessions +0.89 to +0.96; swapped
#: −0.80 to −0.51 where the flexion axis was otherwise clear (three real, every simulated one)
LEAN_COUPLING_MIN = -0.3
#: below this correlation of the thorax's rate about its vertical relative to the pelvis with
#: its own rate about it the pelvis turned further than the thorax, as sensors swapped in the
#: map read (:func:`_twist_coupling`): the five real trials as recorded +0.43 to +0.72, cut
#: +0.21 or more, simulated seated sessions +0.90 to +0.98; swapped −0.14 to −0.49 (real),
#: −0.86 to −0.96 (simulated, where the lean alone missed some: −0.24)
TWIST_COUPLING_MIN = -0.1
#: deg/s: the least RMS rate of the thorax about its vertical relative to the pelvis for the twist
#: to tell (a trunk that only bends twists by the crosstalk of its axes; the real trials and
#: their cuts 13-42°/s)
TWIST_MIN_DEG_S = 10.0
AXIS_KERNEL_DEG = 10.0  # width of the vote for the flexion and lateral-bending axes


def applies(protocol: Protocol) -> bool:
    """Whether ``protocol`` is calibrated from the trunk's movement (a functional step with
    ``axis_method: trunk``)."""
    return any(s.axis_method == METHOD for s in protocol.calibration)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def find_rest(
    t: np.ndarray, speed: np.ndarray, turned: np.ndarray | None = None
) -> tuple[int, int, float]:
    """``(start, stop, mean speed deg/s)`` of the stillest stretch of at least
    :data:`REST_MIN_S` (indices into ``t``; ``speed`` deg/s, the mean over the sensors).

    ``turned`` (deg per sample of ``t``, optional): how far the body turns about the vertical
    between a rest starting there and the trunk movement (:func:`_turn_to_movement`). A rest
    is the axial rotation's zero and ties the two headings, and an uncalibrated gyroscope's
    scale and misalignment carry a few percent of a whole-body turn into their relative
    heading; so among the stretches still enough to grow into the stillest one's rest (within
    :data:`REST_GROW` of it, or 2°/s) and not moving (under
    :data:`~motionlab.segments.steps.TRUNK_MOVING_DEG_S`), the stillest of those turned least
    is taken when it is turned :data:`REST_TURN_DEG` less.
    """
    fs = 1.0 / float(np.median(np.diff(t)))
    n = max(int(round(REST_MIN_S * fs)), 2)
    if len(t) < n:
        raise InputError(
            f"the recording is {t[-1] - t[0]:.1f} s long, shorter than a rest of {REST_MIN_S:g} s",
            remedy="record a rest of a second or more and the trunk movements",
        )
    mean = np.convolve(speed, np.ones(n) / n, mode="valid")  # window k .. k+n
    k = int(np.argmin(mean))
    limit = max(REST_GROW * float(mean[k]), float(mean[k]) + 2.0)
    if turned is not None:
        cost = np.asarray(turned, float)[: len(mean)]
        still = np.flatnonzero(mean <= min(limit, TRUNK_MOVING_DEG_S))
        if len(still) and np.isfinite(cost[still]).all():  # the stillest of those turned least
            least = still[cost[still] <= cost[still].min() + REST_TURN_DEG / 2]
            best = int(least[np.argmin(mean[least])])
            if cost[k] - cost[best] > REST_TURN_DEG:
                k = best
    level = float(mean[k])
    short = uniform_filter1d(speed, max(int(round(0.2 * fs)), 1), mode="nearest")
    limit = max(REST_GROW * level, level + 2.0)
    a, b = k, k + n
    longest = int(REST_MAX_S * fs)
    while b - a < longest and (a > 0 or b < len(t)):
        left = short[a - 1] if a > 0 else np.inf
        right = short[b] if b < len(t) else np.inf
        if min(left, right) > limit:
            break
        if left <= right:
            a -= 1
        else:
            b += 1
    return a, b, level


def _turn_to_movement(t: np.ndarray, vertical_rate: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Per sample (deg): the mean, over the trunk's ``moving`` samples, of how far the pelvis
    turns about the vertical (the path, ∫|rate| dt; ``vertical_rate`` rad/s about earth up)
    between that sample and them. Zeros without movement."""
    rate = np.abs(np.nan_to_num(np.asarray(vertical_rate, float)[1:]))  # a gap turns nothing
    path = np.degrees(np.concatenate([[0.0], np.cumsum(rate * np.diff(t))]))
    at = path[moving]  # non-decreasing
    if not len(at):
        return np.zeros(len(t))
    before = np.searchsorted(at, path, side="right")
    total = np.concatenate([[0.0], np.cumsum(at)])
    below = path * before - total[before]
    above = (total[-1] - total[before]) - path * (len(at) - before)
    return (below + above) / len(at)


def _on(t: np.ndarray, ts: np.ndarray, x: np.ndarray) -> np.ndarray:
    return x if len(ts) == len(t) and np.array_equal(ts, t) else interp_columns(t, ts, x)


def _horizontal_axes(w_rel: np.ndarray, up: np.ndarray, moving: np.ndarray):
    """The two perpendicular horizontal axes (perpendicular to ``up``) about which the relative
    angular velocity ``w_rel`` (N, 3) turns most often over the ``moving`` samples, and the mean
    squared rate about each (rad²/s²), largest first.

    Each sample votes with its horizontal rate's magnitude for its direction, an axis and its
    perpendicular alike (the direction's angle times four), smoothed by a kernel that falls to
    1/e at :data:`AXIS_KERNEL_DEG`; the pair is the densest direction (a grid of 0.5°, then
    mean-shift steps). Flexion and lateral bending both vote for the same pair, while movement
    about other axes (standing up, turning, everyday movement) spreads its votes thin. The
    principal axes of the rate's covariance, used before, were pulled by that movement: 8.6°
    median error against the simulator's thorax axis over the recording, against 0.3° this way
    (``lumbar_seated``, seeds 0-9).
    """
    p = np.eye(3) - np.outer(up, up)
    e1 = _unit(p @ np.eye(3)[int(np.argmin(np.abs(up)))])
    e2 = np.cross(up, e1)
    w = w_rel[moving]
    w = w[np.isfinite(w).all(axis=1)]
    x, y = w @ e1, w @ e2
    theta4 = 4.0 * np.arctan2(y, x)
    weight = np.hypot(x, y)
    kappa = 1.0 / (1.0 - np.cos(np.radians(4.0 * AXIS_KERNEL_DEG)))
    bins = np.radians(np.arange(0.0, 360.0, 2.0))  # axis directions 0.5° apart
    votes = np.bincount(np.round(np.mod(theta4, 2 * np.pi) / bins[1]).astype(int) % len(bins),
                        weights=weight, minlength=len(bins))  # fmt: skip
    kernel = np.exp(kappa * (np.cos(bins[:, None] - bins[None, :]) - 1.0))
    phi4 = float(bins[int(np.argmax(kernel @ votes))])
    for _ in range(20):  # mean shift from the densest bin to the mode of the samples
        k = weight * np.exp(kappa * (np.cos(theta4 - phi4) - 1.0))
        step = float(np.angle(np.sum(k * np.exp(1j * (theta4 - phi4)))))
        phi4 += step
        if abs(step) < 1e-6:
            break
    phi = phi4 / 4.0
    axes = [np.cos(phi) * e1 + np.sin(phi) * e2, -np.sin(phi) * e1 + np.cos(phi) * e2]
    energy = [float(np.mean((w @ a) ** 2)) if len(w) else 0.0 for a in axes]
    order = np.argsort(energy)[::-1]
    return [axes[k] for k in order], [energy[k] for k in order]


def _lean(q: np.ndarray, q_rest: np.ndarray) -> np.ndarray:
    """The sensor's lean since the rest (N, 3) rad, in the sensor frame: the shortest rotation
    that takes the vertical seen at the rest onto the one seen now, as a rotation vector. It is
    the rotation since the rest without its turn about the vertical, so a whole-body turn (or
    sitting down between the trunk movement and a rest at the end) does not count as a lean;
    ``q`` (N, 4) and ``q_rest`` (4,) sensor → earth."""
    ez = np.array([0.0, 0.0, 1.0])
    up_now = rot.rotate(rot.conj(q), ez)
    up_rest = rot.rotate(rot.conj(q_rest), ez)
    c = np.cross(up_now, up_rest)
    s = np.linalg.norm(c, axis=1)
    angle = np.arctan2(s, up_now @ up_rest)
    return c * (angle / np.maximum(s, 1e-12))[:, None]


def _excursions(lean: np.ndarray, axis: np.ndarray) -> tuple[float, float]:
    """How far (deg, 98th percentile) the lean since the rest ``lean`` (N, 3, rad) goes either
    way about ``axis``: ``(positive, negative)``, both ≥ 0."""
    phi = np.degrees(lean @ axis)
    return float(np.percentile(phi, 98)), float(-np.percentile(phi, 2))


def _one_sided(pos: float, neg: float) -> float:
    """How one-sided a movement is: the larger excursion over the smaller (at least 1°)."""
    return max(pos, neg) / max(min(pos, neg), 1.0)


def _flexion_side(lean: np.ndarray, axis: np.ndarray) -> int:
    """Which way about ``axis`` the thorax flexes (+1: its lean since the rest ``lean``, N×3 rad,
    grows about +``axis``; −1: about −``axis``): the side of the longer tail from the thorax's
    median posture (98th and 2nd percentiles against the median). People lean forward further
    than back from where they usually sit; the extremes from the rest say the same only when
    the rest is that posture. A pause held leaning forward (the only rest of a recording that
    starts in movement) made the extremes two-sided and flipped flexion's sign on two of the
    real trials cut so (Danique/trunkmovement_hs: 48° one way, 47° the other from its pause;
    Danique/pivot_hs), while the tails from the median kept it on every cut whose axis was the
    recording's but one (``bench/trunk_cuts.py``)."""
    lo, mid, hi = np.percentile(np.degrees(lean @ axis), [2, 50, 98])
    return 1 if hi - mid >= mid - lo else -1


def _lean_coupling(
    q_rel: np.ndarray, q_rest: np.ndarray, lean: np.ndarray, axis: np.ndarray, moving: np.ndarray
) -> float:
    """Pearson correlation over the ``moving`` samples between the lumbar flexion and the
    thorax's lean, both since the rest and about the thorax sensor's flexion ``axis``: the
    thorax's rotation relative to the pelvis (``q_rel`` (N, 4), thorax sensor → pelvis sensor,
    ``q_rest`` at the rest) and its lean in the world (``lean``, :func:`_lean`). Seated or
    standing, the thorax leans further than the pelvis and the spine flexes as it leans
    (positive); sensors swapped in the map give the inverse relative rotation, a spine that
    extends as the trunk leans (negative). NaN with too few samples or a lean under
    :data:`BEND_MIN_DEG` either way (a sway tells nothing)."""
    bend = rot.to_rotvec(rot.mul(rot.conj(q_rest), q_rel)) @ axis
    tilt = lean @ axis
    ok = moving & np.isfinite(bend) & np.isfinite(tilt)
    if ok.sum() < 10 or np.std(bend[ok]) == 0.0 or max(_excursions(lean[ok], axis)) < BEND_MIN_DEG:
        return float("nan")
    return float(np.corrcoef(bend[ok], tilt[ok])[0, 1])


def _twist_coupling(
    w_rel: np.ndarray, w_thorax: np.ndarray, up: np.ndarray, moving: np.ndarray
) -> float:
    """Pearson correlation over the ``moving`` samples between the thorax's rate relative to the
    pelvis (``w_rel`` (N, 3), rad/s) and its own rate (``w_thorax``), both about its vertical at
    the rest ``up`` (thorax sensor frame). The pelvis, held by the seat or the legs, turns less
    than the thorax about the vertical, and a wheelchair's turn turns both alike: positive.
    Sensors swapped in the map: negative. NaN with too few samples or a twist under
    :data:`TWIST_MIN_DEG_S` (RMS)."""
    rel, own = w_rel @ up, w_thorax @ up
    ok = moving & np.isfinite(rel) & np.isfinite(own)
    if ok.sum() < 10 or np.std(own[ok]) == 0.0:
        return float("nan")
    if np.degrees(np.sqrt(np.mean(rel[ok] ** 2))) < TWIST_MIN_DEG_S:
        return float("nan")
    return float(np.corrcoef(rel[ok], own[ok])[0, 1])


def _frame(y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Mounting matrix (segment → sensor: columns x, y, z in sensor coordinates) with y
    exactly ``y`` and z the part of ``z`` perpendicular to it."""
    y = _unit(y)
    z = _unit(z - (z @ y) * y)
    return np.column_stack([np.cross(y, z), y, z])


def _record(step: str, kind: str, method: str, sensor_axis, segment_axis, rho, verdict):
    return AxisMeasurement(
        step=step,
        kind=kind,
        method=method,
        sensor_axis=np.asarray(sensor_axis, float),
        segment_axis=np.asarray(segment_axis, float),
        rho=float(rho),
        joint_movement=kind == "movement",
        used=True,
        residual_deg=0.0,
        verdict=verdict,
    )


def _segment(
    m: np.ndarray,
    sensor: str,
    records: dict[str, AxisMeasurement],
    messages: list[str],
    method: str = "procrustes",
) -> SegmentRecord:
    return SegmentRecord(
        mounting=rot.from_matrix(m),
        method=method,
        axes=records,
        quality=SegmentQuality(
            ok=not messages,
            messages=messages,
            min_rho=min(r.rho for r in records.values()),
            separation_deg=90.0,
            lm_difference_deg=None,
            hinge_check_deg={},
        ),
        sensor=sensor,
    )


def calibrate(
    session: Session, protocol: Protocol, warnings: list[str] | None = None
) -> SegmentCalibration:
    """Calibration of a trunk protocol (see the module notes); raises :class:`InputError` when
    the recording has no rest or no trunk movement."""
    lumbar = [j for j in protocol.joints.values() if joint_type(j.type).name == "lumbar"]
    if not lumbar:
        raise InputError(
            "a trunk calibration (axis_method: trunk) needs a lumbar joint",
            protocol.path,
            "calibration",
            remedy="add joints: lumbar: {type: lumbar, proximal: pelvis, distal: thorax}",
        )
    joint = lumbar[0]
    p, d = joint.proximal, joint.distal
    leans = [j for j in protocol.joints.values()
             if joint_type(j.type).name == "trunk_lean" and j.proximal == d]  # fmt: skip
    streams = streams_of(session, protocol)
    chairs = [j.distal for j in leans if j.distal in streams]
    segs = [p, d, *chairs]
    quats = sensor_quats(session, protocol, segs)
    t = streams[d][0]
    t = t[(t >= max(streams[s][0][0] for s in segs)) & (t <= min(streams[s][0][-1] for s in segs))]
    acc = {s: _on(t, streams[s][0], streams[s][1]) for s in segs}
    gyr = {s: _on(t, streams[s][0], streams[s][2]) for s in segs}
    q = {s: rot.resample(*quats[s], t) for s in segs}

    # heading of the thorax's fusion onto the pelvis's, from the movement's rates
    w_p = rot.rotate(q[p], gyr[p])
    w_d = rot.rotate(q[d], gyr[d])
    delta = heading.heading_from_rates(w_p, w_d)
    turned = rot.rotate(rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), delta), w_d)
    h_p, h_d = w_p[:, :2], turned[:, :2]
    heading_rho = float(np.sum(h_p * h_d) / max(np.sqrt(np.sum(h_p**2) * np.sum(h_d**2)), 1e-12))
    q_d = heading.apply_heading(q[d], delta)
    q_rel = rot.mul(rot.conj(q[p]), q_d)  # thorax sensor → pelvis sensor
    w_rel = gyr[d] - rot.rotate(rot.conj(q_rel), gyr[p])
    trunk_moving = np.degrees(np.linalg.norm(w_rel, axis=1)) > MOVING_DEG_S

    speed = np.mean([np.degrees(np.linalg.norm(gyr[s], axis=1)) for s in segs], axis=0)
    a, b, level = find_rest(t, speed, _turn_to_movement(t, w_p[:, 2], trunk_moving))
    if level > REST_MAX_DEG_S:
        speed_text = f"{level:.0f}" if level >= REST_MAX_DEG_S + 0.5 else f"{level:.1f}"
        raise InputError(
            f"no rest: the stillest second ({t[a]:.1f}–{t[a] + REST_MIN_S:.1f} s) turns at "
            f"{speed_text}°/s (a rest is under {REST_MAX_DEG_S:g}°/s)",
            protocol.path,
            "calibration",
            remedy="record a second or more sitting or standing still, before, between or "
            "after the trunk movements",
        )
    rest = slice(a, b)
    up = {s: _unit(acc[s][rest].mean(axis=0)) for s in segs}
    rest_rho = {s: float(np.linalg.norm(np.mean([_unit(v) for v in acc[s][rest]], axis=0)))
                for s in segs}  # fmt: skip

    moving = np.ones(len(t), bool)
    moving[rest] = False
    turning = moving & trunk_moving
    moved_s = float(turning.sum() * np.median(np.diff(t)))
    if moving.sum() < 2 or np.degrees(np.sqrt(np.mean(np.sum(w_rel[moving] ** 2, 1)))) < 5.0:
        why = "the thorax hardly turns relative to the pelvis"
    elif moved_s < MOVEMENT_MIN_S:
        why = (
            f"the thorax turns relative to the pelvis for {moved_s:.1f} s besides the rest "
            f"(at least {MOVEMENT_MIN_S:g} s needed)"
        )
    else:
        why = ""
    if why:
        raise InputError(
            f"no trunk movement: {why}",
            protocol.path,
            "calibration",
            remedy="record trunk flexion, lateral bending and rotation besides the rest",
        )
    axes, energy = _horizontal_axes(w_rel, up[d], moving)
    q_rest = rot.mean(q_rel[rest])
    lean = _lean(q[d], rot.mean(q[d][rest]))
    # the flexion axis is the one the thorax turns about most. One-sidedness from the rest
    # gives its sign and the grade, not the axis: it depends on the rest's posture. A rest held
    # leaning (a pause at the end, after wheeling) makes the flexion sway look two-sided and a
    # sideways lean one-sided: chosen by one-sidedness, Danique/pivot_hs cut to keep only its
    # rest at the end took the lateral axis (79° off, its flexion r −0.87 with the optical
    # lateral bending), graded determined (bench/trunk_cuts.py)
    reach = [_excursions(lean, a) for a in axes]
    sided = [_one_sided(*r) for r in reach]
    axis, (pos, neg), sign_ratio = axes[0], reach[0], sided[0]
    ratio = sided[0] / max(sided[1], 1e-9)  # how clearly it is the flexion axis
    # flexion turns the thorax about its −z; its side is the longer tail from the usual posture
    forward = _flexion_side(lean, axis)
    coupling = _lean_coupling(q_rel, q_rest, lean, axis, moving)
    twist = _twist_coupling(w_rel, gyr[d], up[d], moving)
    z_d = -axis if forward > 0 else axis
    m_d = _frame(up[d], z_d)
    z_p = rot.rotate(q_rest, m_d[:, 2])
    m_p = _frame(up[p], z_p)

    steps_named = {s.kind: s.name for s in protocol.calibration}
    rest_name = steps_named.get("static", "rest")
    move_name = steps_named.get("functional", "trunk_movement")
    clear = (
        ratio >= AXIS_RATIO_MIN and sign_ratio >= SIGN_RATIO_MIN and max(pos, neg) >= BEND_MIN_DEG
    )
    axis_verdict = "determined" if clear and (pos >= neg) == (forward > 0) else "weak"
    y, zs = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    segments: dict[str, Any] = {}
    for seg, m in ((d, m_d), (p, m_p)):
        records = {
            rest_name: _record(rest_name, "static", "gravity", up[seg], y, rest_rho[seg],
                               "determined"),
            move_name: _record(move_name, "movement", METHOD, m[:, 2], zs,
                               min(1.0, 1.0 - 1.0 / max(ratio, 1.0)), axis_verdict),
        }  # fmt: skip
        segments[seg] = _segment(m, sensor_for_segment(session, seg), records, [])

    centres: dict[str, CentreHeading] = {}
    t_rest = float(t[rest].mean())
    seg_q = {s: rot.mul(q[s], rot.from_matrix(m)) for s, m in ((p, m_p), (d, m_d))}
    pose_delta = heading.heading_from_pose(seg_q[p][rest], seg_q[d][rest])
    times, deltas = [t_rest], [pose_delta]
    drift = None
    calibrated = _gyros_calibrated(session, (p, d))
    if level <= STILL_DEG_S and not calibrated:  # a still rest shows the biases the fusion left
        drift = _heading_drift(session, {s: sensor_for_segment(session, s) for s in (p, d)},
                               t, q, gyr, rest)  # fmt: skip
    # the headings' drift apart followed, or calibrated away before the fusion
    followed: dict[str, bool] = {joint.name: drift is not None or calibrated}
    if drift is not None:
        step = max(int(round(0.5 / float(np.median(np.diff(t))))), 1)
        times = [float(x) for x in t[::step]]
        deltas = [pose_delta + float(x) for x in drift[::step]]
    centres[joint.name] = CentreHeading(times, deltas, method="trunk rest")
    for lean in leans:  # the trunk's lean: the chair's heading drift followed
        c = lean.distal
        if c not in chairs:
            continue
        horizontal = np.eye(3)[int(np.argmin(np.abs(up[c])))]
        m_c = _frame(up[c], horizontal)
        records = {rest_name: _record(rest_name, "static", "gravity", up[c], y, rest_rho[c],
                                      "determined")}  # fmt: skip
        # y measured, the rest tied to the thorax
        segments[c] = _segment(
            m_c, sensor_for_segment(session, c), records, [], "primary_secondary"
        )
        q_c = rot.mul(q[c], rot.from_matrix(m_c))
        delta_c = heading.heading_from_pose(rot.mul(q[d], rot.from_matrix(m_d))[rest], q_c[rest])
        times_c, deltas_c = [t_rest], [delta_c]
        lean_drift = None
        calibrated = _gyros_calibrated(session, (d, c))
        if level <= STILL_DEG_S and not calibrated:
            labels = {d: sensor_for_segment(session, d), c: sensor_for_segment(session, c)}
            lean_drift = _heading_drift(session, labels, t, q, gyr, rest)
        if lean_drift is not None:
            step = max(int(round(0.5 / float(np.median(np.diff(t))))), 1)
            times_c = [float(x) for x in t[::step]]
            deltas_c = [delta_c + float(x) for x in lean_drift[::step]]
        followed[lean.name] = lean_drift is not None or calibrated
        centres[lean.name] = CentreHeading(times_c, deltas_c, method="trunk rest")

    notes: list[str] = []
    summary = TrunkMovement(
        rest_s=[float(t[a]), float(t[b - 1])],
        rest_speed_deg_s=level,
        axis_ratio=ratio,
        energy_ratio=energy[0] / max(energy[1], 1e-12),
        one_sided=sided,
        excursion_deg=[pos, -neg],
        sign_ratio=sign_ratio,
        heading_deg=float(np.degrees(delta)),
        heading_rho=heading_rho,
        heading_drift_deg=None if drift is None else float(np.degrees(np.ptp(drift))),
        lean_coupling=coupling,
        twist_coupling=twist,
    )
    if axis_verdict != "determined":
        notes.append(f"{d}: {_weak_axis(ratio, pos, neg)}: record a clear forward bend")
    inverse = _inverse(summary)
    if inverse:
        labels = [sensor_for_segment(session, seg) for seg in (d, p)]
        notes.append(
            f"{d} and {p}: {inverse}: are {labels[0]} and {labels[1]} swapped in the sensor map? "
            "(give each the other's segment)"
        )
    steps = {rest_name: [float(t[a]), float(t[b - 1])],
             move_name: [float(t[moving][0]), float(t[moving][-1])]}  # fmt: skip
    result = SegmentCalibration(
        protocol.name,
        steps=steps,
        segments=segments,
        hinges={},
        centres=centres,
        warnings=notes,
        ok=True,
    )
    graded = grading.grade_joints(protocol, result)
    graded.update(trunk_grades(joint, leans, summary, axis_verdict, followed))
    result.grades = {name: replace(g, trunk=summary) for name, g in graded.items()}
    if warnings is not None:
        warnings.extend(notes)
    return result


def _heading_drift(session, labels: dict[str, str], t, q, gyr, rest: slice) -> np.ndarray | None:
    """The heading (rad, per sample, 0 at the rest) that turns the distal sensor's 6-D earth
    frame back onto the proximal's as their headings drift apart: each sensor's gyroscope
    over the steady samples of a still rest (:func:`motionlab.fusion.detect.steady_mask`: a
    back's sway is movement, not bias; none steady, no drift), ``gyr`` being already less the
    bias its fusion removed (:func:`motionlab.segments.sensors.corrected_gyr`), integrated
    about the earth vertical through its orientation (``labels``: proximal then distal segment
    → sensor).
    ``None`` unless both fusions are 6-D and report their gyroscope bias (a vendor's or a 9-D
    orientation has its own heading reference)."""
    drifts = []
    hz = 1.0 / float(np.median(np.diff(t)))
    for seg, label in labels.items():
        fused = session.results.fusion.get(label)
        if fused is None or fused.gyro_bias is None or fused.magnetometer:
            return None
        still = np.zeros(len(t), bool)
        still[rest] = True
        steady = steady_mask(gyr[seg], hz, still)[rest]
        if not steady.any():  # a person's sway: the rest shows no bias
            drifts.append(np.zeros(len(t)))
            continue
        left = gyr[seg][rest][steady].mean(axis=0)  # the rate is less the fusion's bias
        rate = rot.rotate(q[seg], np.broadcast_to(left, (len(t), 3)))[:, 2]
        e = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
        drifts.append(e - e[rest].mean())
    return drifts[0] - drifts[1]


def _gyros_calibrated(session: Session, segments: tuple[str, ...]) -> bool:
    """Whether every one of ``segments``' sensors was fused from gyroscope rates a per-serial
    sensor calibration (``motionlab sensorcal``, ``--calibration``) took the bias off: their
    headings then drift apart only by what that calibration missed, whatever the rest. (The
    rest's mean recorded rate, less the bias the fusion removed, would count the calibrated
    bias twice, so such sensors are not followed from the rest.)"""
    for seg in segments:
        fused = session.results.fusion.get(sensor_for_segment(session, seg))
        cal = None if fused is None else fused.sensor_calibration
        if cal is None or "gyr" not in cal.channels:
            return False
    return True


def _weak_axis(ratio: float, pos: float, neg: float) -> str:
    """Why the flexion axis is weak, in words."""
    if max(pos, neg) < BEND_MIN_DEG:
        return (
            f"the thorax bent only {pos:.0f}° / {neg:.0f}° either way from the rest: too little "
            f"to tell a forward bend from leaning back (at least {BEND_MIN_DEG:g}° wanted)"
        )
    if ratio >= AXIS_RATIO_MIN and _one_sided(pos, neg) >= SIGN_RATIO_MIN:
        return (
            f"the flexion axis's sign is not clear from the movement (the thorax went {pos:.0f}° "
            f"/ {neg:.0f}° either way from the rest, but further the other way from its usual "
            "posture: the rest was held leaning)"
        )
    return (
        f"the flexion axis is not clear from the movement (the thorax went {pos:.0f}° / "
        f"{neg:.0f}° either way about it, {ratio:.1f}× as one-sided as about the other axis; "
        f"{SIGN_RATIO_MIN:g}× and {AXIS_RATIO_MIN:g}× wanted)"
    )


def _inverse(summary: TrunkMovement) -> str:
    """What the movement showed of a relative rotation the wrong way round (thorax and pelvis
    sensors swapped in the map, :data:`LEAN_COUPLING_MIN`, :data:`TWIST_COUPLING_MIN`), in
    words; empty when it showed nothing of the kind."""
    lean, twist = summary.lean_coupling, summary.twist_coupling
    said = []
    if lean is not None and lean < LEAN_COUPLING_MIN:
        said.append(
            f"the lumbar spine extended as the thorax leaned forward (r {lean:+.2f} between "
            "them over the movement, where a spine flexes as the trunk leans)"
        )
    if twist is not None and twist < TWIST_COUPLING_MIN:
        said.append(
            f"the pelvis turned further than the thorax about the vertical (r {twist:+.2f} "
            "between the trunk's twist and the thorax's turning, where the thorax turns further)"
        )
    return ", and ".join(said)


def trunk_grades(
    joint, leans, summary: TrunkMovement, axis_verdict: str, followed: dict[str, bool]
) -> dict[str, JointGrades]:
    """Grades of the lumbar joint and of the trunk's lean (``leans``: ``trunk_lean`` joints)
    from what the movement determined; the lumbar axial rotation and a lean are ``weak`` unless
    the headings' drift apart was followed (``followed``: by joint, a still rest with 6-D
    fusions, or gyroscopes calibrated before the fusion); every angle ``weak`` when the rest
    turns faster than :data:`REST_SLOW_DEG_S`."""
    pos, neg = summary.excursion_deg[0], -summary.excursion_deg[1]
    why_axis = "" if axis_verdict == "determined" else _weak_axis(summary.axis_ratio, pos, neg)
    speed = summary.rest_speed_deg_s
    cause = (  # the drift is followed from a still rest's gyroscopes (6-D fusions)
        f"the rest turned at {speed:.1f}°/s, not still (under {STILL_DEG_S:g}°/s)"
        if speed > STILL_DEG_S
        else "the orientations report no gyroscope bias (a vendor's or a 9-D fusion)"
    )
    rot_grade, why_rot = "determined", ""
    if summary.heading_rho < HEADING_RHO_MIN:
        rot_grade = "weak"
        why_rot = (
            f"the sensors' headings agree only {summary.heading_rho:.2f} over the movement "
            "(the pelvis hardly moved with the thorax)"
        )
    elif not followed.get(joint.name, False):
        rot_grade = "weak"
        why_rot = (
            f"{cause}, so the pelvis's and the thorax's headings are tied at the rest only and "
            "may drift apart by their gyroscopes' biases (0.2-0.3°/s on a real seated trial): "
            "record a still second with the 6-D fusion, or calibrate the gyroscopes (motionlab "
            "sensorcal, then --calibration)"
        )
    out = {
        joint.name: JointGrades(
            [axis_verdict, axis_verdict, rot_grade], [why_axis, why_axis, why_rot]
        )
    }
    for lean in leans:
        grade, why = axis_verdict, why_axis
        if grade == "determined" and not followed.get(lean.name, False):
            grade = "weak"
            why = (
                f"{cause}, so the chair's and the thorax's headings are tied at the rest only "
                "and may drift apart"
            )
        out[lean.name] = JointGrades([grade] * 3, [why] * 3)
    inverse = _inverse(summary)
    if inverse:  # every angle's frames in doubt
        swapped = f"{inverse}: the thorax and pelvis sensors look swapped"
        out = {name: grading.lowered(j, ["weak"] * len(j.grades), swapped)
               for name, j in out.items()}  # fmt: skip
    if summary.rest_speed_deg_s > REST_SLOW_DEG_S:
        slow = (
            f"the rest turns at {summary.rest_speed_deg_s:.1f}°/s (a still rest is under "
            f"{REST_SLOW_DEG_S:g}°/s): the angles' zero and verticals are of a moving posture"
        )
        out = {name: JointGrades(["weak"] * len(g.grades),
                                 [w if w else slow for w in g.reasons])
               for name, g in out.items()}  # fmt: skip
    return out
