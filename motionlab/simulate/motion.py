"""Joint trajectories as analytic functions of time, one generator per kind of movement.

The body's state is a row of :data:`CHANNELS` (rad and m): the pelvis position and orientation
relative to a *feet reference* (a point on the floor between the ankles and a heading; x forward,
y left, z up), and three angles per joint. Knee, elbow and lumbar angles are clinical angles in the
DESIGN signs (:func:`motionlab.kinematics.joint_angles.compose` turns them into rotations); hip,
shoulder and ankle use the same Z-X-Y order with flexion/dorsiflexion, adduction and internal
rotation positive on both sides. Pelvis angles: ``tilt_z`` about its z (negative = anterior tilt),
``tilt_x`` about its x (obliquity), ``rot_y`` about its y (pelvic rotation).

Every generator returns a :class:`Block` whose function of block time ``tau`` is a sum of
sinusoids and polynomials multiplied by a C³ envelope that is exactly zero outside the block, so
the block holds its neutral pose before and after it and can be joined to its neighbours without
a kink (Hermite "smoothstep" of degree 7: 35x⁴ − 84x⁵ + 70x⁶ − 20x⁷).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache

import numpy as np
from scipy.interpolate import CubicSpline

from motionlab.simulate.body import Body

ROOT = ("root_x", "root_y", "root_z", "heading", "tilt_z", "tilt_x", "rot_y")
JOINT_GROUPS = (
    "hip_r", "hip_l", "knee_r", "knee_l", "ankle_r", "ankle_l", "lumbar",
    "shoulder_r", "shoulder_l", "elbow_r", "elbow_l",
)  # fmt: skip
CHANNELS = ROOT + tuple(f"{g}_{i}" for g in JOINT_GROUPS for i in range(3))
CH = {name: i for i, name in enumerate(CHANNELS)}
DEG = np.pi / 180.0


def group(name: str) -> slice:
    """Columns of a joint group (``'knee_r'``) in the channel matrix."""
    i = CH[f"{name}_0"]
    return slice(i, i + 3)


# ------------------------------------------------------------------------------ smooth pieces


def smoothstep(x: np.ndarray) -> np.ndarray:
    """C³ step from 0 (x ≤ 0) to 1 (x ≥ 1): 35x⁴ − 84x⁵ + 70x⁶ − 20x⁷."""
    x = np.clip(x, 0.0, 1.0)
    return x**4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)))


def _smoothstep_integral(x: np.ndarray) -> np.ndarray:
    """∫₀ˣ smoothstep for x in [0, 1]: 7x⁵ − 14x⁶ + 10x⁷ − 2.5x⁸ (= 1/2 at x = 1)."""
    return x**5 * (7.0 + x * (-14.0 + x * (10.0 - 2.5 * x)))


def envelope(tau: np.ndarray, duration: float, ramp: float) -> np.ndarray:
    """1 inside the block, C³ ramps of ``ramp`` s at both ends, exactly 0 outside [0, duration]."""
    ramp = min(ramp, duration / 2)
    return smoothstep(tau / ramp) * smoothstep((duration - tau) / ramp)


def envelope_integral(tau: np.ndarray, duration: float, ramp: float) -> np.ndarray:
    """∫₀^τ :func:`envelope` (s), analytic; constant after the block."""
    ramp = min(ramp, duration / 2)
    t = np.clip(tau, 0.0, duration)
    head = ramp * _smoothstep_integral(np.clip(t / ramp, 0.0, 1.0))
    middle = np.clip(t - ramp, 0.0, duration - 2 * ramp)
    tail_x = np.clip((t - (duration - ramp)) / ramp, 0.0, 1.0)
    tail = ramp * (0.5 - _smoothstep_integral(1.0 - tail_x))  # r ∫_{1-x}^{1} smoothstep
    return head + middle + tail


def wrap(a: np.ndarray) -> np.ndarray:
    """Angle(s) wrapped to [-π, π)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


# ---------------------------------------------------------------------------- gait templates

