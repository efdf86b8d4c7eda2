"""Ideal IMU signals of a sensor on a moving segment, and the magnetic field of the room.

- Gyroscope: the sensor's angular velocity in the sensor frame, ``2 vec(q* ⊗ q̇)`` (rad/s).
- Accelerometer: specific force at the sensor's position, ``Rᵀ (p̈ + g e_z)`` (m/s²; the lever
  arm is included because ``p`` is the sensor's own position; at rest it reads +g along up).
- Magnetometer: ``Rᵀ (B_earth + Σ B_dipole(p))`` (µT) plus a field carried with the sensor; the
  earth field in ENU is ``|B| (0, cos δ, −sin δ)`` with dip ``δ`` (northern hemisphere).

The sensor sits at ``site`` (m, segment frame) with mounting ``q_mount`` (sensor → segment) and
an optional soft-tissue wobble: a small rotation ``exp(w(t))`` in the sensor frame, each heel
strike adding a damped oscillation ``A u (t/τ)³ e^{3−t/τ}/27 sin(2π f t)`` (C³ at its onset).

Optionally (:class:`TissueMotion`, preset ``soft_tissue: motion``) the sensor also moves on the
segment with the soft tissue under it: a second-order mass-spring-damper per axis (natural
frequency ``f`` 10-16 Hz, damping ratio ζ 0.3-0.5) driven by the segment's kinematic acceleration
(gravity left out, so a sensor at rest sits at its mounting)::

    d̈ + 2ζω ḋ + ω² d = −k a_site        (translation d, m, segment frame)
    ρ̈ + 2ζω ρ̇ + ω² ρ = −k α             (rotation ρ, rad, segment frame)
    θ = ρ + n × d / ℓ + θ_slip(t)        (tilt of the sensor as the tissue under it shears)

with ``a_site`` the acceleration of the site and ``α`` the angular acceleration of the segment
(both in the segment frame), ``k`` the preset's ``tissue_gain``, ``n`` the outward skin normal at
the site and ``ℓ`` = 5 cm of tissue. A slip ``θ_slip`` grows by ``slip_deg`` over the recording,
in proportion to ``∫|ω|² dt`` so it advances only while the segment moves, about an axis near
the segment's long axis, and the site slides 2 mm per degree down the segment. The pose is then::

    q_sensor = q_seg ⊗ exp(θ) ⊗ q_mount ⊗ exp(w)  =  q_seg ⊗ q_mount ⊗ wobble
    p_sensor = p_seg + R_seg (site + d + d_slip)

(``wobble = q_mount* ⊗ exp(θ) ⊗ q_mount ⊗ exp(w)``, in the sensor frame). With ``k = 1``
(``--soft-tissue motion`` with ``typical``) a thigh or shank sensor turns by ≈1-3° (peaks
0.5-4°) and moves by 1-3 mm in gait; ``loose`` (``k = 3``) about three times that, plus its slip.
With ``soft_tissue: skin`` (preset ``skin``) a rotation is added to ``θ``: the skin's motion
with the joint angles at both ends of the segment (:func:`skin_artefact`) and its shift after
each heel strike (:func:`impact_artefact`), both bounded by their amplitudes (docs/simulator.md).
The response is solved on a 200 Hz grid (exact first-order-hold discretisation) and represented
by quintic splines, so the IMU signals (derivatives of the pose) and the truth are one function.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import BSpline, make_interp_spline
from scipy.signal import cont2discrete, lfilter

from motionlab import rotations as rot
from motionlab.dsp import butter, padlen, sosfiltfilt
from motionlab.simulate.body import Body
from motionlab.simulate.chain import derivatives, derivatives_many, segment_poses
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
    #: each impact's strength (relative, one per impact; ``None``: all 1)
    strengths: np.ndarray | None = None

    def rotvec(self, t: np.ndarray) -> np.ndarray:
        """Wobble rotation vector (N, 3) in rad (sensor frame)."""
        w = np.zeros(len(t))
        if self.amplitude > 0:

            def pulse(dt: np.ndarray) -> np.ndarray:
                x = dt / self.decay_s
                return x**3 * np.exp(3 - x) / 27 * np.sin(2 * np.pi * self.freq_hz * dt)

            w = after_impacts(t, self.impacts, 40 * self.decay_s, pulse, self.strengths)
        return self.amplitude * w[:, None] * self.axis


def after_impacts(t: np.ndarray, impacts: np.ndarray, length: float,
                  pulse: Callable[[np.ndarray], np.ndarray],
                  strengths: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """``Σ_i s_i pulse(t − t_i)`` (N,) over the impacts ``t_i`` (s) with ``t_i < t < t_i +
    length``; ``s_i`` the impacts' ``strengths`` (default 1).

    Each instant visits only the impacts that can reach it (found by bisection in the sorted
    impacts), so the cost grows with the samples times the impacts that overlap, not with the
    samples times all impacts; the terms are added in the impacts' time order, as a loop over the
    impacts would add them (same numbers, bit for bit). ``t`` need not be sorted.
    """
    t = np.asarray(t, dtype=float)
    w = np.zeros(len(t))
    ti = np.asarray(impacts, dtype=float)
    if len(ti) == 0 or len(t) == 0:
        return w
    order = np.argsort(ti, kind="stable")
    ti = ti[order]
    si = np.ones(len(ti)) if strengths is None else np.asarray(strengths, dtype=float)[order]
    hi = np.searchsorted(ti, t, side="left")  # impacts before each instant: t_i < t exactly
    # a generous lower bound; the exact test t < t_i + length below decides
    lo = np.searchsorted(ti, t - length - 1e-9 * (1.0 + abs(length) + np.abs(t)), side="left")
    for j in range(int(np.max(hi - lo, initial=0))):
        i = lo + j
        m = i < hi
        k = i[m]
        m[m] = t[m] < ti[k] + length
        k = i[m]
        w[m] += si[k] * pulse(t[m] - ti[k])  # × 1.0 is exact: the same bits without strengths
    return w


TISSUE_LEVER_M = 0.05  # height of the tissue column that shears under the sensor (m)
SLIP_M_PER_RAD = 0.002 / np.radians(1.0)  # slide of the site down the segment per slip (m/rad)


@dataclass
class TissueMotion:
    """Motion of a sensor on its segment (see the module docstring): splines of time (s)."""

    rotation: BSpline  # t → (N, 3) rotation vector θ (rad, segment frame)
    displacement: BSpline  # t → (N, 3) displacement of the site (m, segment frame)
    freq_hz: float = 12.0
    damping: float = 0.4
    slip_deg: float = 0.0


@dataclass
class Mount:
    """Where and how a sensor sits on its segment."""

    segment: str
    q_mount: np.ndarray  # (4,) sensor → segment
    site: np.ndarray  # (3,) m, segment frame
    wobble: Wobble = field(default_factory=Wobble)
    tissue: TissueMotion | None = None
    normal: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    #: fraction of the bone's axial rotation the skin under the sensor follows (upper arm, skin)
    humeral_follow: float = 1.0

    def relative(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(wobble (N,4), d (N,3))``: the sensor's rotation away from its mounting (sensor
        frame; ``q_sensor = q_seg ⊗ q_mount ⊗ wobble``) and its site's displacement (m)."""
        t = np.asarray(t, dtype=float)
        q = np.broadcast_to(rot.IDENTITY, (len(t), 4)).copy()
        d = np.zeros((len(t), 3))
        if self.tissue is not None:
            q = rot.mul(rot.mul(rot.conj(self.q_mount), rot.from_rotvec(self.tissue.rotation(t))),
                        self.q_mount)  # fmt: skip
            d = self.tissue.displacement(t)
        if self.wobble.amplitude > 0:
            q = rot.mul(q, rot.from_rotvec(self.wobble.rotvec(t)))
        return q, d


