"""The hip's flexion axis from the walk: the dominant rotation of the thigh relative to the pelvis.

In the walk protocol the thigh's rotation about its long axis comes from the knee axis fitted
from the walk (:mod:`.movement`), and the thigh's heading from the stand, where its frame is
taken to coincide with the pelvis's (:func:`motionlab.segments.heading_anchors`). An error φ of
the thigh frame about its long axis then turns the hip's relative orientation into
``Ry(−φ) R Ry(φ)``: the hip's flexion is measured about an axis φ off the true one, and
adduction picks up ``sin φ`` of the flexion. On simulated walks the knee axis fitted from gait
is 7–10° off on the right thigh and 1–3° on the left, whatever the mounting, also without
sensor errors (the knee's own small rotation and ab/adduction, with little out-of-plane motion
to fit against; ``bench/hip_sources.py``), which gave hip adduction RMSE up to 4.7°.

Here the hip's flexion axis is measured instead: the relative angular velocity of the thigh in
the pelvis frame (from the heading-aligned segment orientations), low-passed at
``LOWPASS_HZ``, has one dominant axis in gait, the flexion axis (uncentred SVD,
:func:`~motionlab.segments.functional.functional_axis`). Its turn φ about the pelvis's
vertical axis from the pelvis's z is removed from the hip alone (:func:`apply_turn`):
``R ← Ry(φ)ᵀ R Ry(φ)``, which is the same as turning the thigh's frame about its long axis by
φ and tying its heading at the stand again. The knee keeps the knee axis. The stand still defines
zero hip rotation; the pelvis angles do not change.

Used only when the thigh's rotation about its long axis was not measured by a calibration
movement (a functional step, e.g. a straight-leg hip flexion), when the thighs moved enough
(``MIN_SAMPLES`` samples above ``MIN_RATE_RAD_S``), the axis is dominant (ρ ≥ ``MIN_RHO``) and
lies within ``MAX_TURN_DEG`` of the pelvis's z. What it does not remove: an ab/adduction rate
that follows the flexion rate turns the dominant axis too (on a real walk the dominant axis
lay 8° and −5° from the markers' pelvis z, see docs/kinematics.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from motionlab import rotations as rot
from motionlab.dsp import butter, sosfiltfilt
from motionlab.errors import InputError
from motionlab.results import HipAxis
from motionlab.segments.functional import functional_axis

LOWPASS_HZ = 6.0
MIN_RATE_RAD_S = 0.5  # relative angular rate a sample needs to count as hip movement
MIN_SAMPLES = 300
MIN_RHO = 0.8  # simulated walks 0.87-0.90; a pelvis frame far off its true heading gave 0.55-0.68
MAX_TURN_DEG = 30.0
_Y = np.array([0.0, 1.0, 0.0])


def relative_rates(t: np.ndarray, q_proximal: np.ndarray, q_distal: np.ndarray) -> np.ndarray:
    """(N, 3) angular velocity (rad/s) of the distal segment relative to the proximal one, in
    the proximal frame, from orientations on the common time ``t`` (s)."""
    rel = rot.mul(rot.conj(q_proximal), q_distal)
    step = rot.to_rotvec(rot.mul(rel[1:], rot.conj(rel[:-1]))) / np.diff(t)[:, None]
    return np.vstack([step, step[-1:]]) if len(step) else np.zeros((len(t), 3))


def flexion_turn(t: np.ndarray, q_pelvis: np.ndarray, q_thigh: np.ndarray) -> HipAxis:
    """The hip's flexion axis measured from the movement (module docstring).

    ``q_*`` are the heading-aligned segment orientations on the common time ``t`` (s). Returns
    the :class:`~motionlab.results.HipAxis` (``turn_deg`` φ about the pelvis y, from its z to
    the axis; 0 when not used).
    """
    out = HipAxis(used=False, turn_deg=0.0, rho=float("nan"), n_samples=0)
    if len(t) < 30:
        return replace(out, reason="too few samples")
    rate = 1.0 / float(np.median(np.diff(t)))
    w = relative_rates(t, q_pelvis, q_thigh)
    if rate > 2.5 * LOWPASS_HZ:
        w = sosfiltfilt(butter(2, LOWPASS_HZ, fs=rate), w, axis=0)
    moving = w[np.linalg.norm(w, axis=1) >= MIN_RATE_RAD_S]
    out = replace(out, n_samples=len(moving))
    if len(moving) < MIN_SAMPLES:
        return replace(out, reason=f"the hip moved too little ({len(moving)} fast samples)")
    try:
        axis, rho, _ = functional_axis(moving)
    except InputError:
        return replace(out, reason="the hip did not move")
    axis = axis if axis[2] >= 0 else -axis
    turn = float(np.degrees(np.arctan2(axis[0], axis[2])))
    off = float(np.degrees(np.arccos(np.clip(np.hypot(axis[0], axis[2]), 0.0, 1.0))))
    out = replace(out, rho=float(rho), turn_deg=turn, tilt_deg=off)
    if rho < MIN_RHO:
        why = f"no dominant hip axis (rho {rho:.2f}, {MIN_RHO:.2f} needed)"
        return replace(out, turn_deg=0.0, reason=why)
    if abs(turn) > MAX_TURN_DEG:
        why = f"the dominant axis is {turn:.0f} deg from the pelvis z"
        return replace(out, turn_deg=0.0, reason=why)
    return replace(out, used=True, reason="")


def apply_turn(q_proximal: np.ndarray, q_distal: np.ndarray, turn_deg: float) -> np.ndarray:
    """Distal orientations whose relative orientation to ``q_proximal`` is ``Ry(φ)ᵀ R Ry(φ)``
    (φ = ``turn_deg``): the hip measured about its dominant axis (module docstring)."""
    if not turn_deg:
        return q_distal
    r = rot.from_axis_angle(_Y, np.radians(turn_deg))
    rel = rot.mul(rot.conj(q_proximal), q_distal)
    return rot.mul(q_proximal, rot.mul(rot.mul(rot.conj(r), rel), r))
