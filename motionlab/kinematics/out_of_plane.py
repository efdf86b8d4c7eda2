"""Out-of-plane metrics: cross-talk, the lumbar axis-angle offset, trunk compensation, knee thrust.

Conventions: angle tables hold degrees (columns as :func:`~motionlab.kinematics.joint_types.
angle_columns`); orientations are segment → ENU earth quaternions ``(N, 4)``, scalar first; time in
s; index windows are ``slice`` objects into the table's time base.

- **Cross-talk** (Ricci 2015 §6.3, Fig. 6.9): during a single-plane movement, the range of the two
  off-axis angles, in degrees and as a percentage of the on-axis range, and its change with the
  calibration against the protocol's nominal sensor placement (Ricci: −39 % to −70 %).
- **Axis-angle out-of-plane offset** (To 2012 §8.2, Fig. 8-15): the angle between the proximal
  and distal segments' x, y and z axes, ``acos(R_rel[k, k])``, as a change from the standing
  reference; for a movement about one axis the two perpendicular axes turn by the same angle, so
  their difference is out-of-plane motion. Peak and mean of its size and the share of the movement
  above the protocol's ``out_of_plane_offset_deg``.
- **Trunk compensation** (Liu 2010 §3.2, §10): thorax orientation relative to the neutral posture
  held before the task, decomposed like the lumbar angles (forward lean, lean to the right, twist
  to the left), with peaks and time above the protocol's ``trunk_compensation_deg``.
- **Knee thrust in gait stance**: per stride, the rise of the adduction (varus) angle from heel
  strike to its maximum during weight acceptance (varus thrust: the varus that appears "as the
  limb accepts weight", Chang et al. 2004, Arthritis Rheum 50:3897; :func:`weight_acceptance`)
  and the range of rotation over stance, with the share of strides above ``varus_thrust_deg``.
  The adduction later in stance is not thrust: a healthy knee's adduction rises with its flexion
  before toe-off (the simulator's knee by 4-6° over the whole stance against 3-4° in weight
  acceptance, seeds 0-2; on the real 16-IMU walk the whole stance gave 11-14°, weight acceptance
  4-12°, its knees' ab/adduction `not determined`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.kinematics.cycles import Cycles
from motionlab.kinematics.joint_angles import decompose
from motionlab.kinematics.joint_types import (
    JOINT_TYPES,
    angle_columns,
    angle_names,
    joint_sequence,
    names_for,
)
from motionlab.results import (
    CrossTalk,
    OffAxisRange,
    OutOfPlaneOffset,
    StanceMetrics,
    TrunkAngleStats,
    TrunkCompensation,
)

_LUMBAR = JOINT_TYPES["lumbar"]
#: lumbar angle index → segment axis index (0 x, 1 y, 2 z) it turns about
PLANE_AXIS = {i: "XYZ".index(c) for i, c in enumerate(_LUMBAR.sequence)}
TRUNK_ANGLES = names_for("lumbar")
NEUTRAL_S = 1.0


def plane_index(joint: Any, plane: str) -> int | None:
    """Index (0-2) of a plane given by angle name (``flexion``) or axis letter (``z``, ``-z``).

    ``joint`` is a :class:`~motionlab.protocol.Joint` (its sequence), or the name of a type
    with a standard sequence (``"lumbar"``).
    """
    if isinstance(joint, str):
        names, sequence = names_for(joint), JOINT_TYPES[joint].sequence
    else:
        names, sequence = angle_names(joint), joint_sequence(joint)
    if plane in names:
        return names.index(plane)
    letter = plane.strip().lstrip("+-").upper()
    return sequence.index(letter) if len(letter) == 1 and letter in sequence else None


def cross_talk(
    angles: dict[str, np.ndarray],
    nominal: dict[str, np.ndarray] | None,
    joint,
    on_axis: int,
    window: slice,
) -> CrossTalk:
    """Off-axis ranges during a single-plane movement of ``joint``, calibrated vs nominal.

    ``on_axis`` is the index of the moving plane; ``nominal`` the angle table computed with the
    protocol's nominal mountings (``None``: no comparison).
    """
    names = [name for name, _ in angle_columns(joint)]
    cols = [col for _, col in angle_columns(joint)]

    def rom(table: dict[str, np.ndarray], col: str) -> float:
        v = np.asarray(table[col][window], float)
        return float(np.nanmax(v) - np.nanmin(v)) if np.isfinite(v).any() else float("nan")

    on = rom(angles, cols[on_axis])
    off_axis = {}
    for i, (name, col) in enumerate(zip(names, cols, strict=True)):
        if i == on_axis:
            continue
        off = rom(angles, col)
        entry = OffAxisRange(off, 100.0 * off / on if on > 0 else float("nan"))
        if nominal is not None:
            before = rom(nominal, col)
            change = 100.0 * (off - before) / before if before > 0 else float("nan")
            entry = replace(entry, nominal_rom_deg=before, change_pct=change)
        off_axis[name] = entry
    return CrossTalk(names[on_axis], on, off_axis)


def axis_angles(q_proximal: np.ndarray, q_distal: np.ndarray) -> np.ndarray:
    """(N, 3) angles (deg) between the segments' x, y and z axes, ``acos(R_rel[k, k])``."""
    r = rot.to_matrix(rot.mul(rot.conj(q_proximal), q_distal))
    diag = np.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    return np.degrees(np.arccos(np.clip(diag, -1.0, 1.0)))


