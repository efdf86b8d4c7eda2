"""Joint angles from two segment orientations, for every type of the joint-type table.

Conventions (``../docs/conventions.md`` has the sign table):

- Inputs are segment → ENU earth quaternions, Hamilton, scalar first, shape ``(N, 4)``. Segment
  frames are ISB style: x anterior, y proximal (up along the segment), z to the subject's right,
  for every segment in the standing pose.
- The relative rotation ``q_rel = q_proximal* ⊗ q_distal`` (so ``q_distal = q_proximal ⊗ q_rel``)
  is decomposed with the joint's intrinsic sequence; for knee, elbow and lumbar always Z-X-Y,
  ``R = Rz(a) Rx(b) Ry(c)``: ``a`` about the proximal z (flexion), ``b`` about the floating axis
  (ab/adduction, carrying angle, lateral bending), ``c`` about the distal y (rotation, pronation,
  axial rotation). This is the joint coordinate system of Grood & Suntay (1983, J Biomech Eng
  105:136) for the knee and of Wu et al. (2005, J Biomech 38:981, ISB part II) for the elbow; the
  lumbar angle is thorax relative to pelvis. Generic ``hinge`` and ``ball`` joints: see
  :mod:`motionlab.kinematics.joint_types`.
- The clinical sign of each angle is ``sign * (a, b, c)`` with the per-type, per-side sign of
  :data:`~motionlab.kinematics.joint_types.JOINT_TYPES`: flexion positive for all joints; knee
  varus (adduction) and internal rotation positive on both sides; elbow carrying angle (valgus)
  and pronation positive on both sides; lumbar lateral bending to the right and axial rotation to
  the left positive.

Angles are in rad inside, in degrees only in :func:`joint_angles` (for tables and CSV).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from motionlab import rotations as rot
from motionlab.kinematics.joint_types import (
    JOINT_TYPES,
    angle_columns,
    column_name,
    joint_sequence,
    resolve_sequence,
    signs_for,
)

__all__ = [
    "JOINT_ANGLE_NAMES",
    "column_name",
    "compose",
    "decompose",
    "decompose_joint",
    "joint_angles",
    "relative",
]

#: angle names of the clinical types; a view of :data:`~motionlab.kinematics.joint_types.
#: JOINT_TYPES` kept for callers that index by type (use :func:`angle_names` for a joint)
JOINT_ANGLE_NAMES: dict[str, tuple[str, str, str]] = {
    t.name: t.angle_names for t in JOINT_TYPES.values() if t.clinical and t.angle_names
}


def relative(q_proximal: np.ndarray, q_distal: np.ndarray) -> np.ndarray:
    """Relative rotation ``q_proximal* ⊗ q_distal`` (distal segment in proximal coordinates)."""
    return rot.mul(rot.conj(q_proximal), q_distal)


def decompose(
    q_proximal: np.ndarray,
    q_distal: np.ndarray,
    joint_type: str,
    side: str = "",
    sequence: str | None = None,
    axis: str | None = None,
) -> np.ndarray:
    """Joint angles (N, 3) in rad from segment → earth quaternions (N, 4).

    Columns follow :func:`~motionlab.kinematics.joint_types.names_for`; ``sequence`` is the
    intrinsic Euler sequence (``None``: the type's standard one; a hinge's from its ``axis``);
    signs from the table. ``side`` is ``'l'`` or ``'r'`` (ignored for types without sides). A
    sample where either orientation is missing (NaN, or a zero quaternion) gives a row of NaN.
    """
    seq = resolve_sequence(joint_type, sequence, axis)
    signs = signs_for(joint_type, side, axis)
    q_rel = np.atleast_2d(relative(q_proximal, q_distal))
    bad = ~np.isfinite(q_rel).all(axis=1) | ~(np.linalg.norm(q_rel, axis=1) > 0)
    if bad.any():
        q_rel = np.where(bad[:, None], rot.IDENTITY, q_rel)
    abc = rot.to_scipy(q_rel).as_euler(seq) * signs
    abc[bad] = np.nan
    return abc


def compose(
    angles: np.ndarray,
    joint_type: str,
    side: str = "",
    sequence: str | None = None,
    axis: str | None = None,
) -> np.ndarray:
    """Relative rotation (N, 4), ``q_distal = q_proximal ⊗ q_rel``; inverse of :func:`decompose`.

    ``angles`` (N, 3) are clinical angles in rad, in decomposition order. The result is
    sign-continuous.
    """
    seq = resolve_sequence(joint_type, sequence, axis)
    signs = signs_for(joint_type, side, axis)
    abc = np.atleast_2d(np.asarray(angles, dtype=float)) * signs
    q = rot.from_scipy(Rotation.from_euler(seq, abc))
    return rot.make_continuous(q)


def decompose_joint(q_proximal: np.ndarray, q_distal: np.ndarray, joint: Any) -> np.ndarray:
    """:func:`decompose` (rad, (N, 3)) with the type, side, sequence and axis of a
    :class:`motionlab.protocol.Joint`."""
    return decompose(
        q_proximal,
        q_distal,
        joint.type,
        joint.side,
        joint_sequence(joint),
        getattr(joint, "axis", None),
    )


def joint_angles(q_proximal: np.ndarray, q_distal: np.ndarray, joint: Any) -> dict[str, np.ndarray]:
    """Angles of a :class:`motionlab.protocol.Joint` as ``{column: degrees (N,)}``, columns from
    :func:`~motionlab.kinematics.joint_types.angle_columns`."""
    angles = np.degrees(decompose_joint(q_proximal, q_distal, joint))
    return {col: angles[:, i] for i, (_, col) in enumerate(angle_columns(joint))}
