"""Hand-built IMU signals with known orientation for the fusion tests (not a test module).

A sensor turns at a constant body rate; the accelerometer reads earth-up (g) and the
magnetometer the ENU field ``[0, B cos δ, −B sin δ]``, both rotated into the sensor frame, plus
seeded white noise and an optional constant gyroscope bias.
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot

G = 9.81
DIP = np.deg2rad(65.0)
FIELD = 48.0 * np.array([0.0, np.cos(DIP), -np.sin(DIP)])


def constant_rotation(
    seconds: float = 30.0,
    rate: float = 100.0,
    omega: tuple[float, float, float] = (0.3, -0.2, 0.5),
    q0: np.ndarray | None = None,
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0),
    gyr_noise: float = 0.005,
    acc_noise: float = 0.05,
    mag_noise: float = 0.5,
    seed: int = 0,
) -> dict[str, np.ndarray | float]:
    """Signals and truth: ``gyr, acc, mag`` (N×3), ``quat`` (N×4), ``rate``, ``bias``."""
    rng = np.random.default_rng(seed)
    n = int(round(seconds * rate))
    t = np.arange(n) / rate
    w = np.asarray(omega, dtype=float)
    start = rot.from_axis_angle([1.0, 2.0, 0.5], 0.7) if q0 is None else np.asarray(q0, float)
    quat = rot.mul(start, rot.from_rotvec(t[:, None] * w))
    acc = rot.rotate(rot.conj(quat), np.array([0.0, 0.0, G]))
    mag = rot.rotate(rot.conj(quat), FIELD)
    gyr = np.broadcast_to(w + np.asarray(bias), (n, 3))
    return {
        "gyr": gyr + gyr_noise * rng.standard_normal((n, 3)),
        "acc": acc + acc_noise * rng.standard_normal((n, 3)),
        "mag": mag + mag_noise * rng.standard_normal((n, 3)),
        "quat": rot.make_continuous(quat),
        "rate": rate,
        "bias": np.asarray(bias, dtype=float),
    }


def wrong_start(sig: dict, seconds: float = 0.5, angle: float = np.deg2rad(90.0)) -> dict:
    """Copy of ``sig`` whose first ``seconds`` of acc and mag come from a pose ``angle`` away.

    Every estimator initialises from the first samples, so it starts that far from the truth.
    """
    out = dict(sig)
    k = int(round(seconds * sig["rate"]))
    off = rot.from_axis_angle([1.0, -1.0, 0.3], angle)
    wrong = rot.mul(off, sig["quat"][:k])
    out["acc"] = sig["acc"].copy()
    out["mag"] = sig["mag"].copy()
    out["acc"][:k] = rot.rotate(rot.conj(wrong), np.array([0.0, 0.0, G]))
    out["mag"][:k] = rot.rotate(rot.conj(wrong), FIELD)
    return out


def heading_aligned(q_est: np.ndarray, q_ref: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``q_est`` rotated about earth-up by the mean heading offset over ``mask`` (for 6-D runs)."""
    e = rot.mul(q_ref[mask], rot.conj(q_est[mask]))
    yaw = 2.0 * np.arctan2(e[:, 3], e[:, 0])
    off = np.arctan2(np.mean(np.sin(yaw)), np.mean(np.cos(yaw)))
    return rot.mul(rot.from_axis_angle([0.0, 0.0, 1.0], off), q_est)


def swinging_start(
    seconds: float = 12.0,
    rate: float = 50.0,
    moving: float = 3.0,
    amplitude_deg: float = 15.0,
    lever: float = 0.3,
    seed: int = 0,
) -> dict[str, np.ndarray | float]:
    """A sensor ``lever`` m above a pivot that rocks for the first ``moving`` s (three axes at
    0.9-1.7 Hz, ``amplitude_deg`` each: up to about 180 °/s, |acc| off g by up to ~10 %), then
    holds still; the accelerometer reads gravity plus the lever's acceleration. Like a seated
    trunk recording that starts in movement. Same keys as :func:`constant_rotation` (no bias,
    no field noise)."""
    rng = np.random.default_rng(seed)
    n = int(round(seconds * rate))
    t = np.arange(n) / rate
    env = np.clip(1.0 - t / moving, 0.0, 1.0) ** 2  # the rocking fades out by ``moving``
    amp = np.deg2rad(amplitude_deg) * env
    angles = amp[:, None] * np.sin(2 * np.pi * np.array([1.3, 0.9, 1.7]) * t[:, None] + [0, 1, 2])
    quat = rot.mul(rot.from_axis_angle([1.0, 2.0, 0.5], 0.4), rot.from_rotvec(angles))
    quat = rot.make_continuous(quat)
    _, w = rot.angular_velocity(t, quat)
    gyr = np.vstack([w[:1], w])  # sample k: the rate over the interval ending at k
    pos = rot.rotate(quat, np.array([0.0, 0.0, lever]))
    lin = np.gradient(np.gradient(pos, t, axis=0), t, axis=0)
    acc = rot.rotate(rot.conj(quat), lin + np.array([0.0, 0.0, G]))
    mag = rot.rotate(rot.conj(quat), FIELD)
    return {
        "gyr": gyr + 0.005 * rng.standard_normal((n, 3)),
        "acc": acc + 0.05 * rng.standard_normal((n, 3)),
        "mag": mag,
        "quat": quat,
        "rate": rate,
        "bias": np.zeros(3),
    }
