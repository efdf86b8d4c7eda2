"""Clinical joint angles from two segment orientations (knee, elbow, lumbar).

Conventions (``../docs/conventions.md`` has the sign table):

- Inputs are segment → ENU earth quaternions, Hamilton, scalar first, shape ``(N, 4)``. Segment
  frames are ISB style: x anterior, y proximal (up along the segment), z to the subject's right,
  for every segment in the standing pose.
- The relative rotation ``q_rel = q_proximal* ⊗ q_distal`` (so ``q_distal = q_proximal ⊗ q_rel``)
  is decomposed intrinsic Z-X-Y, ``R = Rz(a) Rx(b) Ry(c)``: ``a`` about the proximal z
  (flexion), ``b`` about the floating axis (ab/adduction, carrying angle, lateral bending), ``c``
  about the distal y (rotation, pronation, axial rotation). This is the joint coordinate system
  of Grood & Suntay (1983, J Biomech Eng 105:136) for the knee and of Wu et al. (2005,
  J Biomech 38:981, ISB part II) for the elbow; the lumbar angle is thorax relative to pelvis.
- The clinical sign of each angle is ``sign * (a, b, c)`` with the per-joint, per-side sign in
  :data:`SIGNS`: flexion positive for all joints; knee varus (adduction) and internal rotation
  positive on both sides; elbow carrying angle (valgus) and pronation positive on both sides;
  lumbar lateral bending to the right and axial rotation to the left positive.

Angles are in rad inside, in degrees only in :func:`joint_angles` (for tables and CSV).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from motionlab import rotations as rot
from motionlab.errors import InputError

JOINT_ANGLE_NAMES: dict[str, tuple[str, str, str]] = {
    "knee": ("flexion", "adduction", "rotation"),
    "elbow": ("flexion", "carrying", "pronation"),
    "lumbar": ("flexion", "lateral_bending", "axial_rotation"),
}

# Clinical angle = SIGNS[joint][side] * (a, b, c) of R = Rz(a) Rx(b) Ry(c).
# - a > 0 turns the distal segment's far end (along -y) forward: elbow flexion, knee extension;
#   for the lumbar joint it turns the thorax's top (+y) backward: extension.
# - b > 0 turns the far end (-y) toward -z (left): medial on the right side (knee varus,
#   elbow varus), lateral on the left side; it tilts the thorax's top to the right.
# - c > 0 turns the distal anterior axis toward -z (left): internal rotation / pronation on the
#   right side, external on the left; the thorax turning to the left.
SIGNS: dict[str, dict[str, np.ndarray]] = {
    "knee": {"r": np.array([-1.0, 1.0, 1.0]), "l": np.array([-1.0, -1.0, -1.0])},
    "elbow": {"r": np.array([1.0, -1.0, 1.0]), "l": np.array([1.0, 1.0, -1.0])},
    "lumbar": {"": np.array([-1.0, 1.0, 1.0])},
}


def _signs(joint_type: str, side: str) -> np.ndarray:
    if joint_type not in SIGNS:
        raise InputError(
            f"unknown joint type {joint_type!r}",
            where="joint type",
            remedy=f"use one of {', '.join(SIGNS)}",
        )
    if joint_type == "lumbar":
        return SIGNS["lumbar"][""]
    side = {"left": "l", "right": "r"}.get(side, side)
    if side not in ("l", "r"):
        raise InputError(
            f"a {joint_type} joint needs side 'l' or 'r', got {side!r}",
            where="joint side",
            remedy="set side: l or side: r in the protocol's joint",
        )
    return SIGNS[joint_type][side]


def relative(q_proximal: np.ndarray, q_distal: np.ndarray) -> np.ndarray:
    """Relative rotation ``q_proximal* ⊗ q_distal`` (distal segment in proximal coordinates)."""
    return rot.mul(rot.conj(q_proximal), q_distal)


def decompose(
    q_proximal: np.ndarray, q_distal: np.ndarray, joint_type: str, side: str = ""
) -> np.ndarray:
    """Clinical joint angles (N, 3) in rad from segment → earth quaternions (N, 4).

    Columns follow :data:`JOINT_ANGLE_NAMES` ``[joint_type]``; signs as in the module docstring.
    ``side`` is ``'l'`` or ``'r'`` (ignored for ``'lumbar'``). A sample where either
    orientation is missing (NaN, or a zero quaternion) gives a row of NaN.
    """
    signs = _signs(joint_type, side)
    q_rel = np.atleast_2d(relative(q_proximal, q_distal))
    bad = ~np.isfinite(q_rel).all(axis=1) | ~(np.linalg.norm(q_rel, axis=1) > 0)
    if bad.any():
        q_rel = np.where(bad[:, None], rot.IDENTITY, q_rel)
    abc = rot.to_scipy(q_rel).as_euler("ZXY") * signs
    abc[bad] = np.nan
    return abc


def compose(angles: np.ndarray, joint_type: str, side: str = "") -> np.ndarray:
    """Relative rotation (N, 4), ``q_distal = q_proximal ⊗ q_rel``; inverse of :func:`decompose`.

    ``angles`` (N, 3) are clinical angles in rad (columns of :data:`JOINT_ANGLE_NAMES`).
    The result is sign-continuous.
    """
    signs = _signs(joint_type, side)
    abc = np.atleast_2d(np.asarray(angles, dtype=float)) * signs
    q = rot.from_scipy(Rotation.from_euler("ZXY", abc))
    return rot.make_continuous(q)


def column_name(joint_type: str, side: str, angle: str) -> str:
    """CSV column of one angle: ``knee_r_flexion_deg``; the lumbar joint has no side."""
    if joint_type == "lumbar" or not side:
        return f"{joint_type}_{angle}_deg"
    return f"{joint_type}_{side}_{angle}_deg"


def joint_angles(q_proximal: np.ndarray, q_distal: np.ndarray, joint) -> dict[str, np.ndarray]:
    """Angles of a :class:`motionlab.protocol.Joint` as ``{column_name: degrees (N,)}``."""
    angles = np.degrees(decompose(q_proximal, q_distal, joint.type, joint.side))
    return {
        column_name(joint.type, joint.side, name): angles[:, i]
        for i, name in enumerate(JOINT_ANGLE_NAMES[joint.type])
    }