def segment_kinematics(body: Body, timeline: Timeline, t: np.ndarray,
                       segments: tuple[str, ...]) -> dict:  # fmt: skip
    """``{segment: (q, omega, alpha, a)}`` on a uniform grid ``t`` (s): orientation, angular
    velocity (rad/s) and acceleration (rad/s², both segment frame), origin acceleration (m/s²,
    ENU, gravity left out)."""

    def pose(seg: str):
        return lambda tt: _poses(body, timeline, tt, segments)[seg]

    out = {}
    kin = derivatives_many([pose(seg) for seg in segments], t)
    for seg, (q, _, omega, acc) in zip(segments, kin, strict=True):
        out[seg] = (q, omega, np.gradient(omega, t, axis=0), acc)
    return out


STA_REF_RAD = np.radians(60.0)  # joint angle at which a driver of the skin artefact is tanh(1)


def skin_artefact(drivers: np.ndarray, directions: np.ndarray, amplitude: float) -> np.ndarray:
    """Rotation (N, 3; rad, segment frame) of the skin under a sensor, driven by joint angles.

    ``drivers`` (N, n) are the flexion angles (rad) of the joints at both ends of the segment;
    each enters through ``x = tanh(angle / 60°)`` and ``x²`` about its own axis, ``directions``
    (n, 2, 3) unit vectors, so the artefact is no rotation about one fixed axis (which a hinge fit
    would take for a turned axis) and is bounded: its norm never exceeds ``amplitude`` (rad)::

        θ = amplitude / (2n) · Σ_j (x_j d_j1 + x_j² d_j2)

    Correlated with the joint angles as the bone-pin and fluoroscopy studies find it (Leardini
    et al. 2005, Gait Posture 21:212: the artefact has the frequency content of the movement
    itself).
    """
    x = np.tanh(np.asarray(drivers, dtype=float) / STA_REF_RAD)
    n = x.shape[1]
    if n == 0:
        return np.zeros((len(x), 3))
    theta = x @ directions[:, 0] + (x**2) @ directions[:, 1]
    return amplitude / (2 * n) * theta


