"""Synthetic sessions with an exact truth: ``simulate(protocol, duration, seed)``.

The subject (:mod:`.body`) performs the protocol's calibration steps and tasks (:mod:`.timeline`,
:mod:`.motion`, :mod:`.tasks`) as smooth analytic motion; each protocol segment carries an IMU
whose ideal signals (:mod:`.signals`) pass through a sensor error model (:mod:`.errors`);
optionally optical markers are recorded (:mod:`.markers`). The truth (:mod:`.truth`) holds
segment and sensor orientations, joint angles in the DESIGN conventions, biases, clocks, steps and
marker layouts. Random draws come from independent streams keyed by ``(seed, purpose, sensor)``,
so the motion and mountings of one seed are the same under every preset.

Mountings (``mounting=``): ``nominal`` puts each sensor at the protocol's ``sensor_axes`` turned by
up to ``mounting_max_deg`` about a random axis, near the body's usual site for the segment;
``random`` draws the orientation uniformly over SO(3) (Haar measure: a normalised 4-D Gaussian)
and the site anywhere on the segment's skin (:meth:`~.body.Body.surface_site`: along its length
and around it); ``surface`` uses such a site with the sensor flat on the skin (sensor z along the
outward normal) and turned by a uniform angle about it. The extra draws come from sub-streams of
the mounting stream, so ``nominal`` keeps its numbers and the soft tissue is the same under every
mounting.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from motionlab import __version__
from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import decompose_joint
from motionlab.kinematics.joint_types import JOINT_TYPES, angle_columns
from motionlab.kinematics.segment_types import kind_side
from motionlab.protocol import Protocol, load_protocol
from motionlab.session import SensorStream, Session
from motionlab.simulate import markers as _markers
from motionlab.simulate.body import SEGMENTS, Body
from motionlab.simulate.chain import segment_poses
from motionlab.simulate.errors import (
    SOFT_TISSUE,
    Clock,
    Preset,
    apply_channel,
    draw_channel,
    draw_clock,
    dropped,
    error_model,
    get_preset,
    sample_times,
    soft_hard_iron,
)
from motionlab.simulate.gait_truth import gait_truth
from motionlab.simulate.motion import CH, group, smoothstep
from motionlab.simulate.signals import (
    MagneticField,
    Mount,
    Wobble,
    _poses,
    ideal_imu,
    impact_artefact,
    movement_tremor,
    segment_kinematics,
    sensor_pose,
    skin_artefact,
    tissue_motion,
)
from motionlab.simulate.timeline import KNEE_MODELS, Timeline, plan
from motionlab.simulate.truth import Truth, load_truth, save_truth, write_truth_csv

__all__ = ["simulate", "Truth", "load_truth", "save_truth", "write_truth_csv", "MagneticField"]

PROVENANCE_TIME = "2000-01-01T00:00:00+00:00"  # fixed, so that the same seed gives the same bytes
_STREAMS = {"mount": 1, "sensor": 2, "markers": 3, "field": 4}
MOUNTINGS = ("nominal", "random", "surface")
# sub-streams of "mount" for the newer draws
_SUB_SITE, _SUB_TISSUE, _SUB_SKIN, _SUB_TREMOR, _SUB_SHOCK, _SUB_STRIKES = 1, 2, 3, 4, 5, 6
TISSUE_RATE_HZ = 200.0  # grid of the soft-tissue dynamics
#: named gait variants (``gait=``): options of the gait tasks (motion.gait_block); ``asymmetric``:
#: the right stance ends at 67 % instead of 62 % and the left heel strikes at 47 % of the stride
#: (right step 0.47, left step 0.53 of a stride); ``slow``: 0.75 strides/s (90 steps/min) at
#: 0.9 m/s. Every variant walks the ellipse of the gait task, so it turns at both ends.
GAIT_VARIANTS: dict[str, dict[str, float]] = {
    "normal": {},
    "asymmetric": {"toe_off_r": 0.67, "step_offset": 0.47},
    "slow": {"stride_hz": 0.75, "speed": 0.9},
    "slow_asymmetric": {"stride_hz": 0.75, "speed": 0.9, "toe_off_r": 0.67, "step_offset": 0.47},
}


def _rng(seed: int, purpose: str, index: int = 0, *sub: int) -> np.random.Generator:
    return np.random.default_rng([seed, _STREAMS[purpose], index, *sub])


def _uniform_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation uniform over SO(3) (normalised 4-D Gaussian; ``w ≥ 0``)."""
    q = rot.normalize(rng.normal(size=4))
    return q if q[0] >= 0 else -q


