"""Elbow angles from two accelerometers only (after Lee 2012, ch. 5).

Model (Lee §5.1-5.3, restated in motionlab's frames): the upper arm has no heading change (it moves
in a vertical plane) and the carrying angle keeps its value ``c`` of the stand, so the forearm is
``R_U · Rz(n) · Rx(c) · Ry(m)`` with flexion ``n`` and pronation ``m`` (the Z-X-Y elbow
decomposition with the middle angle fixed). Lee fixes ``c`` at 0°; with the 10-15° valgus of a
real (and the simulated) elbow that read the carrying angle as flexion wherever the elbow is
nearly straight (9° RMS below 20° of flexion on simulated elbows, and pronation 70-90° off
there), so ``c`` is taken from gravity in the stand, elbow straight and palms forward. Gravity
measured in each segment's frame (calibrated accelerometers, low-passed to remove movement
acceleration) then gives, in closed form instead of Lee's constrained Newton iteration,

- flexion from the forearm's long-axis component,
  ``(v_y cos n − v_x sin n) cos c + v_z sin c = u_y``;
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


def elbow_from_gravity(
    up_upper: np.ndarray, up_fore: np.ndarray, side: str, carrying: float = 0.0
) -> np.ndarray:
    """Clinical elbow angles (N, 3) in rad from "up" (N, 3) in upper-arm and forearm coordinates,
    with the carrying angle fixed at ``carrying`` (rad, clinical sign: :func:`stand_carrying`).

    Columns: flexion, carrying angle (``carrying`` throughout), pronation; signs as
    :mod:`motionlab.kinematics.joint_angles`.
    """
    signs = signs_for("elbow", side)
    c = signs[1] * carrying
    v = up_upper / np.linalg.norm(up_upper, axis=1, keepdims=True)
    u = up_fore / np.linalg.norm(up_fore, axis=1, keepdims=True)
    amp = np.hypot(v[:, 0], v[:, 1])
    phi = np.arctan2(v[:, 0], v[:, 1])
    target = (u[:, 1] - v[:, 2] * np.sin(c)) / np.cos(c)  # v_y cos n − v_x sin n
    acos = np.arccos(np.clip(target / np.maximum(amp, 1e-9), -1.0, 1.0))
    cands = [_wrap(-phi + acos), _wrap(-phi - acos)]
    prons = []
    for n in cands:
        bx, bz = _flexed_up(v, n, c)
        prons.append(_wrap(np.arctan2(u[:, 2], u[:, 0]) - np.arctan2(bz, bx)))
    ok = [
        (n >= FLEX_RANGE[0]) & (n <= FLEX_RANGE[1]) & (np.abs(m) <= np.pi / 2)
        for n, m in zip(cands, prons, strict=True)
    ]
    second = _choose_branch(np.column_stack(cands), np.column_stack(prons), np.column_stack(ok))
    n = np.where(second, cands[1], cands[0])
    m = np.where(second, prons[1], prons[0])
    flex_lock = amp < LOCK
    bx, bz = _flexed_up(v, n, c)
    pron_lock = flex_lock | (np.hypot(bx, bz) < LOCK) | (np.hypot(u[:, 0], u[:, 2]) < LOCK)
    n = _hold(n, flex_lock)
    m = _hold(m, pron_lock)
    return np.column_stack([signs[0] * n, np.full_like(n, signs[1] * c), signs[2] * m])


def _flexed_up(v: np.ndarray, n: np.ndarray, c: float) -> tuple[np.ndarray, np.ndarray]:
    """The x and z components of "up" ``v`` (upper-arm coordinates) in the frame turned by
    ``Rz(n) · Rx(c)``, before the pronation about its y: ``Rx(c)ᵀ Rz(n)ᵀ v``."""
    ay = v[:, 1] * np.cos(n) - v[:, 0] * np.sin(n)
    return v[:, 0] * np.cos(n) + v[:, 1] * np.sin(n), v[:, 2] * np.cos(c) - ay * np.sin(c)


def stand_carrying(up_upper: np.ndarray, up_fore: np.ndarray, side: str) -> float:
    """The carrying angle (rad, clinical sign) of an elbow held straight with the palms forward,
    from "up" (N, 3) in upper-arm and forearm coordinates over the pose: with ``n = m = 0`` the
    forearm's "up" is the upper arm's turned by ``Rx(c)ᵀ`` about x."""
    v, u = np.mean(up_upper, axis=0), np.mean(up_fore, axis=0)
    c = np.arctan2(v[2], v[1]) - np.arctan2(u[2], u[1])
    return float(signs_for("elbow", side)[1] * _wrap(c))


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
        carrying = 0.0  # Lee's model, where the recording has no stand with the arm hanging
        stand = _stand(protocol, calibration, joint.proximal)
        if stand is not None and ((t >= stand[0]) & (t <= stand[1])).any():
            pose = (t >= stand[0]) & (t <= stand[1])
            carrying = stand_carrying(ups[0][1][pose], up_d[pose], joint.side)
        angles = np.degrees(elbow_from_gravity(ups[0][1], up_d, joint.side, carrying))
        out.setdefault("time_s", t)
        for i, (_, col) in enumerate(angle_columns(joint)):
            out[col] = np.interp(out["time_s"], t, angles[:, i])
    return out


def _stand(protocol: Protocol, calibration: Any, upper_arm: str) -> tuple[float, float] | None:
    """The time (s) of the first static calibration step found in which ``upper_arm`` hangs
    (its vertical axis given): the elbow straight and the palms forward, as the arm and elbow
    protocols ask; ``None`` when the recording has none."""
    for step in protocol.calibration:
        found = (calibration.steps or {}).get(step.name) if calibration is not None else None
        if step.kind == "static" and upper_arm in step.vertical_axis and found:
            return float(found[0]), float(found[1])
    return None
