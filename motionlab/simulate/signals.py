"""Ideal IMU signals of a sensor on a moving segment, and the magnetic field of the room.

- Gyroscope: the sensor's angular velocity in the sensor frame, ``2 vec(q* ⊗ q̇)`` (rad/s).
- Accelerometer: specific force at the sensor's position, ``Rᵀ (p̈ + g e_z)`` (m/s²; the lever
  arm is included because ``p`` is the sensor's own position; at rest it reads +g along up).
- Magnetometer: ``Rᵀ (B_earth + Σ B_dipole(p))`` (µT) plus a field carried with the sensor; the
  earth field in ENU is ``|B| (0, cos δ, −sin δ)`` with dip ``δ`` (northern hemisphere).

The sensor sits at ``site`` (m, segment frame) with mounting ``q_mount`` (sensor → segment) and
an optional soft-tissue wobble: a small rotation ``exp(w(t))`` in the sensor frame, each heel
strike adding a damped oscillation ``A u (t/τ)³ e^{3−t/τ}/27 sin(2π f t)`` (C³ at its onset).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from motionlab import rotations as rot
from motionlab.simulate.body import Body
from motionlab.simulate.chain import derivatives, segment_poses
from motionlab.simulate.timeline import Timeline

MU0_4PI = 1e-7  # T·m/A


@dataclass
class MagneticField:
    """Earth field (norm µT, dip deg) and point dipoles ``(position m, moment A·m²)`` in ENU."""

    norm_ut: float = 50.0
    dip_deg: float = 60.0
    dipoles: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)

    @property
    def earth(self) -> np.ndarray:
        d = np.radians(self.dip_deg)
        return self.norm_ut * np.array([0.0, np.cos(d), -np.sin(d)])

    def at(self, p: np.ndarray) -> np.ndarray:
        """Field (N, 3) in µT at positions ``p`` (N, 3) in m."""
        b = np.broadcast_to(self.earth, p.shape).copy()
        for pos, moment in self.dipoles:
            r = p - pos
            dist = np.linalg.norm(r, axis=1, keepdims=True)
            u = r / dist
            b += 1e6 * MU0_4PI * (3 * u * (u @ moment)[:, None] - moment) / dist**3
        return b


@dataclass
class Wobble:
    """Soft-tissue wobble of one mounting: amplitude (rad), axis, frequency (Hz), decay (s)."""

    amplitude: float = 0.0
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    freq_hz: float = 12.0
    decay_s: float = 0.04
    impacts: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def rotvec(self, t: np.ndarray) -> np.ndarray:
        """Wobble rotation vector (N, 3) in rad (sensor frame)."""
        w = np.zeros(len(t))
        if self.amplitude > 0:
            for ti in self.impacts:  # a loop over heel strikes, vectorised over time
                m = (t > ti) & (t < ti + 40 * self.decay_s)
                x = (t[m] - ti) / self.decay_s
                w[m] += x**3 * np.exp(3 - x) / 27 * np.sin(2 * np.pi * self.freq_hz * (t[m] - ti))
        return self.amplitude * w[:, None] * self.axis


@dataclass
class Mount:
    """Where and how a sensor sits on its segment."""

    segment: str
    q_mount: np.ndarray  # (4,) sensor → segment
    site: np.ndarray  # (3,) m, segment frame
    wobble: Wobble = field(default_factory=Wobble)


def _poses(body: Body, timeline: Timeline, t: np.ndarray, segments: tuple[str, ...]) -> dict:
    """Segment poses at ``t``, shared by the sensors sampled at the same instants (cached on the
    timeline next to its channel cache)."""
    ch = timeline.channels(t)
    cache = timeline.__dict__.setdefault("_pose_cache", [])
    for ch_old, segs, poses in cache:
        if ch_old is ch and segs == segments:
            return poses
    poses = segment_poses(body, ch, list(segments))
    cache[:] = [*cache[-1:], (ch, segments, poses)]
    return poses


def sensor_pose(body: Body, timeline: Timeline, mount: Mount, segments: tuple[str, ...] = ()):
    """A function ``t → (q_sensor (N,4) sensor → ENU, p_sensor (N,3) m)``.

    ``segments`` lists every segment that carries a sensor, so their poses are computed together.
    """
    segments = tuple(segments) or (mount.segment,)

    def pose(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q_seg, p_seg = _poses(body, timeline, t, segments)[mount.segment]
        q = rot.mul(q_seg, mount.q_mount)
        if mount.wobble.amplitude > 0:
            q = rot.mul(q, rot.from_rotvec(mount.wobble.rotvec(t)))
        return q, p_seg + rot.rotate(q_seg, mount.site)

    return pose


def ideal_imu(
    body: Body,
    timeline: Timeline,
    mount: Mount,
    t: np.ndarray,
    field_model: MagneticField,
    gravity: float = 9.81,
    segments: tuple[str, ...] = (),
) -> dict[str, np.ndarray]:
    """Error-free ``gyr``, ``acc``, ``mag`` (sensor frame) and the true ``quat``, ``position``.

    ``t`` are the true sampling instants (s); ``segments`` as in :func:`sensor_pose`.
    """
    q, p, omega, a = derivatives(sensor_pose(body, timeline, mount, segments), t)
    f = a + np.array([0.0, 0.0, gravity])
    q_inv = rot.conj(q)
    return {
        "quat": q,
        "position": p,
        "gyr": omega,
        "acc": rot.rotate(q_inv, f),
        "mag": rot.rotate(q_inv, field_model.at(p)),
    }