def _flat_on_skin(normal: np.ndarray, turn: float) -> np.ndarray:
    """Mounting (sensor → segment) with sensor z along ``normal``, turned by ``turn`` rad."""
    helper = np.array([0.0, 1.0, 0.0]) if abs(normal[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, normal)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    x = np.cos(turn) * e1 + np.sin(turn) * e2
    return rot.from_matrix(np.column_stack([x, np.cross(normal, x), normal]))


def _random_rotation(rng: np.random.Generator, max_deg: float) -> np.ndarray:
    axis = rng.normal(size=3)
    return rot.from_axis_angle(axis, np.radians(rng.uniform(0.0, max_deg)))


#: skin artefact (``soft_tissue="skin"``) per segment kind, relative to the preset's ``sta_deg``,
#: ``sta_impact_deg`` and ``tissue_gain`` (the thigh's): largest on the thigh (Leardini et al.
#: 2005), about half on the shank (Benoit et al. 2006; Reinschmidt et al. 1997), large about the
#: humerus' long axis (Cutti et al. 2005, Med Biol Eng Comput 43:291), small on trunk and foot.
STA_SCALE = {"thigh": 1.0, "shank": 0.5, "upperarm": 0.7, "forearm": 0.4, "foot": 0.3}
STA_SCALE_OTHER = 0.3
#: relative weights of the artefact's rotation about the segment's x (anterior), y (long) and z
#: (lateral) axes: the rotation about the long axis is the largest (Benoit et al. 2006: knee
#: rotation errors from skin markers several times those of ab/adduction)
STA_AXIS_WEIGHTS = np.array([0.6, 1.0, 0.6])
#: fraction of the humerus' axial (internal/external) rotation that a sensor on the upper arm's
#: skin follows, at the proximal and the distal end of the strap zone (linear in between; 0.69 at
#: the nominal mid-arm site): a cluster on the upper arm reads 0.64-0.74 of the humeral axial
#: rotation tracked through the proximal ulna ("Humeral axial rotation measurement through a
#: proximal ulna marker cluster", regression slopes in three tasks), and the distal markers lose
#: about half what the whole cluster loses (Warner & Heller 2025, J Biomech 112893: 25.9° against
#: 48.7° of the range; here 0.15 at the distal end against 0.31 at mid-arm)
STA_HUMERAL_FOLLOW = (0.55, 0.85)
#: spread (SD) of that fraction between sensors (the slopes' SD 0.04-0.10 between subjects)
STA_HUMERAL_FOLLOW_SD = 0.05
#: frequency (Hz) and decay (s) of the skin's shift after a heel strike (its peak ≈ 3 decays)
STA_IMPACT_HZ = (2.0, 4.0)
STA_IMPACT_DECAY_S = (0.03, 0.05)
#: the tissue's ringing after its own leg's heel strike (``sta_shock_mm`` on the thigh): scale
#: per segment kind (the pelvis rings after either leg's; with ``soft_tissue="skin"`` the wobble
#: takes the same scale), frequency (Hz), decay and rise (s). The real full-body walk's
#: (``datasets/human``, Xsens at 100 Hz) leg sensors carry 5.4-8.4 m/s² and 2.4-3.4 rad/s RMS
#: above 10 Hz while walking, its pelvis 1.0 and 0.31; the simulated legs carried 0.06-0.14 and
#: 0.7-0.8 (``bench/leg_ringing.py``, docs/simulator.md)
STA_RING_SCALE = {"thigh": 1.0, "shank": 1.0, "foot": 1.0, "pelvis": 0.12}
STA_SHOCK_HZ = (12.0, 20.0)
STA_SHOCK_DECAY_S = (0.030, 0.060)
STA_SHOCK_RISE_S = 0.005  # the shock reaches every sensor at the strike: one rise for all
#: the spread of one strike's ringing from the next (log-normal SD of its strength, per sensor):
#: the real walk's legs ring 19-27 % (gyroscope above 10 Hz, RMS over 0.3 s from each strike,
#: coefficient of variation over the strikes), the simulated wobble 1-4 % alike
STA_STRIKE_SPREAD = 0.25
#: the trunk sensors' tremor on the tissue while the trunk moves (:func:`movement_tremor`),
#: from the trunk data set's two ``trunkmovement`` trials (x-IMU3 on the upper and lower back,
#: ``bench/real_trunk.py``'s data; docs/simulator.md): the gyroscope's part above 4 Hz over
#: half-second windows, median 15-17°/s RMS on the upper back where it turns at 50-200°/s and
#: 12°/s at 20-50°/s (2.7°/s still), 4.1-5.7°/s on the lower back (0.9 still); spread over
#: 4-12 Hz, about the upper back's two horizontal axes (12-13°/s each) more than its long axis
#: (4-5°/s). Level (deg/s), axis weights (x, y, z segment frame), band (Hz), speed scale (deg/s)
STA_TREMOR_DEG_S = {"thorax": 19.0, "pelvis": 5.5}
STA_TREMOR_WEIGHTS = {"thorax": np.array([1.0, 0.35, 1.0]), "pelvis": np.array([1.0, 1.0, 1.0])}
STA_TREMOR_BAND_HZ = (4.0, 12.0)
STA_TREMOR_SPEED_DEG_S = 20.0


def _skin_drivers(body: Body, seg: str, ch: np.ndarray) -> np.ndarray:
    """Flexion angles (N, n; rad) of the joints at both ends of ``seg``, from the channels."""
    groups = [body.parent(seg)[1]]
    groups += [body.parent(c)[1] for c in SEGMENTS if body.parent(c)[0] == seg]
    cols = [group(g).start for g in groups if g is not None and f"{g}_0" in CH]
    return ch[:, cols]


def humeral_follow(body: Body, seg: str, site: np.ndarray, rng: np.random.Generator) -> float:
    """Fraction (0.5-0.9) of the humerus' axial rotation that the skin at ``site`` (m, segment
    frame) on upper arm ``seg`` follows: :data:`STA_HUMERAL_FOLLOW` by how far down the strap
    zone it sits, and :data:`STA_HUMERAL_FOLLOW_SD` drawn from ``rng``."""
    y0, y1 = body.strap_zone(seg)
    along = float(np.clip((site[1] - y0) / (y1 - y0), 0.0, 1.0))
    prox, dist = STA_HUMERAL_FOLLOW
    return float(np.clip(prox + along * (dist - prox) + rng.normal(0.0, STA_HUMERAL_FOLLOW_SD),
                         0.5, 0.9))  # fmt: skip


def _humeral_lag(body: Body, seg: str, ch: np.ndarray, follow: float) -> np.ndarray:
    """Rotation (N, 3; rad, segment frame) of the skin that stays behind the humerus' axial
    rotation: ``−(1 − follow)`` times the shoulder's internal rotation (the last angle of its
    Z-X-Y sequence, about the humerus' own long axis y), so that the sensor turns by ``follow``
    times the humerus about that axis relative to the thorax."""
    _, grp, _ = body.parent(seg)
    _, side = kind_side(seg)
    axial = ch[:, group(grp)][:, 2] * (-1.0 if side == "l" else 1.0)
    return -(1.0 - follow) * axial[:, None] * np.array([0.0, 1.0, 0.0])


def _mount(body: Body, protocol: Protocol, seg: str, i: int, seed: int, preset: Preset,
           max_deg: float, impacts: np.ndarray, mounting: str = "nominal",
           kin: tuple | None = None, grid: np.ndarray | None = None,
           ch_grid: np.ndarray | None = None,
           leg_impacts: dict[str, np.ndarray] | None = None) -> Mount:  # fmt: skip
    """Where sensor ``i`` sits; ``kin`` on ``grid`` (segment kinematics) for the soft tissue, the
    channels ``ch_grid`` on it for the skin artefact and each leg's heel strikes
    ``leg_impacts`` (s, by side) for the tissue's ringing."""
    rng = _rng(seed, "mount", i)
    nominal = rot.from_matrix(protocol.segments[seg].nominal_mounting())
    kind, side = kind_side(seg)
    scale = 1.0 if kind in ("thigh", "shank", "foot") else 0.5
    strengths = None
    if preset.soft_tissue == "skin":  # the wobble rings as the shock does: STA_RING_SCALE
        scale = STA_RING_SCALE.get(kind, scale)
        spread = _rng(seed, "mount", i, _SUB_STRIKES)
        strengths = np.exp(spread.normal(0.0, STA_STRIKE_SPREAD, len(impacts)))
    mount = Mount(
        segment=seg,
        q_mount=rot.mul(_random_rotation(rng, max_deg), nominal),
        site=body.sensor_site(seg) + rng.uniform(-0.01, 0.01, 3),
        wobble=Wobble(
            amplitude=np.radians(preset.wobble_deg) * scale,
            axis=rot.normalize(rng.normal(size=3)),
            freq_hz=rng.uniform(10.0, 16.0),
            impacts=impacts,
            strengths=strengths,
        ),
    )
    mount.normal = body.site_normal(seg, mount.site)
    if mounting != "nominal":
        alt = _rng(seed, "mount", i, _SUB_SITE)
        mount.site, mount.normal = body.surface_site(seg, alt.uniform(), alt.uniform())
        if mounting == "random":
            mount.q_mount = _uniform_rotation(alt)
        else:
            mount.q_mount = _flat_on_skin(mount.normal, alt.uniform(0.0, 2 * np.pi))
    if kin is not None and grid is not None:
        t_rng = _rng(seed, "mount", i, _SUB_TISSUE)
        damping = t_rng.uniform(0.3, 0.5)
        slip_axis = rot.normalize(np.array([0.3, 1.0, 0.3]) * t_rng.normal(size=3))
        slip = np.radians(preset.slip_deg) * t_rng.uniform(0.5, 1.0)
        artefact, shock, gain = None, None, preset.tissue_gain
        if ch_grid is not None:  # skin: per segment kind, largest on the thigh
            kind_scale = STA_SCALE.get(kind, STA_SCALE_OTHER)
            gain *= kind_scale
            drivers = _skin_drivers(body, seg, ch_grid)
            s_rng = _rng(seed, "mount", i, _SUB_SKIN)
            dirs = s_rng.normal(size=(drivers.shape[1], 2, 3)) * STA_AXIS_WEIGHTS
            dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
            amplitude = np.radians(preset.sta_deg) * kind_scale * s_rng.uniform(0.6, 1.0)
            artefact = skin_artefact(drivers, dirs, amplitude)
            direction = rot.normalize(s_rng.normal(size=3) * STA_AXIS_WEIGHTS)
            impact = np.radians(preset.sta_impact_deg) * kind_scale * s_rng.uniform(0.6, 1.0)
            artefact += impact_artefact(grid, impacts, direction, impact,
                                        s_rng.uniform(*STA_IMPACT_HZ),
                                        s_rng.uniform(*STA_IMPACT_DECAY_S))  # fmt: skip
            if preset.sta_shock_mm > 0 and kind in STA_RING_SCALE:  # the heel's shock
                h_rng = _rng(seed, "mount", i, _SUB_SHOCK)
                own = impacts if side not in (leg_impacts or {}) else leg_impacts[side]
                shocks = np.exp(h_rng.normal(0.0, STA_STRIKE_SPREAD, len(own)))
                along = rot.normalize(h_rng.normal(size=3) * STA_AXIS_WEIGHTS)
                size = preset.sta_shock_mm * 1e-3 * STA_RING_SCALE[kind] * h_rng.uniform(0.6, 1.0)
                shock = impact_artefact(grid, own, along, size, h_rng.uniform(*STA_SHOCK_HZ),
                                        h_rng.uniform(*STA_SHOCK_DECAY_S),
                                        STA_SHOCK_RISE_S, shocks)  # fmt: skip
            if kind in STA_TREMOR_DEG_S and preset.sta_deg > 0:  # trembling on the back
                artefact += movement_tremor(
                    grid,
                    kin[1],
                    np.radians(STA_TREMOR_DEG_S[kind]),
                    STA_TREMOR_WEIGHTS[kind],
                    STA_TREMOR_BAND_HZ,
                    np.radians(STA_TREMOR_SPEED_DEG_S),
                    _rng(seed, "mount", i, _SUB_TREMOR),
                )
            if kind == "upperarm" and preset.sta_deg > 0:  # the humerus turns under the skin
                mount.humeral_follow = humeral_follow(body, seg, mount.site, s_rng)
                artefact += _humeral_lag(body, seg, ch_grid, mount.humeral_follow)
        mount.tissue = tissue_motion(kin, grid, mount.site, mount.normal, mount.wobble.freq_hz,
                                     damping, gain, slip_axis, slip, artefact, shock)  # fmt: skip
    return mount


def _joint_truth(protocol: Protocol, ch: np.ndarray, poses: dict, body: Body) -> dict:
    """Joint angles (deg) per protocol joint: the designed angles where the joint is one of the
    body model's joints, else decomposed from the segment orientations."""
    out = {}
    for joint in protocol.joints.values():
        grp = f"{joint.type}_{joint.side}" if JOINT_TYPES[joint.type].sided else joint.type
        parent, chan, _ = body.parent(joint.distal)
        if chan == grp and parent == joint.proximal:
            angles = ch[:, group(grp)]
        else:
            angles = decompose_joint(poses[joint.proximal][0], poses[joint.distal][0], joint)
        for i, (_, col) in enumerate(angle_columns(joint)):
            out[col] = np.degrees(angles[:, i])
    return out


def _field(field: MagneticField | None, preset: Preset, timeline: Timeline, body: Body,
           seed: int) -> MagneticField:  # fmt: skip
    field = field if field is not None else MagneticField()
    if preset.dipole_moment > 0:
        rng = _rng(seed, "field")
        t_mid = np.array([0.5 * timeline.duration])
        pelvis = segment_poses(body, timeline.channels(t_mid), ["pelvis"])["pelvis"][1][0]
        where = pelvis + np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), -0.5])
        moment = rot.normalize(rng.normal(size=3)) * preset.dipole_moment
        field = MagneticField(field.norm_ut, field.dip_deg, [*field.dipoles, (where, moment)])
    return field