# Right-leg sagittal angles (deg) over one stride from heel strike (% of the cycle): the knots of a
# periodic cubic spline, kept to its first _HARMONICS Fourier harmonics (5.4 Hz at 0.9 strides/s).
# 6 harmonics follow these knots as closely as 12 around contact (the shank's zero crossing within
# 1 ms, its deceleration 52 against 58 rad/s²); 12 put 0.13 rad/s RMS of the shank's ω into 7-11
# Hz, where clocksync.impact_clock looks for heel strikes, and its shank clock offsets went
# 11-40 ms wrong (seed 3; step-time asymmetry errors up to 11 points in bench/gait.py).
# Knee, loading response to mid-stance (0-42 %) and swing (72-100 %): the mean knee flexion of
# Schwartz, Rozumalski & Trost (2008, J Biomech 41:1639; typically developing children at their
# self-selected speed; the mean curve as tabulated every 2 % in the open repository
# 0todd0000/detrend1d, detrend1d/csv/kneeflex.csv) at 12 of its instants; its key values agree
# with the adult ones of Perry & Burnfield (2010, Gait Analysis, ch. 7: 5° at initial contact,
# 15-20° in loading response, 60-62° peak, 25° at the end of mid-swing). It ends its terminal-swing
# extension at 98 % (3.8°) and flexes straight into loading response (11° at 4 %); the former
# Perry-only knots (100 %: 5°, 15 %: 18°, 6 harmonics) spread that reversal over 93-5 %, so the
# shank kept swinging forward 16-19 ms past the kinematic initial contact, where on a real walk
# it stops 1-7 ms before it (bench/gait_contact.py). Knee pre-swing (50 %: 10°, 55 %: 19°, 60 %:
# 38°, Perry & Burnfield's 40° at toe-off): near its mid-stance value until terminal stance, which
# puts the shank's fastest backward rotation (hip minus knee flexion rate) at 55-60 % of the
# stride and 51-56 ms before the kinematic toe-off, as on the real walk (≈57 %, 52-60 ms;
# Schwartz's later pre-swing, 56 %: 22.6°, 62 %: 40.6°, put it 39 ms before).
# Hip: Perry & Burnfield (2010, ch. 8) key values (30° at initial contact, 10° extension at 50 %,
# neutral at toe-off, 35° in terminal swing); the terminal-swing retraction (35° → 30°) ends at
# 97 % and the hip holds 30° into loading response (6 %), as on the real walk (Vicon walking2,
# sagittal angles from the joint centres: hip flexion falls 3-6° from its swing peak at ≈90 % to
# 97-98 %, then stays within 3° of that until 10 %; the knee joint centre still moves forward
# relative to the hip at initial contact).
# Ankle: Perry & Burnfield (2010, ch. 6).
_GAIT_POINTS = {
    "knee": (
        [0, 4, 8, 12, 24, 42, 50, 55, 60, 72, 80, 86, 90, 94, 98, 100],
        [5.5, 11.0, 17.2, 19.7, 14.5, 6.7, 10.0, 19.0, 38.0, 60.5, 50.8, 32.9, 19.0, 7.5, 3.8, 5.5],
    ),
    "hip": ([0, 6, 20, 50, 62, 85, 97, 100], [30, 30, 18, -10, 0, 35, 30, 30]),
    "ankle": ([0, 8, 45, 62, 75, 90, 100], [0, -6, 10, -16, -2, 2, 0]),
}
_HARMONICS = 6