def impact_artefact(t: np.ndarray, impacts: np.ndarray, direction: np.ndarray, amplitude: float,
                    freq_hz: float, decay_s: float, rise_s: float = 0.0,
                    strengths: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """The ringing (N, 3; segment frame) of the tissue under a sensor after each heel strike: a
    rotation (rad) of the skin or a displacement (m) of the tissue, in ``amplitude``'s unit.

    The skin shifts on the muscles as they take the load and swings back (Cappozzo et al. 1996,
    Clin Biomech 11:90: the thigh's markers move most after heel strike), and the soft tissue
    rings as the heel's shock reaches it: after each impact ``amplitude · u³ e^{3−u} / 27 ·
    sin(2π f (t − t_i))`` along (about) ``direction`` (unit), ``u = (t − t_i) / decay_s``; C³ at
    its onset, at most ``amplitude`` for strikes further apart than its duration. With
    ``rise_s`` > 0 the envelope is ``(1 − e^{−(t − t_i)/rise_s})³ e^{−(t − t_i)/decay_s}``
    instead: a shock that is there within a few ``rise_s`` of the strike, whatever its decay
    (C² at its onset, so the acceleration it gives is continuous). ``strengths``: each
    impact's, relative (default 1).
    """

    def pulse(dt: np.ndarray) -> np.ndarray:
        if rise_s > 0:
            envelope = (1.0 - np.exp(-dt / rise_s)) ** 3 * np.exp(-dt / decay_s)
        else:
            u = dt / decay_s
            envelope = u**3 * np.exp(3 - u) / 27
        return envelope * np.sin(2 * np.pi * freq_hz * dt)

    ring = after_impacts(t, impacts, 20 * decay_s, pulse, strengths)
    return amplitude * ring[:, None] * direction


def movement_tremor(t: np.ndarray, omega: np.ndarray, level: float, weights: np.ndarray,
                    band_hz: tuple[float, float], speed_ref: float,
                    rng: np.random.Generator) -> np.ndarray:  # fmt: skip
    """Rotation (N, 3; rad, segment frame) of a sensor trembling on the tissue while its segment
    moves: noise band-passed to ``band_hz`` (zero phase, on the uniform grid ``t``, s) about the
    segment's axes with ``weights``, scaled so that its rate's RMS is ``level`` (rad/s) where the
    segment turns fast and fading with ``1 − exp(−|ω| / speed_ref)`` (``omega`` (N, 3) rad/s,
    smoothed over 0.25 s) towards rest, where it is none (what the upper-back sensors of the trunk
    data set show: docs/simulator.md)."""
    dt = float(t[1] - t[0])
    sos = butter(4, band_hz, 1.0 / dt, "bandpass")
    if len(t) <= padlen(sos):  # too short to filter
        return np.zeros((len(t), 3))
    noise = sosfiltfilt(sos, rng.normal(size=(len(t), 3)), axis=0) * weights
    rate = np.gradient(noise, dt, axis=0)
    noise *= level / max(float(np.sqrt(np.mean(np.sum(rate**2, axis=1)))), 1e-12)
    n = max(1, int(round(0.25 / dt)))
    speed = np.convolve(np.linalg.norm(omega, axis=1), np.ones(n) / n, mode="same")
    return noise * (1.0 - np.exp(-speed / speed_ref))[:, None]


def tissue_motion(
    kin: tuple[np.ndarray, ...],
    t: np.ndarray,
    site: np.ndarray,
    normal: np.ndarray,
    freq_hz: float,
    damping: float,
    gain: float,
    slip_axis: np.ndarray,
    slip_rad: float,
    artefact: np.ndarray | None = None,
    shock: np.ndarray | None = None,
) -> TissueMotion:
    """The soft-tissue motion of a sensor at ``site`` with skin normal ``normal`` (segment frame)
    from the segment's kinematics ``kin`` (:func:`segment_kinematics` on the uniform grid ``t``);
    ``artefact`` (N, 3; rad) is a rotation added on that grid (:func:`skin_artefact`), ``shock``
    (N, 3; m) a displacement (the ringing after heel strikes, :func:`impact_artefact`) that
    shears the tissue as the response does."""
    q, omega, alpha, acc = kin
    a_site = (rot.rotate(rot.conj(q), acc) + np.cross(alpha, site)
              + np.cross(omega, np.cross(omega, site)))  # fmt: skip
    w = 2 * np.pi * freq_hz
    dt = float(t[1] - t[0])
    num, den, _ = cont2discrete(([1.0], [1.0, 2 * damping * w, w * w]), dt, method="foh")
    drive = -gain * np.hstack([a_site, alpha])
    resp = lfilter(np.ravel(num), den, drive, axis=0)
    d, rho = resp[:, :3], resp[:, 3:]
    if shock is not None:
        d = d + shock
    theta = rho + np.cross(normal, d) / TISSUE_LEVER_M
    if artefact is not None:
        theta = theta + artefact
    if slip_rad > 0:
        work = cumulative_trapezoid(np.sum(omega**2, axis=1), t, initial=0.0)
        progress = work / work[-1] if work[-1] > 0 else np.zeros_like(work)
        theta = theta + slip_rad * progress[:, None] * slip_axis
        d = d - SLIP_M_PER_RAD * slip_rad * progress[:, None] * np.array([0.0, 1.0, 0.0])
    return TissueMotion(
        rotation=make_interp_spline(t, theta, k=5),
        displacement=make_interp_spline(t, d, k=5),
        freq_hz=freq_hz,
        damping=damping,
        slip_deg=float(np.degrees(slip_rad)),
    )


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
        site = mount.site
        if mount.tissue is None:
            q = rot.mul(q_seg, mount.q_mount)
        else:
            q = rot.mul(rot.mul(q_seg, rot.from_rotvec(mount.tissue.rotation(t))), mount.q_mount)
            site = site + mount.tissue.displacement(t)
        if mount.wobble.amplitude > 0:
            q = rot.mul(q, rot.from_rotvec(mount.wobble.rotvec(t)))
        return q, p_seg + rot.rotate(q_seg, site)

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
