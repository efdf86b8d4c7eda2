"""Synthetic sessions with an exact truth: ``simulate(protocol, duration, seed)``.

The subject (:mod:`.body`) performs the protocol's calibration steps and tasks (:mod:`.timeline`,
:mod:`.motion`, :mod:`.tasks`) as smooth analytic motion; each protocol segment carries an IMU
whose ideal signals (:mod:`.signals`) pass through a sensor error model (:mod:`.errors`);
optionally optical markers are recorded (:mod:`.markers`). The truth (:mod:`.truth`) holds
segment and sensor orientations, joint angles in the DESIGN conventions, biases, clocks, steps and
marker layouts. Random draws come from independent streams keyed by ``(seed, purpose, sensor)``,
so the motion and mountings of one seed are the same under every preset.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from motionlab import __version__
from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import decompose_joint
from motionlab.kinematics.joint_types import JOINT_TYPES, angle_columns
from motionlab.protocol import Protocol, load_protocol
from motionlab.session import SensorStream, Session
from motionlab.simulate import markers as _markers
from motionlab.simulate.body import SEGMENTS, Body, kind_side
from motionlab.simulate.chain import segment_poses
from motionlab.simulate.errors import (
    Clock,
    Preset,
    apply_channel,
    draw_channel,
    draw_clock,
    dropped,
    get_preset,
    sample_times,
    soft_hard_iron,
)
from motionlab.simulate.motion import group, smoothstep
from motionlab.simulate.signals import (
    MagneticField,
    Mount,
    Wobble,
    _poses,
    ideal_imu,
    sensor_pose,
)
from motionlab.simulate.timeline import Timeline, plan
from motionlab.simulate.truth import Truth, load_truth, save_truth, write_truth_csv

__all__ = ["simulate", "Truth", "load_truth", "save_truth", "write_truth_csv", "MagneticField"]

PROVENANCE_TIME = "2000-01-01T00:00:00+00:00"  # fixed, so that the same seed gives the same bytes
_STREAMS = {"mount": 1, "sensor": 2, "markers": 3, "field": 4}


def _rng(seed: int, purpose: str, index: int = 0) -> np.random.Generator:
    return np.random.default_rng([seed, _STREAMS[purpose], index])


def _random_rotation(rng: np.random.Generator, max_deg: float) -> np.ndarray:
    axis = rng.normal(size=3)
    return rot.from_axis_angle(axis, np.radians(rng.uniform(0.0, max_deg)))


def _mount(body: Body, protocol: Protocol, seg: str, i: int, seed: int, preset: Preset,
           max_deg: float, impacts: np.ndarray) -> Mount:  # fmt: skip
    rng = _rng(seed, "mount", i)
    nominal = rot.from_matrix(protocol.segments[seg].nominal_mounting())
    kind, _ = kind_side(seg)
    scale = 1.0 if kind in ("thigh", "shank", "foot") else 0.5
    return Mount(
        segment=seg,
        q_mount=rot.mul(_random_rotation(rng, max_deg), nominal),
        site=body.sensor_site(seg) + rng.uniform(-0.01, 0.01, 3),
        wobble=Wobble(
            amplitude=np.radians(preset.wobble_deg) * scale,
            axis=rot.normalize(rng.normal(size=3)),
            freq_hz=rng.uniform(10.0, 16.0),
            impacts=impacts,
        ),
    )


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
    field, gravity
        Magnetic field model (default 50 µT, dip 60°) and gravity (m/s²).
    optical
        Camera system (rate, clock, lab frame, noise); default from the preset.

    Returns
    -------
    (Session, Truth)
        The session with one SI :class:`SensorStream` per protocol segment, and the truth.
    """
    protocol = protocol if isinstance(protocol, Protocol) else load_protocol(protocol)
    preset = get_preset(preset)
    if not duration > 0 or not rate_hz > 0:
        raise InputError("duration and rate must be positive", where="--duration/--rate")
    for seg in protocol.segments:
        if seg not in SEGMENTS:
            body_segments = ", ".join(SEGMENTS)
            raise InputError(
                f"segment {seg!r} is not in the simulator's body model",
                protocol.path,
                f"segments.{seg}",
                f"use one of {body_segments}",
            )
    body = Body(height)
    timeline = plan(protocol, body, duration, seed, rest_s=rest_s, calibration=calibration)
    field = _field(field, preset, timeline, body, seed)
    t = np.arange(int(np.floor(duration * rate_hz + 1e-9)) + 1) / rate_hz
    ch = timeline.channels(t)
    poses = _poses(body, timeline, t, tuple(protocol.segments))
    truth = Truth(
        time=t,
        segments={k: {"orientation": q, "position": p} for k, (q, p) in poses.items()},
        joint_angles=_joint_truth(protocol, ch, poses, body),
        steps=timeline.steps(),
    )
    session = Session()
    carried = _rng(seed, "field", 1).integers(len(protocol.segments))
    for i, seg in enumerate(protocol.segments):
        stream, info = _sensor(body, timeline, protocol, seg, i, seed, preset, rate_hz, duration,
                               field, gravity, mounting_max_deg, i == carried)  # fmt: skip
        q_grid, p_grid = sensor_pose(body, timeline, info.pop("mount"), tuple(poses))(t)
        truth.sensors[seg] = {"orientation": rot.make_continuous(q_grid), "position": p_grid}
        truth.sensors[seg] |= info
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
        "gravity_m_s2": gravity,
        "earth_field_uT": field.earth,
        "magnetic_dipoles": [{"position_m": p, "moment_Am2": m} for p, m in field.dipoles],
        "error_model": asdict(preset),
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


def _sensor(body, timeline, protocol, seg, i, seed, preset, rate_hz, duration, field, gravity,
            max_deg, carries_field):  # fmt: skip
    """One IMU: its recorded stream and its truth entries."""
    mount = _mount(body, protocol, seg, i, seed, preset, max_deg, timeline.impacts())
    rng = _rng(seed, "sensor", i)
    clock = draw_clock(preset.timing, rng)
    stamps, t_true = sample_times(clock, rate_hz, duration, rng)
    shared = tuple(protocol.segments) if clock == Clock(jitter_s=0.0) else ()  # same instants
    ideal = ideal_imu(body, timeline, mount, t_true, field, gravity, shared)
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
        attrs={"simulated": True, "rate_hz": rate_hz},
    )
    info = {
        "mount": mount,
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
