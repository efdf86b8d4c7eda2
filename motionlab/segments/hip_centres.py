"""The pelvis's medio-lateral axis from the two hip joint centres, fitted from the movement.

With the stand alone the pelvis sensor gives its vertical axis (gravity) and nothing about which
way the pelvis faces; the protocol's placement hint stood in for it, and a pelvis sensor 22–26°
off its hint (simulated walks, seeds 0 and 2) put 1–2.5° into the hip angles: the thigh's
heading is tied to the pelvis's at the stand, so the wrong forward direction cancels while the
pelvis is as upright as in the stand and not while it tilts in walking (``bench/hip_sources.py``).

Each hip joint centre is a point the pelvis and the thigh share, so its specific force seen from
either sensor has the same magnitude at every instant (Seel, Schauer & Raisch 2012, IEEE CCA):
``‖f_p + K(ω_p, ω̇_p) r_p‖ = ‖f_t + K(ω_t, ω̇_t) r_t‖`` with ``K(ω, ω̇) r = ω̇ × r + ω × (ω × r)``
and ``r`` the vector (m) from the sensor to the centre in the sensor frame. Fitted for each hip
(least squares over the moving samples, signals low-passed at ``LOWPASS_HZ``), the two centres
seen from the pelvis sensor give the line between the hips, the pelvis's z (ISB: to the right),
with its sign, whatever the mounting. It is used only when it is plausible: the centres
``HIP_WIDTH_M`` apart (the simulated body 0.175 m, adults 0.15–0.22 m) and the line within
``MAX_TILT_DEG`` of the horizontal in the stand. Measured on simulated walks (``typical``
preset, seeds 0–4): 1.4–7.7° from the true pelvis z, against −26 to +4° for the hint.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt

from motionlab.session import SensorStream, estimate_rate
from motionlab.timebase import interp_columns

LOWPASS_HZ = 6.0
MOVING_RAD_S = 0.35  # a sample counts when either segment turns faster (rad/s)
MIN_SAMPLES = 500
HIP_WIDTH_M = (0.05, 0.40)  # fitted widths were 0.08-0.23 m for a true 0.175 m
MAX_TILT_DEG = 20.0
RHO = 0.8  # weight of the hip-centre axis in the pelvis's frame fit (secondary to gravity)


def _skew(v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) cross-product matrices of (N, 3) vectors."""
    z = np.zeros(len(v))
    return np.stack(
        [
            np.stack([z, -v[:, 2], v[:, 1]], axis=1),
            np.stack([v[:, 2], z, -v[:, 0]], axis=1),
            np.stack([-v[:, 1], v[:, 0], z], axis=1),
        ],
        axis=1,
    )


def hip_line(pelvis: SensorStream, thigh_r: SensorStream, thigh_l: SensorStream):
    """``(line (3,) m, RMS misfit m/s²)``: the vector from the left to the right hip centre in
    the pelvis sensor's frame, or ``None`` when the pelvis moved too little with a thigh.

    The specific force at each hip centre seen from the pelvis sensor comes from the joint-centre
    fit of the clock sync (:func:`motionlab.clocksync.joint_centre_forces`: lever arms and
    accelerometer biases); their difference is ``K(ω, ω̇)(r_R − r_L)``, the biases cancel, and
    the line is its linear least-squares solution over the shared samples.
    """
    from motionlab.clocksync import INPUT_LP_HZ, INPUT_ORDER, joint_centre_forces

    fits = [joint_centre_forces(pelvis, thigh) for thigh in (thigh_r, thigh_l)]
    if any(f is None for f in fits):
        return None
    (t_r, f_r, _), (t_l, f_l, _) = fits
    t, i_r, i_l = np.intersect1d(t_r, t_l, return_indices=True)
    if len(t) < MIN_SAMPLES:
        return None
    diff = f_r[i_r] - f_l[i_l]
    rate = estimate_rate(t)
    gyr = interp_columns(t, pelvis.time, pelvis.gyr)  # as the fit filtered it
    w = sosfiltfilt(butter(INPUT_ORDER, INPUT_LP_HZ, fs=rate, output="sos"), gyr, axis=0)
    dw = np.gradient(w, t, axis=0)
    sw = _skew(w)
    k = _skew(dw) + sw @ sw
    moving = np.linalg.norm(w, axis=1) > MOVING_RAD_S
    if moving.sum() < MIN_SAMPLES:
        return None
    n = int(moving.sum())  # the two fits' pelvis biases differ: a constant term
    a = np.concatenate([k[moving], np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2).reshape(-1, 6)
    b = diff[moving].reshape(-1)
    x = np.linalg.lstsq(a, b, rcond=None)[0]
    return x[:3], float(np.sqrt(np.mean((a @ x - b) ** 2)))


def pelvis_z(
    pelvis: SensorStream, thigh_r: SensorStream, thigh_l: SensorStream, up: np.ndarray
) -> dict[str, Any]:
    """The pelvis's z (to the right) in the pelvis sensor's frame from the two hip centres.

    ``up`` is the pelvis sensor's vertical in the stand (unit, sensor frame). Returns
    ``{"used": bool, "axis": (3,) unit, horizontal in the stand, "width_m", "tilt_deg",
    "misfit_m_s2", "reason"}``.
    """
    out: dict[str, Any] = {"used": False}
    fit = hip_line(pelvis, thigh_r, thigh_l)
    if fit is None:
        return out | {"reason": "the pelvis moved too little with the thighs"}
    line, residual = fit
    width = float(np.linalg.norm(line))
    out |= {"width_m": width, "misfit_m_s2": residual}
    if not HIP_WIDTH_M[0] <= width <= HIP_WIDTH_M[1]:
        return out | {"reason": f"the fitted hip centres are {100 * width:.0f} cm apart"}
    line = line / width
    tilt = float(np.degrees(np.arcsin(np.clip(line @ up, -1.0, 1.0))))
    out["tilt_deg"] = tilt
    if abs(tilt) > MAX_TILT_DEG:
        return out | {"reason": f"the line between the fitted hip centres tilts {tilt:.0f} deg"}
    axis = line - (line @ up) * up
    return out | {"used": True, "axis": axis / np.linalg.norm(axis), "reason": ""}
