"""Pelvis angles relative to the walking direction: tilt, obliquity and rotation.

The pelvis segment frame (ISB: x anterior, y up, z right; :func:`~motionlab.segments` gives it)
is expressed in a *walking frame* ``W``: x horizontal along the walking direction, y up (ENU z),
z to the right. The rotation ``R = W^T R_pelvis`` is decomposed rotation-obliquity-tilt, the
order Baker (2001, Gait Posture 13:1) recommends for the pelvis so that the angles keep their
clinical meaning at large rotations: intrinsic Y-X-Z, ``R = Ry(a) Rx(b) Rz(c)``.

Signs (right-side convention, as Vicon's Plug-in Gait reports the right side):

========================= ==================================== =====
column                    positive means                       value
========================= ==================================== =====
``pelvis_tilt_deg``       anterior tilt (the front goes down)  −c
``pelvis_obliquity_deg``  the right side up                    −b
``pelvis_rotation_deg``   the right side forward (faces left)  +a
========================= ==================================== =====

For the left side (gait profile score) obliquity and rotation change sign
(:func:`side_angles`). The walking direction comes from the pelvis itself
(:func:`walking_heading`): its forward heading averaged over one stride, which removes the
pelvic rotation that swings about it once per stride.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from motionlab import rotations as rot

PELVIS_COLUMNS = ("pelvis_tilt_deg", "pelvis_obliquity_deg", "pelvis_rotation_deg")
_SIGNS = np.array([-1.0, -1.0, 1.0])  # (tilt, obliquity, rotation) from (c, b, a)


def forward_heading(q_pelvis: np.ndarray) -> np.ndarray:
    """(N,) unwrapped heading (rad, ENU, counter-clockwise from east) of the pelvis x axis."""
    x = rot.rotate(np.asarray(q_pelvis, dtype=float), np.array([1.0, 0.0, 0.0]))
    return np.unwrap(np.arctan2(x[:, 1], x[:, 0]))


def walking_heading(q_pelvis: np.ndarray, rate_hz: float, stride_s: float) -> np.ndarray:
    """(N,) walking direction (rad): the pelvis heading averaged over one stride (``stride_s``)."""
    n = max(1, int(round(stride_s * rate_hz)))
    return uniform_filter1d(forward_heading(q_pelvis), n, mode="nearest")


def pelvis_angles(q_pelvis: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(N, 3) tilt, obliquity, rotation (rad, right-side signs, module docstring).

    ``q_pelvis`` (N, 4) pelvis segment → ENU; ``heading`` (N,) walking direction (rad, ENU).
    """
    heading = np.asarray(heading, dtype=float)
    # W → ENU: Rz(heading) then the ISB base (segment y up, z right): x→x, y→ENU z, z→ −ENU y
    base = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)
    q_w = rot.mul(rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), heading), base)
    q_rel = rot.mul(rot.conj(q_w), np.asarray(q_pelvis, dtype=float))
    a, b, c = rot.to_scipy(q_rel).as_euler("YXZ").T
    return np.column_stack([c, b, a]) * _SIGNS


def side_angles(angles: np.ndarray, side: str) -> np.ndarray:
    """Pelvis angles with the signs of ``side`` (``l``: obliquity and rotation negated)."""
    return angles * (np.array([1.0, -1.0, -1.0]) if side == "l" else 1.0)