@cache
def _gait_fourier(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Fourier coefficients (a_k cos kθ + b_k sin kθ, k = 0…:data:`_HARMONICS`) of a periodic
    gait curve (rad)."""
    pct, deg = _GAIT_POINTS[name]
    spline = CubicSpline(np.array(pct) / 100.0, np.array(deg, dtype=float), bc_type="periodic")
    n = 256
    c = np.fft.rfft(spline(np.arange(n) / n)) / n
    a = 2 * c.real[: _HARMONICS + 1]
    b = -2 * c.imag[: _HARMONICS + 1]
    a[0] /= 2
    return a * DEG, b * DEG


def gait_basis(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cos(kθ)`` and ``sin(kθ)`` (N, :data:`_HARMONICS` + 1) for :func:`gait_curve`; ``(−1)^k``
    shifts them by π."""
    kt = np.multiply.outer(theta, np.arange(_HARMONICS + 1))
    return np.cos(kt), np.sin(kt)


def gait_curve(name: str, basis: tuple[np.ndarray, np.ndarray], half: bool = False) -> np.ndarray:
    """Gait template ``name`` (knee, hip, ankle) from :func:`gait_basis` of the phase (rad,
    0 = heel strike); ``half`` shifts it by half a stride (the other leg)."""
    a, b = _gait_fourier(name)
    if half:
        sign = (-1.0) ** np.arange(len(a))
        a, b = a * sign, b * sign
    return basis[0] @ a + basis[1] @ b


# -------------------------------------------------------------------------------- postures


def legs_sagittal(body: Body, kappa, beta, gamma):
    """Pelvis height/forward position and hip/ankle angles for feet flat on the floor.

    ``kappa`` knee flexion, ``beta`` forward tilt of the shank, ``gamma`` anterior pelvic tilt
    (rad). Returns ``(forward, up, hip_flexion, ankle_dorsiflexion)`` with positions in m
    relative to the feet reference.
    """
    L = body.lengths
    thigh = kappa - beta
    forward = L["shank"] * np.sin(beta) - L["thigh"] * np.sin(thigh)
    up = L["ankle_height"] + L["shank"] * np.cos(beta) + L["thigh"] * np.cos(thigh)
    return forward, up, thigh + gamma, beta


def posture(body: Body, name: str) -> np.ndarray:
    """Neutral channel row of a named pose: ``standing``, ``sitting`` or ``supine``."""
    p = np.zeros(len(CHANNELS))
    for side in "rl":
        p[CH[f"elbow_{side}_1"]] = 10 * DEG  # carrying angle
    if name == "sitting":
        fwd, up, hip, ank = legs_sagittal(body, 90 * DEG, 0.0, 0.0)
        p[CH["root_x"]], p[CH["root_z"]] = fwd, up
        for side in "rl":
            p[CH[f"knee_{side}_0"]], p[CH[f"hip_{side}_0"]] = 90 * DEG, hip
            p[CH[f"elbow_{side}_0"]] = 30 * DEG
        p[CH["lumbar_0"]] = 10 * DEG
    elif name == "supine":
        p[CH["root_x"]] = -(body.lengths["thigh"] + body.lengths["shank"])
        p[CH["root_z"]] = body.lengths["pelvis_depth"]
        p[CH["tilt_z"]] = np.pi / 2
    else:
        p[CH["root_z"]] = legs_sagittal(body, 0.0, 0.0, 0.0)[1]
    return p


def posture_of(text: str) -> str:
    """Pose named in a step's ``pose`` or ``instructions`` text (default standing)."""
    t = text.lower()
    if any(w in t for w in ("supine", "lying", "lie ")):
        return "supine"
    if any(w in t for w in ("sit", "seated", "chair")):
        return "sitting"
    return "standing"


# ----------------------------------------------------------------------------------- blocks


@dataclass
class Block:
    """A stretch of the recording: channels as a function of block time ``tau`` (s).

    ``fn`` returns local channels (N, C); ``end`` is the displacement of the feet reference at
    the end ``(dx, dy, dheading)`` in the block's local frame; ``impacts`` are heel-strike times
    (s, block time) and ``impact_sides`` the leg of each (``"r"`` or ``"l"``).
    """

    name: str
    kind: str
    phase: str
    duration: float
    fn: Callable[[np.ndarray], np.ndarray]
    end: tuple[float, float, float] = (0.0, 0.0, 0.0)
    impacts: np.ndarray = field(default_factory=lambda: np.zeros(0))
    generator: str = ""
    impact_sides: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype="U1"))


def _tile(p: np.ndarray, tau: np.ndarray) -> np.ndarray:
    return np.broadcast_to(p, (len(tau), len(p))).copy()


def static_block(body: Body, name: str, kind: str, phase: str, duration: float, pose: str):
    """Holding a pose, perfectly still."""
    p = posture(body, pose)
    return Block(name, kind, phase, duration, lambda tau: _tile(p, tau), generator=f"static:{pose}")


