"""Calibration, heading anchors, task blocks and metrics on simulated sessions with known truth.

Small one-sided protocols keep the simulations short. Each simulated session is fused once
(:func:`motionlab.stages.fuse`, as a user would before calibrating) and calibrated from those
orientations; the angles and metrics then read the simulator's true sensor orientations (with,
where a test says so, a 6-D heading offset and drift), so that these tests measure calibration
and metrics, not the fusion filters.
"""

import dataclasses

import numpy as np
import pytest
from protocol_texts import ELBOW_R

from motionlab import rotations as rot
from motionlab import stages
from motionlab.clocksync import synchronise
from motionlab.errors import InputError
from motionlab.kinematics.joint_angles import decompose
from motionlab.kinematics.metrics import session_metrics
from motionlab.kinematics.session_angles import session_angles
from motionlab.protocol import load_protocol
from motionlab.results import FusionEntry, Results
from motionlab.segments import calibrate_segments, streams_of
from motionlab.segments.steps import find_tasks
from motionlab.simulate import simulate

Z = np.array([0.0, 0.0, 1.0])

KNEE = """name: knee_r
segments:
  thigh_r: {side: r, sensor_axes: [x, y, z]}
  shank_r: {side: r, sensor_axes: [-z, y, x]}
calibration:
  - {name: standing, kind: static, pose: standing, duration_s: 4,
     vertical_axis: {thigh_r: y, shank_r: y}}
  - {name: sitting, kind: static, pose: sitting, duration_s: 4, vertical_axis: {thigh_r: x}}
  - {name: knee_flexion_r, kind: functional, pose: sitting, axis: {shank_r: -z},
     repetitions: 3, duration_s: 9 %(method)s}
%(extra)s  - {name: hip_flexion_r, kind: functional, pose: standing, axis: {thigh_r: z, shank_r: z},
     repetitions: 3, duration_s: 9, optional: true}
joints:
  knee_r: {type: knee, proximal: thigh_r, distal: shank_r, side: r}
tasks:
  - {name: gait, kind: gait, duration_s: 25}
  - {name: squat, kind: squat, repetitions: 3, duration_s: 12}
metrics: [rom, cycles, cross_talk, varus_thrust, stance_rotation]
thresholds: {varus_thrust_deg: 2.0}
"""


def write(tmp, name, text):
    path = tmp / f"{name}.yaml"
    path.write_text(text)
    return load_protocol(path)


def simulate_fused(protocol, **kwargs):
    """A simulated session fused as a user would before calibrating (:func:`stages.fuse`, which
    also fills the dropped samples' gaps); ``truth.sensors[label]["stamps"]`` keeps the
    simulated time stamps of ``sample_time``."""
    session, truth = simulate(protocol, **kwargs)
    for label, s in session.sensors.items():
        truth.sensors[label]["stamps"] = s.time
    stages.fuse(session)
    return session, truth


def true_fusion(session, truth, heading=None, clocks=None):
    """A copy of ``session`` whose ``results.fusion`` are the true sensor orientations at its
    samples (optionally 6-D-like headings); the fixture's own fusion stays for the other tests.
    A sample's true time is from its stamp in ``clocks`` (a session with the same samples on the
    simulated clocks; default ``session``), between the simulated ones for a filled gap's."""
    fused = {}
    for label in session.sensors:
        tr = truth.sensors[label]
        t = np.interp((clocks or session).sensors[label].time, tr["stamps"], tr["sample_time"])
        q = rot.resample(truth.time, tr["orientation"], t)
        if heading is not None:
            q = rot.mul(rot.from_axis_angle(Z, heading(label, t)), q)
        fused[label] = FusionEntry("truth", q)
    return dataclasses.replace(session, results=dataclasses.replace(session.results, fusion=fused))


def mount_error_deg(truth, cal, seg):
    return float(np.degrees(rot.angle(rot.mul(truth.sensors[seg]["mounting"],
                                              cal.segments[seg].mounting))))  # fmt: skip


