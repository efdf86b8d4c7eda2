"""Elbow angles from two accelerometers only (after Lee 2012, ch. 5).

Model (Lee §5.1-5.3, restated in motionlab's frames): the upper arm has no heading change (it moves
in a vertical plane) and the elbow has no carrying angle, so the forearm is ``R_U · Rz(n) · Ry(m)``
with flexion ``n`` and pronation ``m`` (the Z-X-Y elbow decomposition with the middle angle zero).
Gravity measured in each segment's frame (calibrated accelerometers, low-passed to remove
movement acceleration) then gives, in closed form instead of Lee's constrained Newton iteration,

- flexion from the forearm's long-axis component: ``v_y cos n − v_x sin n = u_y``;
- pronation from the angle between the remaining components in the forearm's x-z plane;

where ``v`` is "up" in upper-arm and ``u`` in forearm coordinates. Of the two flexion branches the
one inside the elbow's range (−10° … 170°, Lee Tab. 5.2) with pronation within ±90° is kept, and
of two such (or none) the one nearer the previous sample (Lee's warm start).
When an angle is unobservable (Lee's singularities: the forearm, or the elbow axis, vertical) the
last observable value is held ("lock", Lee §5.3.3, threshold 0.05).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import pandas as pd

from motionlab import rotations as rot
from motionlab.binding import sensor_for_segment
from motionlab.dsp import butter, sosfiltfilt
from motionlab.errors import InputError
from motionlab.kinematics.joint_types import angle_columns, signs_for
from motionlab.protocol import Protocol
from motionlab.session import Session, estimate_rate

LOCK = 0.05
FLEX_RANGE = np.radians([-10.0, 170.0])
LOWPASS_HZ = 2.0


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def _hold(x: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """Replace ``bad`` samples by the last good one (the first good one at the start)."""
    s = pd.Series(np.where(bad, np.nan, x))
    return s.ffill().bfill().fillna(0.0).to_numpy()


@numba.njit(cache=True)
def _choose_branch(n: np.ndarray, m: np.ndarray, ok: np.ndarray) -> np.ndarray:
    # per sample: the admissible branch, or of two admissible (or none) the one nearer to the
    # previous sample's choice (Lee's warm start from the previous estimate)
    out = np.zeros(n.shape[0], dtype=np.bool_)
    pn, pm = n[0, 0], m[0, 0]
    for k in range(n.shape[0]):
        if ok[k, 0] != ok[k, 1]:
            pick = 1 if ok[k, 1] else 0
        else:
            d0 = abs(n[k, 0] - pn) + abs(m[k, 0] - pm)
            d1 = abs(n[k, 1] - pn) + abs(m[k, 1] - pm)
            pick = 1 if d1 < d0 else 0
        out[k] = pick == 1
        pn, pm = n[k, pick], m[k, pick]
    return out


def elbow_from_gravity(up_upper: np.ndarray, up_fore: np.ndarray, side: str) -> np.ndarray:
    """Clinical elbow angles (N, 3) in rad from "up" (N, 3) in upper-arm and forearm coordinates.

    Columns: flexion, carrying angle (0 by the model), pronation; signs as
    :mod:`motionlab.kinematics.joint_angles`.
    """
    v = up_upper / np.linalg.norm(up_upper, axis=1, keepdims=True)
    u = up_fore / np.linalg.norm(up_fore, axis=1, keepdims=True)
    amp = np.hypot(v[:, 0], v[:, 1])
    phi = np.arctan2(v[:, 0], v[:, 1])
    acos = np.arccos(np.clip(u[:, 1] / np.maximum(amp, 1e-9), -1.0, 1.0))
    cands = [_wrap(-phi + acos), _wrap(-phi - acos)]
    prons = []
    for n in cands:
        wx = v[:, 0] * np.cos(n) + v[:, 1] * np.sin(n)
        prons.append(_wrap(np.arctan2(u[:, 2], u[:, 0]) - np.arctan2(v[:, 2], wx)))
    ok = [
        (n >= FLEX_RANGE[0]) & (n <= FLEX_RANGE[1]) & (np.abs(m) <= np.pi / 2)
        for n, m in zip(cands, prons, strict=True)
    ]
    second = _choose_branch(np.column_stack(cands), np.column_stack(prons), np.column_stack(ok))
    n = np.where(second, cands[1], cands[0])
    m = np.where(second, prons[1], prons[0])
    flex_lock = amp < LOCK
    wx = v[:, 0] * np.cos(n) + v[:, 1] * np.sin(n)
    pron_lock = flex_lock | (np.hypot(wx, v[:, 2]) < LOCK) | (np.hypot(u[:, 0], u[:, 2]) < LOCK)
    n = _hold(n, flex_lock)
    m = _hold(m, pron_lock)
    signs = signs_for("elbow", side)
    return np.column_stack([signs[0] * n, np.zeros_like(n), signs[2] * m])


def session_elbow_angles(session: Session, protocol: Protocol) -> dict[str, Any]:
    """Accelerometer-only elbow angles (degrees) of every elbow joint of a calibrated session."""
    calibration = session.results.calibration
    cal = calibration.segments if calibration is not None else {}
    elbows = [j for j in protocol.joints.values() if j.type == "elbow"]
    if not elbows:
        raise InputError(
            "the accelerometer-only method is for elbows",
            where=f"protocol {protocol.name}",
            remedy="use method='imu'",
            argument="method",
        )
    out: dict[str, Any] = {}
    for joint in elbows:
        ups = []
        for seg in (joint.proximal, joint.distal):
            label = sensor_for_segment(session, seg)
            if label is None or seg not in cal:
                raise InputError(
                    f"segment '{seg}' has no calibrated sensor",
                    where=f"joint {joint.name}",
                    remedy="run motionlab calibrate first",
                )
            s = session.sensors[label]
            sos = butter(2, LOWPASS_HZ, fs=estimate_rate(s.time))
            acc = sosfiltfilt(sos, s.acc, axis=0)
            up = rot.rotate(rot.conj(np.asarray(cal[seg].mounting)), acc)  # sensor → segment
            ups.append((s.time, up))
        t = ups[0][0]
        up_d = np.column_stack([np.interp(t, ups[1][0], ups[1][1][:, k]) for k in range(3)])
        angles = np.degrees(elbow_from_gravity(ups[0][1], up_d, joint.side))
        out.setdefault("time_s", t)
        for i, (_, col) in enumerate(angle_columns(joint)):
            out[col] = np.interp(out["time_s"], t, angles[:, i])
    return out
