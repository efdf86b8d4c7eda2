"""Hand-built IMU recordings with known sensor errors for the sensorcal tests (not a test module).

A sensor holds a sequence of static poses joined by smooth turns, optionally followed by a
tumble that sweeps every direction. True signals: gyroscope = body rate, accelerometer =
earth-up g, magnetometer = the ENU field, in the sensor frame. Measured signals get the error
model ``y = K x + o + noise`` per channel (gyroscope: ``K = I``).
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot

G = 9.80665
DIP = np.deg2rad(60.0)
FIELD = 50.0 * np.array([0.0, np.cos(DIP), -np.sin(DIP)])


def random_poses(n: int, seed: int) -> np.ndarray:
    """(n, 4) orientations whose up directions are spread over the sphere."""
    rng = np.random.default_rng(seed)
    return rot.normalize(rng.normal(size=(n, 4)))


def axis_poses() -> np.ndarray:
    """(6, 4) orientations putting +x, −x, +y, −y, +z, −z of the sensor up."""
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for axis in np.vstack((np.eye(3), -np.eye(3)))[[0, 3, 1, 4, 2, 5]]:
        # rotation taking the sensor axis onto earth-up
        c = np.cross(axis, up)
        if np.linalg.norm(c) < 1e-9:
            q = np.array([1.0, 0, 0, 0]) if axis @ up > 0 else np.array([0.0, 1, 0, 0])
        else:
            q = rot.from_axis_angle(c, np.arccos(np.clip(axis @ up, -1, 1)))
        out.append(q)
    return np.array(out)


def trajectory(
    poses: np.ndarray,
    hold: float = 3.0,
    move: float = 1.5,
    tumble: float = 0.0,
    rate: float = 100.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample times, orientation (sensor → ENU) and body rate of the pose sequence.

    Each pose is held ``hold`` s, the turns between poses take ``move`` s (smoothstep
    profile); ``tumble`` s of rotation about two axes at incommensurate rates end the record.
    """
    pieces = []
    for i, q in enumerate(poses):
        pieces.append(np.repeat(q[None], int(hold * rate), axis=0))
        if i + 1 < len(poses):
            s = np.linspace(0.0, 1.0, int(move * rate), endpoint=False)
            pieces.append(rot.slerp(q, poses[i + 1], 3 * s**2 - 2 * s**3))
    if tumble > 0:
        t = np.arange(int(tumble * rate)) / rate
        spin = rot.mul(
            rot.from_rotvec(np.outer(t, [0.0, 0.0, 0.9])),
            rot.from_rotvec(np.outer(t, [0.37, 0.0, 0.0])),
        )
        pieces.append(rot.mul(poses[-1], spin))
    quat = rot.make_continuous(np.vstack(pieces))
    step = rot.mul(rot.conj(quat[:-1]), quat[1:])
    gyr = rot.to_rotvec(step) * rate
    gyr = np.vstack((gyr, gyr[-1:]))
    return np.arange(len(quat)) / rate, quat, gyr


def measure(
    quat: np.ndarray,
    gyr: np.ndarray,
    seed: int = 0,
    gyr_bias: np.ndarray | None = None,
    acc_gain: np.ndarray | None = None,
    acc_bias: np.ndarray | None = None,
    mag_gain: np.ndarray | None = None,
    mag_offset: np.ndarray | None = None,
    noise: tuple[float, float, float] = (0.003, 0.02, 0.2),
) -> dict[str, np.ndarray]:
    """Measured ``gyr`` (rad/s), ``acc`` (m/s²), ``mag`` (µT) with the given errors and noise."""
    rng = np.random.default_rng(seed)
    eye, zero = np.eye(3), np.zeros(3)
    acc = rot.rotate(rot.conj(quat), np.array([0.0, 0.0, G]))
    mag = rot.rotate(rot.conj(quat), FIELD)
    n = len(quat)
    return {
        "gyr": gyr + (zero if gyr_bias is None else gyr_bias) + noise[0] * rng.normal(size=(n, 3)),
        "acc": acc @ (eye if acc_gain is None else acc_gain).T
        + (zero if acc_bias is None else acc_bias)
        + noise[1] * rng.normal(size=(n, 3)),
        "mag": mag @ (eye if mag_gain is None else mag_gain).T
        + (zero if mag_offset is None else mag_offset)
        + noise[2] * rng.normal(size=(n, 3)),
    }
