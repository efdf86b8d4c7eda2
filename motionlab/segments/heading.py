"""Heading alignment of adjacent segments without the magnetometer.

A 6-D orientation estimate has an arbitrary heading per sensor: each sensor's "earth" frame is the
true ENU frame turned about the vertical by an unknown angle. For joint angles, the distal
segment's orientation is turned about the earth vertical by ``δ`` (``q ← q_z(δ) ⊗ q``) so that it
shares the proximal segment's heading. Two estimates of ``δ``:

- static pose: in the reference pose the two segment frames coincide, so ``δ`` maximises
  ``tr(R_prox,kᵀ R_z(δ) R_dist,k)`` summed over the still window (closed form);
- hinge constraint: the joint axis is one line in both segments, so its earth-frame directions
  ``R_prox j_prox`` and ``R_dist j_dist`` must agree; ``δ`` is the 2-D Procrustes angle between
  their horizontal components over a movement (after Laidig et al., Sensors 2022 22:9850).
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot


def heading_from_pose(q_proximal: np.ndarray, q_distal: np.ndarray) -> float:
    """Heading offset δ (rad) making the distal segment frame equal the proximal one on average."""
    b = np.einsum("nij,nkj->ik", rot.to_matrix(q_distal), rot.to_matrix(q_proximal))
    return float(np.arctan2(b[0, 1] - b[1, 0], b[0, 0] + b[1, 1]))


def heading_from_hinge(
    q_proximal: np.ndarray, q_distal: np.ndarray, axis_proximal: np.ndarray, axis_distal: np.ndarray
) -> float:
    """Heading offset δ (rad) aligning the joint axis seen from both segments (segment coords).

    Samples where the axis is near vertical carry little heading information and weigh little.
    """
    a = rot.rotate(q_proximal, np.broadcast_to(axis_proximal, (len(q_proximal), 3)))
    d = rot.rotate(q_distal, np.broadcast_to(axis_distal, (len(q_distal), 3)))
    cross = np.sum(d[:, 0] * a[:, 1] - d[:, 1] * a[:, 0])
    dot = np.sum(d[:, 0] * a[:, 0] + d[:, 1] * a[:, 1])
    return float(np.arctan2(cross, dot))


def apply_heading(q: np.ndarray, delta: float) -> np.ndarray:
    """Orientations turned by ``delta`` (rad) about the earth vertical: ``q_z(δ) ⊗ q``."""
    return rot.mul(rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), delta), q)
