"""Segment and sensor poses from the channel matrix, and their exact time derivatives.

Poses are segment → ENU earth quaternions (Hamilton, scalar first) and segment-origin positions
(m). Knee, elbow and lumbar rotations come from :func:`motionlab.kinematics.joint_angles.compose`
so the simulated truth uses the same joint conventions as the analysis; hip, shoulder and ankle
use intrinsic Z-X-Y rotations ``Rz(flexion) Rx(±adduction) Ry(±internal rotation)`` (+ right,
− left). At heading 0 the subject faces east: segment x → east, y → up, z (right) → south.

Derivatives are taken of the analytic motion, not of sampled series: each quantity is evaluated
at ``t + k h`` (k = −4…4, h = 2⁻⁹ s) and combined with 8th-order central difference weights
(Fornberg 1988, Math Comp 51:699), which is exact to ~1e-9 for these band-limited motions.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from motionlab import rotations as rot
from motionlab.kinematics.joint_angles import compose
from motionlab.kinematics.segment_types import kind_side
from motionlab.simulate.body import SEGMENTS, Body
from motionlab.simulate.motion import CH, group

Q_BASE = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)  # body → ENU at heading 0
_Z, _X, _Y = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]

STEP = 2.0**-9
OFFSETS = np.arange(-4, 5)
D1 = np.array([1 / 280, -4 / 105, 1 / 5, -4 / 5, 0.0, 4 / 5, -1 / 5, 4 / 105, -1 / 280])
D2 = np.array([-1 / 560, 8 / 315, -1 / 5, 8 / 5, -205 / 72, 8 / 5, -1 / 5, 8 / 315, -1 / 560])
#: instants per evaluation in :func:`derivatives_many` (9 stencil points each: ≈ 290 MB of
#: channels per chunk, a 20-minute recording at 100 Hz in one)
CHUNK = 2**17


def zxy(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Quaternion of the intrinsic rotation ``Rz(a) Rx(b) Ry(c)`` (angles in rad, (N,))."""
    return rot.mul(
        rot.mul(rot.from_axis_angle(_Z, a), rot.from_axis_angle(_X, b)),
        rot.from_axis_angle(_Y, c),
    )


def joint_rotation(grp: str, ch: np.ndarray) -> np.ndarray:
    """Rotation of a child segment in its parent's frame for channel group ``grp``."""
    if grp == "lumbar":
        return compose(ch[:, group("lumbar")], "lumbar")
    if grp == "lumbar_half":
        return compose(0.5 * ch[:, group("lumbar")], "lumbar")
    kind, side = kind_side(grp)
    angles = ch[:, group(grp)]
    if kind in ("knee", "elbow"):
        return compose(angles, kind, side)
    s = -1.0 if side == "l" else 1.0
    return zxy(angles[:, 0], s * angles[:, 1], s * angles[:, 2])


def segment_poses(
    body: Body, ch: np.ndarray, segments: list[str] | None = None
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{segment: (q (N,4), origin (N,3))}`` for ``segments`` (default all) and their parents."""
    wanted = set()
    for seg in segments if segments is not None else SEGMENTS:
        wanted.update(body.chain(seg))
    heading = rot.from_axis_angle(_Z, ch[:, CH["heading"]])
    q_root = rot.mul(
        rot.mul(heading, Q_BASE), zxy(*(ch[:, CH[k]] for k in ("tilt_z", "tilt_x", "rot_y")))
    )
    poses = {"pelvis": (q_root, ch[:, [CH["root_x"], CH["root_y"], CH["root_z"]]])}
    for seg in SEGMENTS:  # parents come first
        if seg == "pelvis" or seg not in wanted:
            continue
        parent, grp, offset = body.parent(seg)
        q_par, p_par = poses[parent]
        poses[seg] = (rot.mul(q_par, joint_rotation(grp, ch)), p_par + rot.rotate(q_par, offset))
    return {k: v for k, v in poses.items() if segments is None or k in segments}


def derivatives(
    pose: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pose, body angular velocity and earth-frame acceleration of a moving frame.

    ``pose(t)`` returns ``(q (N,4), p (N,3))``. Returns ``q`` (sign-continuous), ``p``,
    ``omega`` (N,3, rad/s, in the moving frame: ``2 vec(q* ⊗ q̇)``) and ``a`` (N,3, m/s², earth).
    """
    (out,) = derivatives_many([pose], t)
    return out


def derivatives_many(
    poses: list[Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]], t: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`derivatives` of several frames at the same instants ``t``.

    The poses are evaluated at :data:`CHUNK` instants at a time (each at its 9 stencil points),
    every frame within a chunk before the next chunk, so that frames sharing a computation (the
    segment poses cached by ``signals._poses``) share it chunk by chunk, and the memory held is
    that of one chunk whatever the length of ``t``. Every number depends on its own instant only,
    so the result is the same for any chunk size; the sign continuity of ``q`` is made over the
    whole of ``t`` at the end.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    parts: list[list[tuple[np.ndarray, ...]]] = [[] for _ in poses]
    for a in range(0, max(n, 1), CHUNK):
        tc = t[a : a + CHUNK]
        tt = (tc[:, None] + STEP * OFFSETS).ravel()
        for pose, part in zip(poses, parts, strict=True):
            q, p = pose(tt)
            q = q.reshape(len(tc), len(OFFSETS), 4)
            p = p.reshape(len(tc), len(OFFSETS), 3)
            centre = q[:, 4:5]
            q = q * np.where(np.sum(q * centre, axis=-1, keepdims=True) < 0, -1.0, 1.0)
            qdot = np.einsum("k,nkj->nj", D1, q) / STEP
            acc = np.einsum("k,nkj->nj", D2, p) / STEP**2
            part.append((q[:, 4], p[:, 4], qdot, acc))
    out = []
    for part in parts:
        cols = zip(*part, strict=True)
        q4, p4, qdot, acc = (np.concatenate(x) if len(part) > 1 else x[0] for x in cols)
        q0 = rot.make_continuous(q4)
        qdot = qdot * np.sign(np.sum(q0 * q4, axis=-1))[:, None]
        omega = 2.0 * rot.mul(rot.conj(q0), qdot)[:, 1:]
        out.append((q0, p4, omega, acc))
    return out