def _gait_options(gait: str | dict | None) -> dict | None:
    """Options of the gait tasks from a variant name or a dict; ``None`` when not asked for."""
    if gait is None:
        return None
    if isinstance(gait, str):
        if gait not in GAIT_VARIANTS:
            raise InputError(f"unknown gait variant {gait!r}", where="argument gait",
                             remedy=f"use one of {', '.join(GAIT_VARIANTS)}",
                             argument="gait")  # fmt: skip
        return dict(GAIT_VARIANTS[gait])
    return {k: float(v) for k, v in gait.items()}


def _with_gait(protocol: Protocol, options: dict) -> Protocol:
    """The protocol with ``options`` added to every gait task's options."""
    tasks = [
        dataclasses.replace(t, options={**t.options, **options})
        if any(w in f"{t.kind} {t.name}".lower() for w in ("gait", "walk"))
        else t
        for t in protocol.tasks
    ]
    return dataclasses.replace(protocol, tasks=tasks)


def simulate(
    protocol: Protocol | str | Path,
    duration: float = 60.0,
    seed: int = 0,
    preset: str | Preset = "typical",
    *,
    height: float = 1.75,
    rate_hz: float = 100.0,
    markers: bool = False,
    calibration: bool = True,
    mounting_max_deg: float = 30.0,
    field: MagneticField | None = None,
    gravity: float = 9.81,
    optical: _markers.OpticalSystem | None = None,
    rest_s: float = 3.0,
    mounting: str = "nominal",
    soft_tissue: str | None = None,
    gait: str | dict | None = None,
    gyr_sampling: str = "point",
    knee_model: str = "simple",
    progress: Callable[[str], None] | None = None,
) -> tuple[Session, Truth]:
    """Simulate a recording of ``protocol`` lasting ``duration`` s (true time).

    Parameters
    ----------
    protocol
        A :class:`Protocol` or a protocol file (path or packaged name).
    duration, seed, preset
        Length (s), random seed, error preset (``clean``, ``typical``, ``harsh`` or a
        :class:`~motionlab.simulate.errors.Preset`).
    height, rate_hz
        Body height (m) and IMU sampling rate (Hz).
    markers
        Also record optical markers (``session.markers['optical']``, lab frame, camera clock).
    calibration
        Perform the protocol's calibration steps before the tasks.
    mounting_max_deg
        Largest random deviation of a sensor from its nominal mounting (deg).
    mounting
        ``nominal`` (the protocol's ``sensor_axes``, within ``mounting_max_deg``), ``random``
        (any orientation, anywhere on the segment) or ``surface`` (anywhere on the segment, flat
        on the skin, any turn about the skin normal); see the module docstring.
    soft_tissue
        ``impacts`` (ringing after heel strikes), ``motion`` (also moving with the segment's
        acceleration, and slipping by the preset's ``slip_deg``) or ``skin`` (``motion`` scaled
        per segment, plus the skin's motion with the joint angles and after heel strikes, by the
        preset's ``sta_deg`` and ``sta_impact_deg``, and the upper arm's skin following only
        :data:`STA_HUMERAL_FOLLOW` of the humerus' axial rotation); default the preset's
        (``motion`` for ``loose``, ``skin`` for ``skin``). See :mod:`.signals` and
        docs/simulator.md.
    knee_model
        ``simple`` (flexion with proportional couplings) or ``anatomical`` (screw-home rotation
        and varus that no fixed axis follows); :func:`~.timeline.knee_coupling`. The truth's
        knee angles are the bones' (the segments'), with these couplings in them.
    gait
        A gait variant (:data:`GAIT_VARIANTS`) or options of the gait tasks (``stride_hz``,
        ``speed``, ``toe_off_r``, ``toe_off_l``, ``step_offset``, ``stride_cv``; see
        :func:`~motionlab.simulate.motion.gait_block`). The strides vary by
        :data:`~motionlab.simulate.motion.STRIDE_CV` by default; ``{"stride_cv": 0}`` walks the
        metronome of before. When given, the truth also holds the gait events from the feet's
        motion and the pelvis angles (:mod:`.gait_truth`).
    field, gravity
        Magnetic field model (default 50 µT, dip 60°) and gravity (m/s²).
    gyr_sampling
        ``point`` (the rate at each sampling instant) or ``interval`` (the mean rate over the
        interval ending there, as real MEMS gyroscopes report: the rotation between the two
        instants over their spacing). Recorded in each stream's ``attrs["gyr_sampling"]``.
    optical
        Camera system (rate, clock, lab frame, noise); default from the preset.
    progress
        Called with one line once the arguments are checked and the work begins.

    Returns
    -------
    (Session, Truth)
        The session with one SI :class:`SensorStream` per protocol segment, and the truth.
    """
    protocol = protocol if isinstance(protocol, Protocol) else load_protocol(protocol)
    preset = get_preset(preset)
    if mounting not in MOUNTINGS:
        raise InputError(f"unknown mounting {mounting!r}", where="argument mounting",
                         remedy=f"use one of {', '.join(MOUNTINGS)}",
                         argument="mounting")  # fmt: skip
    soft_tissue = soft_tissue or preset.soft_tissue
    if soft_tissue not in SOFT_TISSUE:
        raise InputError(f"unknown soft-tissue model {soft_tissue!r}",
                         where="argument soft_tissue",
                         remedy=f"use one of {', '.join(SOFT_TISSUE)}",
                         argument="soft_tissue")  # fmt: skip
    if not duration > 0 or not rate_hz > 0:
        raise InputError(
            "duration and rate must be positive",
            where="argument duration, argument rate_hz",
            argument=("duration", "rate_hz"),
        )
    if gyr_sampling not in ("point", "interval"):
        raise InputError(f"unknown gyroscope sampling {gyr_sampling!r}",
                         where="argument gyr_sampling", remedy="use point or interval",
                         argument="gyr_sampling")  # fmt: skip
    off_body = [k for k, v in protocol.segments.items() if k not in SEGMENTS and not v.required]
    if off_body:  # optional sensors off the body (a wheelchair's) are not simulated
        protocol = dataclasses.replace(
            protocol,
            segments={k: v for k, v in protocol.segments.items() if k not in off_body},
            joints={k: j for k, j in protocol.joints.items()
                    if j.proximal not in off_body and j.distal not in off_body},
        )  # fmt: skip
    for seg in protocol.segments:
        if seg not in SEGMENTS:
            body_segments = ", ".join(SEGMENTS)
            raise InputError(
                f"segment {seg!r} is not in the simulator's body model",
                protocol.path,
                f"segments.{seg}",
                f"use one of {body_segments}",
            )
    if knee_model not in KNEE_MODELS:
        raise InputError(f"unknown knee model {knee_model!r}", where="argument knee_model",
                         remedy=f"use one of {', '.join(KNEE_MODELS)}",
                         argument="knee_model")  # fmt: skip
    gait_options = _gait_options(gait)
    if gait_options is not None:
        protocol = _with_gait(protocol, gait_options)
    body = Body(height)
    timeline = plan(protocol, body, duration, seed, rest_s=rest_s, calibration=calibration,
                    knee_model=knee_model)  # fmt: skip
    field = _field(field, preset, timeline, body, seed)
    if progress is not None:  # the arguments are checked: what is being done, and how long
        progress(f"simulating {duration:g} s of '{protocol.name}' (seed {seed}) ...")
    t = np.arange(int(np.floor(duration * rate_hz + 1e-9)) + 1) / rate_hz
    ch = timeline.channels(t)
    poses = _poses(body, timeline, t, tuple(protocol.segments))
    truth = Truth(
        time=t,
        segments={k: {"orientation": q, "position": p} for k, (q, p) in poses.items()},
        joint_angles=_joint_truth(protocol, ch, poses, body),
        steps=timeline.steps(),
    )
    if gait_options is not None:
        truth.gait = gait_truth(body, timeline, t)
    session = Session()
    carried = _rng(seed, "field", 1).integers(len(protocol.segments))
    extended = mounting != "nominal" or soft_tissue != "impacts"  # the newer truth fields
    kin, grid, ch_grid = None, None, None
    if soft_tissue in ("motion", "skin"):
        grid = np.arange(-1.0, duration + 1.0 + 1e-9, 1.0 / TISSUE_RATE_HZ)
        kin = segment_kinematics(body, timeline, grid, tuple(protocol.segments))
        ch_grid = timeline.channels(grid) if soft_tissue == "skin" else None
    for i, seg in enumerate(protocol.segments):
        mount = _mount(body, protocol, seg, i, seed, preset, mounting_max_deg, timeline.impacts(),
                       mounting, kin[seg] if kin else None, grid, ch_grid,
                       {leg: timeline.impacts(leg) for leg in ("r", "l")})  # fmt: skip
        stream, info = _sensor(body, timeline, protocol, mount, seg, i, seed, preset, rate_hz,
                               duration, field, gravity, i == carried, gyr_sampling)  # fmt: skip
        q_grid, p_grid = sensor_pose(body, timeline, mount, tuple(poses))(t)
        truth.sensors[seg] = {"orientation": rot.make_continuous(q_grid), "position": p_grid}
        truth.sensors[seg] |= info
        if extended:
            wobble, disp = mount.relative(t)
            tissue = mount.tissue
            truth.sensors[seg] |= {
                "wobble": rot.make_continuous(wobble),
                "displacement": disp,
                "normal": mount.normal,
                "tissue_hz": tissue.freq_hz if tissue else mount.wobble.freq_hz,
                "tissue_damping": tissue.damping if tissue else 0.0,
                "slip_deg": tissue.slip_deg if tissue else 0.0,
            }
            if mount.humeral_follow < 1.0:
                truth.sensors[seg]["humeral_follow"] = mount.humeral_follow
        session.sensors[seg] = stream

    system = optical or _markers.OpticalSystem(
        noise_m=preset.marker_noise_m,
        occlusions_per_min=preset.occlusions_per_min,
        occlusion_mean_s=preset.occlusion_mean_s,
    )
    lay = _markers.layout(body, protocol, _rng(seed, "markers"))
    truth.markers = {
        "labels": lay.labels,
        "segments": lay.segments,
        "kinds": lay.kinds,
        "known": np.array(lay.known),
        "local": lay.local,
        "lab_rotation": system.lab_rotation,
        "lab_origin": system.lab_origin,
        "rate_hz": system.rate_hz,
        "clock_offset_s": system.offset_s,
        "clock_drift": system.drift,
        "noise_m": system.noise_m,
    }
    if markers:
        mset, frame_time = _markers.record(body, timeline, lay, system, duration,
                                           _rng(seed, "markers", 1))  # fmt: skip
        session.markers["optical"] = mset
        truth.markers["frame_time"] = frame_time

    params = {
        "protocol": protocol.name,
        "duration_s": duration,
        "seed": seed,
        "preset": preset.name,
        "height_m": height,
        "rate_hz": rate_hz,
        "markers": markers,
        "calibration": calibration,
        "mounting_max_deg": mounting_max_deg,
        # the newer options only when used, so older files keep their bytes
        **({"mounting": mounting} if mounting != "nominal" else {}),
        **({"soft_tissue": soft_tissue} if soft_tissue != "impacts" else {}),
        **({"gait": gait_options} if gait_options is not None else {}),
        **({"gyr_sampling": gyr_sampling} if gyr_sampling != "point" else {}),
        **({"knee_model": knee_model} if knee_model != "simple" else {}),
        "gravity_m_s2": gravity,
        "earth_field_uT": field.earth,
        "magnetic_dipoles": [{"position_m": p, "moment_Am2": m} for p, m in field.dipoles],
        "error_model": error_model(preset),
    }
    truth.config = params
    session.metadata = {
        "subject": {"height_m": height},
        "protocol": protocol.name,
        "seed": seed,
        "preset": preset.name,
        "simulated": True,
        "duration_s": duration,
    }
    session.provenance.append(
        {
            "time": PROVENANCE_TIME,
            "software": f"motionlab {__version__}",
            "command": "motionlab simulate",
            "parameters": {k: v for k, v in params.items() if k != "error_model"},
            "inputs": {},
        }
    )
    return session, truth