def rest_block(duration: float, row: np.ndarray) -> Block:
    """Standing (or sitting) still in the pose ``row`` the previous block ended in."""
    return Block("rest", "rest", "rest", duration, lambda tau: _tile(row, tau), generator="rest")


def cycles(tau, duration, reps, ramp=0.4):
    """(one-sided 0→1→0, symmetric ±1) repetition waves under the block envelope."""
    f = max(reps, 1) / duration
    e = envelope(tau, duration, min(ramp, 0.25 / f))
    ph = 2 * np.pi * f * tau
    return e * (1 - np.cos(ph)) / 2, e * np.sin(ph)


#: The pelvis's sideways sway in gait (m): the body's centre moves over the stance foot, furthest
#: at mid-stance (Perry & Burnfield 2010, Gait Analysis ch. 2: about 2 cm to each side), so the
#: pelvis accelerates towards the other side through single support (the ground's medial push).
#: Checked against the real 16-IMU walk (``bench/gait_pelvis.py``: its pelvis sensor's sideways
#: acceleration over 10-50 % of the right stride -0.50 m/s², of the left +0.31; simulated
#: seeds 0-5 now -0.53 to -0.79 and -0.03 to +0.37, before this sway was turned to the stance
#: side +0.2 to +0.5 and -0.5 to -0.8). Its up-and-down bounce (here lowest at mid-stance, on
#: the real walk in double support) still differs from the real walk's: docs/simulator.md.
PELVIS_SWAY_M = 0.02
#: Obliquity once per stride (deg, and where in the stride it peaks): the swing side drops,
#: the stance side is up, most at the end of loading response (Perry & Burnfield 2010:
#: contralateral drop about 4-5°; Kadaba et al. 1989, J Orthop Res 7:849: range about 8°); the
#: real walk: +4.5° at 20-30 % of the right stride, -4.5° at 70-80 % (``bench/gait_pelvis.py``).
#: It went round twice per stride before.
PELVIS_OBLIQUITY_DEG = 4.0
PELVIS_OBLIQUITY_PEAK = 0.22


def stride_phase(duration: float, stride_hz: float, cv: float, seed: int):
    """The gait phase θ(τ) (rad, 2π a stride) of a walk whose stride times vary from stride to
    stride (each ``1 / stride_hz`` times a factor of mean 1 and SD ``cv``, within ±3 SD, from
    seed ``seed``): a cubic spline through the strides' starts, so the joints' rates stay
    smooth. Healthy adults' stride-time CV is 1-3 % (Hausdorff 2005, J NeuroEng Rehabil 2:19)."""
    rng = np.random.default_rng([seed, 2305])
    n = int(np.ceil(duration * stride_hz * 1.5)) + 3
    factors = 1.0 + np.clip(cv * rng.standard_normal(n), -3 * cv, 3 * cv)
    starts = np.r_[0.0, np.cumsum(factors / stride_hz)]
    return CubicSpline(starts, 2 * np.pi * np.arange(len(starts)))