@pytest.fixture(scope="module")
def knee(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("knee")
    protocol = write(tmp, "knee_r", KNEE % {"method": "", "extra": ""})
    session, truth = simulate_fused(protocol, duration=110, seed=2, rest_s=5.0)
    return tmp, protocol, session, truth


@pytest.fixture(scope="module")
def elbow(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("elbow")
    protocol = write(tmp, "elbow_r", ELBOW_R)
    session, truth = simulate_fused(protocol, duration=70, seed=1, rest_s=5.0)
    return tmp, protocol, session, truth


def test_knee_steps_mountings_and_joint_movement_axis(knee):
    _, protocol, session, truth = knee
    cal = calibrate_segments(session, protocol)
    for step in truth.steps:
        found = cal.steps.get(step["name"])
        if step["kind"] == "functional":
            assert abs(found[0] - step["start_s"]) < 2.5 and abs(found[1] - step["end_s"]) < 2.5
        elif step["phase"] == "calibration":  # a pose: the still block around it, trimmed
            assert found[0] < step["start_s"] + 1 and found[1] > step["end_s"] - 1
    assert mount_error_deg(truth, cal, "thigh_r") < 1.5
    assert mount_error_deg(truth, cal, "shank_r") < 1.5
    shank = cal.segments["shank_r"]
    # the seated knee flexion turns the shank about the screw-home-coupled axis: left out,
    # since the straight-leg hip flexion gives the z axis with the knee still
    assert shank.axes["knee_flexion_r"].used is False
    assert shank.axes["hip_flexion_r"].secondary is True
    assert shank.method == "primary_secondary"
    assert shank.quality.hinge_check_deg["knee_flexion_r"] < 3.0


def test_knee_flexion_axis_alone_carries_the_screw_home_bias(knee):
    tmp, _, session, truth = knee
    protocol = write(tmp, "no_hip", KNEE.split("  - {name: hip_flexion_r")[0] % {
        "method": "", "extra": ""} + KNEE.split("optional: true}\n")[1])  # fmt: skip
    cal = calibrate_segments(session, protocol)
    assert cal.segments["shank_r"].axes["knee_flexion_r"].used is True
    # the sim's tibia rotates 0.12°/° with flexion: the functional axis is several degrees off
    assert 3.0 < mount_error_deg(truth, cal, "shank_r") < 15.0


def test_hinge_axis_method(knee):
    tmp, _, session, truth = knee
    text = KNEE % {"method": ", axis_method: hinge", "extra": ""}
    protocol = write(tmp, "hinge", text.split("  - {name: hip_flexion_r")[0] + text.split(
        "optional: true}\n")[1])  # fmt: skip
    assert protocol.calibration[2].axis_method == "hinge"
    cal = calibrate_segments(session, protocol)
    shank = cal.segments["shank_r"].axes["knee_flexion_r"]
    assert shank.method == "hinge" and shank.used is True
    # seated, the thigh is still: Seel's constraint leaves its axis free, so it gets none
    assert "knee_flexion_r:hinge" not in cal.segments["thigh_r"].axes
    # the hinge axis is the same (screw-home coupled) axis the SVD finds
    assert shank.hinge_check_deg < 2.0
    true_z = rot.rotate(rot.conj(truth.sensors["shank_r"]["mounting"]), -Z)
    assert 3.0 < np.degrees(np.arccos(shank.sensor_axis @ true_z)) < 15.0


def test_bad_axis_method_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="axis_method"):
        write(tmp_path, "bad", KNEE % {"method": ", axis_method: seel", "extra": ""})


def test_knee_flexion_done_twice_is_ambiguous(knee):
    tmp, _, _, _ = knee
    again = ("  - {name: knee_flexion_again, kind: functional, pose: sitting, "
             "axis: {shank_r: -z}, repetitions: 3, duration_s: 9}\n")  # fmt: skip
    twice = write(tmp, "twice", KNEE % {"method": "", "extra": again})
    session, _ = simulate(twice, duration=90, seed=4, rest_s=5.0)
    once = write(tmp, "once", KNEE % {"method": "", "extra": ""})
    with pytest.raises(InputError, match="ambiguous: two candidate windows"):
        calibrate_segments(session, once)


def test_heading_offset_and_drift_removed_by_anchors(knee):
    _, protocol, session, truth = knee
    cal = calibrate_segments(session, protocol)
    # 6-D-like: every sensor its own heading, the shank's drifting 0.1°/s during the tasks
    drift = {"thigh_r": (1.0, 0.0), "shank_r": (-2.0, np.radians(0.1))}

    def heading(label, t):
        offset, rate = drift[label]
        return offset + rate * np.clip(t - 50.0, 0.0, None)

    table = session_angles(true_fusion(session, truth, heading), protocol, cal)
    ref = np.interp(table["time_s"], truth.time, truth.joint_angles["knee_r_rotation_deg"])
    squat = (table["time_s"] > truth.step("squat")["start_s"]) & (
        table["time_s"] < truth.step("squat")["end_s"]
    )
    err = table["knee_r_rotation_deg"][squat] - ref[squat]
    assert np.sqrt(np.mean(err**2)) < 1.0  # re-referenced at the rest before the squat
    # the drift is real: with the first anchor only the squat would be ~4° off
    assert np.degrees(heading("shank_r", np.array([95.0]))[0] + 2.0) > 4.0


def test_task_blocks_found_in_order(knee):
    _, protocol, session, truth = knee
    cal = calibrate_segments(session, protocol)
    after = max(v[1] for v in cal.steps.values() if v)
    tasks = find_tasks(streams_of(session, protocol), protocol, after_s=after)
    for name in ("gait", "squat"):
        step = truth.step(name)
        assert abs(tasks[name][0] - step["start_s"]) < 2.5
        assert abs(tasks[name][1] - step["end_s"]) < 2.5


def test_metrics_agree_with_the_truth(knee):
    """Metrics on the clocks the pipeline gives them (``run`` synchronises the sensors first).

    Unsynchronised, the shank's clock is 26 ms off the thigh's here, and that alone put the
    stance rotation range 0.6-0.9° off per stride with the former gait templates, 0.7-1.2° with
    the real-like terminal swing (on the sensors' true clocks: ≤ 0.2° with either)."""
    _, protocol, unsynced, truth = knee
    session = dataclasses.replace(unsynced, sensors=dict(unsynced.sensors), results=Results())
    (fit,) = synchronise(session, protocol)
    assert fit.status == "applied" and abs(fit.offset_s) > 0.02
    stages.fuse(session)  # on the synchronised clocks, as run does
    session.results.calibration = calibrate_segments(session, protocol)
    session = true_fusion(session, truth, clocks=unsynced)
    blocks = {n: (truth.step(n)["start_s"], truth.step(n)["end_s"]) for n in ("gait", "squat")}
    m = session_metrics(session, protocol, blocks)
    squat = m.joints["squat"]["knee_r_flexion_deg"]
    assert squat.repetitions == 3
    sel = (truth.time >= blocks["squat"][0]) & (truth.time <= blocks["squat"][1])
    true_flex = truth.joint_angles["knee_r_flexion_deg"][sel]
    assert squat.rom_deg == pytest.approx(np.ptp(true_flex), abs=1.0)
    assert squat.cycle_max_mean_deg == pytest.approx(true_flex.max(), abs=1.0)
    gait = m.gait["gait"]["knee_r"]
    # the strides the gait analysis keeps: 0.9 strides/s over 33 s less the speed ramps at both
    # ends (24), and of these the simulated walker's oval track leaves out the bends' (a heading
    # change over 20° a stride, 9 here)
    assert 12 <= gait.strides <= 20
    stride_s = np.diff(m.joints["gait"]["knee_r_flexion_deg"].cycle_start_s)
    assert np.median(stride_s) == pytest.approx(1 / 0.9, abs=0.02)
    # thrust and stance rotation against the same stances (heel strike → toe-off) of the truth
    t = truth.time
    add = truth.joint_angles["knee_r_adduction_deg"]
    rotation = truth.joint_angles["knee_r_rotation_deg"]
    thrust, rot_range = [], []
    for hs, to in zip(gait.heel_strike_s, gait.toe_off_s, strict=True):
        stance = (t >= hs) & (t <= to)
        thrust.append(add[stance].max() - add[stance][0])
        rot_range.append(np.ptp(rotation[stance]))
    # the calibrated adduction carries ~3 % of the flexion (≈1° over the 33° a stance adds from
    # heel strike to toe-off; 0.4-1.1° here)
    assert np.abs(gait.varus_thrust_deg - thrust).max() < 2.0
    assert np.abs(gait.stance_rotation_range_deg - rot_range).max() < 1.0
    # stance share of the stride (the simulated shank has no heel-strike impact: about 40 %)
    assert 0.35 < np.median((gait.toe_off_s - gait.heel_strike_s) * 0.9) < 0.65
    ct = m.cross_talk["knee_flexion_r"]["knee_r"]
    assert ct.on_axis == "flexion" and ct.on_axis_rom_deg > 60
    assert ct.off_axis["adduction"].rom_deg < ct.off_axis["adduction"].nominal_rom_deg


def test_elbow_forearm_frame_keeps_the_carrying_angle(elbow):
    _, protocol, session, truth = elbow
    cal = calibrate_segments(session, protocol)
    fore = cal.segments["forearm_r"]
    assert fore.method == "primary_secondary"
    assert fore.axes["elbow_flexion_r"].used is False
    assert mount_error_deg(truth, cal, "forearm_r") < 2.0
    assert mount_error_deg(truth, cal, "upperarm_r") < 1.5
    heading = lambda label, t: 0.5 if label == "forearm_r" else -1.0  # noqa: E731
    table = session_angles(true_fusion(session, truth, heading), protocol, cal)
    standing = (table["time_s"] > 6) & (table["time_s"] < 8)
    assert table["elbow_r_carrying_deg"][standing].mean() == pytest.approx(10.0, abs=1.5)
    ref = np.interp(table["time_s"], truth.time, truth.joint_angles["elbow_r_flexion_deg"])
    error = table["elbow_r_flexion_deg"] - ref
    assert np.isnan(error).mean() < 0.05  # none inside the simulated packet losses
    assert np.sqrt(np.nanmean(error**2)) < 1.0


def test_truth_angles_match_decomposition(elbow):
    _, _, _, truth = elbow
    seg = truth.segments
    angles = np.degrees(decompose(seg["upperarm_r"]["orientation"],
                                  seg["forearm_r"]["orientation"], "elbow", "r"))  # fmt: skip
    assert np.allclose(angles[:, 0], truth.joint_angles["elbow_r_flexion_deg"], atol=1e-6)


def test_a_shank_strapped_half_a_turn_round_takes_its_flexion_axis_sign_from_anatomy():
    """The knee protocol with sensors strapped any way round (seed 5): the left shank's sensor
    sits half a turn about the long axis from where the hint puts it, so gravity and the seated
    knee flexion's axis (compared without its sign) agree with the hint, which then signed the
    flexion axis the wrong way round: the shank's frame 171° off, the knee reading 180° less
    its flexion (39° RMS in gait), graded determined. The knee's hinge fit signs the axis by
    anatomy (a knee flexes one way) and overrules the hint."""
    from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors

    knee = load_protocol("knee")
    session, truth = simulate(knee, 200.0, seed=5, mounting="random", rate_hz=50.0)
    prepare_sensors(session)
    analyse(session, PipelineOptions("knee", progress=False))
    cal = session.results.calibration
    for seg in ("shank_l", "shank_r"):
        d = rot.mul(truth.sensors[seg]["mounting"], cal.segments[seg].mounting)
        assert np.degrees(2 * np.arccos(min(1.0, abs(d[0])))) < 15.0
    assert cal.segments["shank_l"].hint_contradicted