def out_of_plane_offset(
    axis_deg: np.ndarray,
    reference: np.ndarray,
    plane: int,
    window: slice,
    cycles: Cycles,
    threshold_deg: float,
) -> OutOfPlaneOffset:
    """To's out-of-plane offset during a movement in ``plane`` (index of the lumbar angle).

    ``axis_deg`` is :func:`axis_angles` over the table, ``reference`` its value (3,) in the
    standing pose. The statistics cover the span of the repetitions (the block without them).
    """
    rotation_axis = PLANE_AXIS[plane]
    p, q = (k for k in range(3) if k != rotation_axis)
    change = axis_deg[window] - reference
    offset = change[:, p] - change[:, q]
    span = slice(int(cycles.start[0]), int(cycles.end[-1]) + 1) if len(cycles) else slice(None)
    size = np.abs(offset[span])
    axes = "xyz"
    per_rep = [
        float(np.max(np.abs(offset[a : b + 1])))
        for a, b in zip(cycles.start, cycles.end, strict=True)
    ]
    return OutOfPlaneOffset(
        axes=[axes[p], axes[q]],
        peak_deg=float(np.nanmax(size)),
        mean_deg=float(np.nanmean(size)),
        above_pct=float(100.0 * np.mean(size > threshold_deg)),
        threshold_deg=float(threshold_deg),
        repetition_peak_deg=np.array(per_rep),
        offset_deg=offset,
    )


def neutral(time: np.ndarray, q: np.ndarray, t_start: float) -> np.ndarray:
    """Mean orientation (4,) over the ``NEUTRAL_S`` seconds before ``t_start`` (or after it)."""
    sel = (time >= t_start - NEUTRAL_S) & (time < t_start)
    if sel.sum() < 3:
        sel = (time >= t_start) & (time < t_start + NEUTRAL_S)
    return rot.mean(q[sel])


def trunk_compensation(
    time: np.ndarray, q_thorax: np.ndarray, window: slice, thresholds: dict[str, float]
) -> TrunkCompensation:
    """Trunk lean and twist (deg) relative to the neutral posture before the task (Liu 2010).

    Angles as the lumbar joint (Z-X-Y of neutral* ⊗ q): ``flexion`` forward lean positive,
    ``lateral_bending`` lean to the right positive, ``axial_rotation`` twist to the left positive.
    """
    q0 = neutral(time, q_thorax, float(time[window][0]))
    q = q_thorax[window]
    ang = np.degrees(decompose(np.broadcast_to(q0, q.shape), q, "lumbar"))
    per_angle = {}
    flagged = False
    for i, name in enumerate(TRUNK_ANGLES):
        v = ang[:, i]
        limit = float(thresholds.get(name, np.inf))
        above = float(100.0 * np.mean(np.abs(v) > limit))
        flagged |= above > 0
        per_angle[name] = TrunkAngleStats(
            max_deg=float(v.max()),
            min_deg=float(v.min()),
            peak_abs_deg=float(np.abs(v).max()),
            above_pct=above,
            threshold_deg=limit,
        )
    return TrunkCompensation(per_angle, bool(flagged), ang)


#: weight acceptance lasts at least this share of stance (loading response: the first 10 % of
#: the gait cycle, about a sixth of stance; Perry & Burnfield, Gait Analysis, 2010)
LOADING_SHARE = 1.0 / 6.0


def weight_acceptance(flexion: np.ndarray) -> int:
    """Samples from heel strike to the end of weight acceptance in one stance (``flexion``, deg,
    heel strike → toe-off): to the knee's flexion peak in the first half of stance (the
    loading-response peak), and at least ``LOADING_SHARE`` of stance (a knee that does not flex
    on loading still accepts the weight then)."""
    n = len(flexion)
    half = flexion[: n // 2 + 1]
    peak = int(np.nanargmax(half)) if np.isfinite(half).any() else 0
    return max(peak, int(round(LOADING_SHARE * (n - 1))), 1)


def stance_metrics(
    adduction: np.ndarray,
    rotation: np.ndarray,
    flexion: np.ndarray,
    strides: Cycles,
    threshold_deg: float,
) -> StanceMetrics:
    """Varus thrust over each stride's weight acceptance and rotation range over its stance
    (heel strike → toe-off); a stride through a sensor's gap has none (NaN) and the means, SDs
    and share above the threshold are of the others.

    ``adduction``, ``rotation`` and ``flexion`` (deg) are the knee's clinical angles over the
    block; ``strides.peak`` holds each stride's toe-off.
    """
    thrust, rot_range = [], []
    for a, b in zip(strides.start, strides.peak, strict=True):
        add = adduction[a : a + weight_acceptance(flexion[a : b + 1]) + 1]
        thrust.append(float(np.max(add) - add[0]))  # NaN: a sensor's gap in the stance
        rot_range.append(float(np.ptp(rotation[a : b + 1])))
    thrust, rot_range = np.array(thrust), np.array(rot_range)

    def stats(x: np.ndarray) -> tuple[float, float]:
        x = x[np.isfinite(x)]  # a stride through a gap gives none (it made the mean NaN)
        if len(x) == 0:
            return float("nan"), float("nan")
        return float(x.mean()), float(x.std(ddof=1)) if len(x) > 1 else 0.0

    t_mean, t_sd = stats(thrust)
    r_mean, r_sd = stats(rot_range)
    return StanceMetrics(
        strides=len(strides),
        varus_thrust_deg=thrust,
        varus_thrust_mean_deg=t_mean,
        varus_thrust_sd_deg=t_sd,
        varus_thrust_above_pct=float(100.0 * np.mean(thrust[np.isfinite(thrust)] > threshold_deg))
        if np.isfinite(thrust).any()
        else float("nan"),
        threshold_deg=float(threshold_deg),
        stance_rotation_range_deg=rot_range,
        stance_rotation_range_mean_deg=r_mean,
        stance_rotation_range_sd_deg=r_sd,
    )