def gait_block(
    body: Body, name: str, phase: str, duration: float, options: dict, seed: int = 0
) -> Block:
    """Walking around an ellipse (straight-ish sides, turns at the ends) at a steady cadence.

    Speed up to ``speed`` m/s (default 1.2), stride frequency ``stride_hz`` (default 0.9 Hz);
    knee, hip and ankle follow published mean curves (knee: Schwartz et al. 2008; hip and ankle:
    Perry & Burnfield 2010, with the hip's terminal-swing retraction ending before initial contact
    as on a real walk; the comment above :data:`_GAIT_POINTS` says which values come from where),
    with pelvis bounce/sway/rotation and arm swing. Around contact the shank's sagittal angular
    velocity is checked against a real walk by ``bench/gait_contact.py``.
    ``toe_off_r``, ``toe_off_l`` and ``step_offset`` change the timing of each leg within the
    stride (:func:`_shaped_gait`). ``stride_cv`` (default :data:`STRIDE_CV`; 0: every stride
    alike, the metronome of before) varies the stride times from stride to stride
    (:func:`stride_phase`, from ``seed``); both legs follow the varied phase, with or without the
    timing options. The impacts (heel strikes) come where the phase reaches each leg's heel
    strike: the right's at 0, the left's at ``step_offset`` of each stride.
    """
    a, b = float(options.get("path_a", 4.0)), float(options.get("path_b", 2.0))
    speed, f = float(options.get("speed", 1.2)), float(options.get("stride_hz", 0.9))
    ramp = min(2.0, duration / 3)
    phidot = speed / a
    stand = posture(body, "standing")

    def path(phi):
        x, y = a * np.sin(phi), b - b * np.cos(phi)
        return x, y, phi + wrap(np.arctan2(b * np.sin(phi), a * np.cos(phi)) - phi)

    cv = float(options.get("stride_cv", STRIDE_CV))
    if not 0 <= cv < 1 / 3:  # NaN too; from 1/3 a stride 3 SD short would take no time
        raise ValueError(
            f"stride_cv is a fraction of the stride time (0.02: 2 %), 0 or more and "
            f"below 1/3, not {cv:g}"
        )
    theta = stride_phase(duration, f, cv, seed) if cv > 0 else None

    def cycles(tau):
        """Strides walked by block time ``tau`` (1 a stride, 0 at a right heel strike)."""
        return f * tau if theta is None else theta(tau) / (2 * np.pi)

    def fn(tau):
        e = envelope(tau, duration, ramp)
        th = 2 * np.pi * f * tau if theta is None else theta(tau)
        x, y, psi = path(phidot * envelope_integral(tau, duration, ramp))
        out = _tile(stand, tau)
        # the pelvis over the stance leg (th = 0 at the right heel strike): see PELVIS_SWAY_M
        sway = PELVIS_SWAY_M * e * np.sin(th)  # to the right in the right stance
        out[:, CH["root_x"]] = x + np.sin(psi) * sway
        out[:, CH["root_y"]] = y - np.cos(psi) * sway
        out[:, CH["root_z"]] += e * (0.02 * np.cos(2 * th) - 0.015)
        out[:, CH["heading"]] = psi
        out[:, CH["tilt_z"]] = e * (-3 * DEG + 2 * DEG * np.sin(2 * th))
        peak = 2 * np.pi * PELVIS_OBLIQUITY_PEAK  # the right side up (tilt_x > 0: down)
        out[:, CH["tilt_x"]] = -e * PELVIS_OBLIQUITY_DEG * DEG * np.cos(th - peak)
        out[:, CH["rot_y"]] = e * 5 * DEG * np.cos(th)
        basis = gait_basis(th)
        for side, shift in (("r", 0.0), ("l", np.pi)):
            out[:, CH[f"knee_{side}_0"]] = e * gait_curve("knee", basis, shift > 0)
            out[:, CH[f"knee_{side}_2"]] = e * 3 * DEG * np.sin(th + shift - 0.4)
            out[:, CH[f"knee_{side}_1"]] = e * 1.5 * DEG * np.sin(2 * (th + shift))
            hip = gait_curve("hip", basis, shift > 0)
            out[:, CH[f"hip_{side}_0"]] = e * hip
            out[:, CH[f"hip_{side}_1"]] = e * 3 * DEG * np.sin(th + shift + 0.3)
            out[:, CH[f"ankle_{side}_0"]] = e * gait_curve("ankle", basis, shift > 0)
            out[:, CH[f"shoulder_{side}_0"]] = e * (-0.5 * hip + 8 * DEG)
            out[:, CH[f"elbow_{side}_0"]] += e * (20 * DEG - 0.3 * hip)
        out[:, CH["lumbar_2"]] = e * 5 * DEG * np.cos(th + np.pi)
        out[:, CH["lumbar_1"]] = e * 3 * DEG * np.sin(2 * th)
        out[:, CH["lumbar_0"]] = e * (3 * DEG + 1 * DEG * np.cos(2 * th))
        return out

    if any(k in options for k in GAIT_SHAPE_OPTIONS):
        fn = _shaped_gait(fn, options, cycles, duration, ramp)
    end = path(phidot * float(envelope_integral(np.array(duration), duration, ramp)))
    offset = float(options.get("step_offset", 0.5))
    n = np.arange(np.ceil(cycles(duration)))
    strikes = np.sort(np.r_[n, n + offset])  # in strides: the right leg's, the left's
    if theta is None and offset == 0.5:  # the metronome's, as before (bit for bit)
        strikes = np.arange(0.0, duration, 0.5 / f)
    elif theta is None:
        strikes = strikes / f
    else:  # where the varied phase reaches them
        grid = np.arange(0.0, duration, 1e-3)
        strikes = np.interp(strikes, cycles(grid), grid)
    strikes = strikes[(strikes < duration) & (envelope(strikes, duration, ramp) > 0.5)]
    k = cycles(strikes)  # the right's at whole strides, the left's ``offset`` after
    right = np.abs(k - np.round(k)) <= np.abs(k - offset - np.round(k - offset))
    sides = np.where(right, "r", "l")
    return Block(name, "gait", phase, duration, fn, end, strikes, "gait", sides)