def _sensor(body, timeline, protocol, mount, seg, i, seed, preset, rate_hz, duration, field,
            gravity, carries_field, gyr_sampling="point"):  # fmt: skip
    """One IMU: its recorded stream and its truth entries."""
    rng = _rng(seed, "sensor", i)
    clock = draw_clock(preset.timing, rng)
    stamps, t_true = sample_times(clock, rate_hz, duration, rng)
    shared = tuple(protocol.segments) if clock == Clock(jitter_s=0.0) else ()  # same instants
    ideal = ideal_imu(body, timeline, mount, t_true, field, gravity, shared)
    if gyr_sampling == "interval":  # mean rate over the interval ending at each instant
        q_before = sensor_pose(body, timeline, mount, shared)(t_true - 1.0 / rate_hz)[0]
        ideal["gyr"] = rot.to_rotvec(rot.mul(rot.conj(q_before), ideal["quat"])) * rate_hz
    soft, hard = soft_hard_iron(preset, rng)
    mag = ideal["mag"]
    carried = np.zeros(3)
    if carries_field and preset.carried_field_ut > 0:
        carried = rot.normalize(rng.normal(size=3)) * preset.carried_field_ut
        on = smoothstep((t_true - 0.4 * duration) / 1.0) * smoothstep(0.6 * duration - t_true)
        mag = mag + on[:, None] * carried
    mag = mag @ soft.T + hard
    draws = {ch: draw_channel(getattr(preset, ch), rng) for ch in ("gyr", "acc", "mag")}
    raw = {"gyr": ideal["gyr"], "acc": ideal["acc"], "mag": mag}
    measured, biases = {}, {}
    for ch, model in (("gyr", preset.gyr), ("acc", preset.acc), ("mag", preset.mag)):
        measured[ch], biases[ch] = apply_channel(raw[ch], model, draws[ch], rate_hz, rng)
    keep = ~dropped(len(stamps), preset.timing, rng)
    _, side = kind_side(seg)
    stream = SensorStream(
        label=seg,
        time=stamps[keep],
        acc=measured["acc"][keep],
        gyr=measured["gyr"][keep],
        mag=measured["mag"][keep],
        serial=f"SIM-{seed}-{i:02d}",
        vendor="motionlab-sim",
        segment=seg,
        side=side,
        source_units={"acc": "m/s^2", "gyr": "rad/s", "mag": "uT"},
        attrs={"simulated": True, "rate_hz": rate_hz, "gyr_sampling": gyr_sampling},
    )
    info = {
        "segment": seg,
        "mounting": mount.q_mount,
        "site": mount.site,
        "sample_time": t_true[keep],
        "clock_offset_s": clock.offset,
        "clock_drift": clock.drift,
        "jitter_s": clock.jitter_s,
        "dropped": int((~keep).sum()),
        "soft_iron": soft,
        "hard_iron": hard,
        "carried_field_uT": carried,
        "wobble_deg": float(np.degrees(mount.wobble.amplitude)),
    }
    for ch in ("gyr", "acc", "mag"):
        info[f"{ch}_bias"] = biases[ch][keep]
        info[f"{ch}_matrix"] = draws[ch].matrix
    return stream, info