#: the stride-to-stride variation of the stride time (CV as a fraction) of the simulated walk
#: (gait option ``stride_cv``; :func:`stride_phase`): see docs/simulator.md, "Stride-to-stride
#: variation", for the real walks it comes from.
STRIDE_CV = 0.025
#: gait options that change the legs' timing (:func:`_shaped_gait`)
GAIT_SHAPE_OPTIONS = ("toe_off_r", "toe_off_l", "step_offset")
#: where the templates' toe-off falls (fraction of the stride, Perry & Burnfield 2010: 60-62 %)
TEMPLATE_TOE_OFF = 0.62


def leg_phase(u: np.ndarray, toe_off: float) -> np.ndarray:
    """Template phase (0-1) of a leg at its own stride phase ``u`` (0-1 from heel strike).

    A smooth monotone warp ``v = u + c sin²(πu)`` with ``v(toe_off) = TEMPLATE_TOE_OFF``: the
    template's stance is stretched to end at ``toe_off`` (so ``toe_off`` 0.67 gives a longer
    stance), heel strike stays at 0 and the curves stay C^∞ across strides.
    """
    c = (TEMPLATE_TOE_OFF - toe_off) / np.sin(np.pi * toe_off) ** 2
    if abs(c) * np.pi >= 0.95:
        raise ValueError(f"toe-off at {toe_off:g} of the stride is too far from the template's")
    return u + c * np.sin(np.pi * u) ** 2


def _shaped_gait(fn, options: dict, cycles, duration: float, ramp: float):
    """The gait block's ``fn`` with each leg on its own timing.

    ``cycles(tau)``: the strides walked by block time ``tau`` (1 a stride, varied from stride to
    stride or not). The right leg's heel strikes at stride phase 0, the left's at ``step_offset``
    (default 0.5; below 0.5 the left step is the shorter one); each leg's template runs through
    :func:`leg_phase` with its ``toe_off_<side>`` (default :data:`TEMPLATE_TOE_OFF`). The pelvis,
    trunk and arms keep the right leg's phase.
    """
    offset = float(options.get("step_offset", 0.5))
    toe = {s: float(options.get(f"toe_off_{s}", TEMPLATE_TOE_OFF)) for s in "rl"}

    def shaped(tau):
        out = fn(tau)
        e = envelope(tau, duration, ramp)
        for side, d in (("r", 0.0), ("l", offset)):
            u = np.mod(cycles(tau) - d, 1.0)
            th = 2 * np.pi * leg_phase(u, toe[side])
            basis = gait_basis(th)
            out[:, CH[f"knee_{side}_0"]] = e * gait_curve("knee", basis)
            out[:, CH[f"knee_{side}_2"]] = e * 3 * DEG * np.sin(th - 0.4)
            out[:, CH[f"knee_{side}_1"]] = e * 1.5 * DEG * np.sin(2 * th)
            hip = gait_curve("hip", basis)
            out[:, CH[f"hip_{side}_0"]] = e * hip
            out[:, CH[f"hip_{side}_1"]] = e * 3 * DEG * np.sin(th + 0.3)
            out[:, CH[f"ankle_{side}_0"]] = e * gait_curve("ankle", basis)
        return out

    return shaped
