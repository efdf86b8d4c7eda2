"""A hip's heading tied by straight walking (``segments.heading.walk_anchors``): the thigh swings
about its own z, which stays across the walking direction as the pelvis's z does, so a walk
ties the thigh's heading to the pelvis's wherever it goes straight, and a long walk's hips no
longer drift away from the stand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.segments import heading, unheld_headings
from motionlab.simulate import simulate

RATE = 100.0
Z = np.array([0.0, 0.0, 1.0])


def _walk(seconds: float, drift_deg_s: float, rotation_deg: float, turn_at: float | None = None,
          spin: bool = False):  # fmt: skip
    """Segment orientations (ISB segment frames, earth z up) of a pelvis walking straight ahead
    (turning 180° in 2 s at ``turn_at``) and a thigh swinging ±25° at 1 Hz about its z, turned
    about the vertical by the hip's rotation (``rotation_deg`` ± 5° at the stride frequency)
    and, in its own 6-D earth frame, by a heading that drifts ``drift_deg_s``. ``spin``: the
    thigh turns ±60° about its long axis instead of swinging."""
    t = np.arange(0.0, seconds, 1 / RATE)
    psi = np.zeros_like(t)
    if turn_at is not None:
        psi = np.pi * np.clip((t - turn_at) / 2.0, 0.0, 1.0)
    up_to_earth = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)  # segment y up
    q_pelvis = rot.mul(rot.from_axis_angle(Z, psi), np.broadcast_to(up_to_earth, (len(t), 4)))
    swing = np.radians(25.0) * np.sin(2 * np.pi * t)
    turn = np.radians(rotation_deg + 5.0 * np.sin(2 * np.pi * t + 1.0))
    y = np.array([0.0, 1.0, 0.0])
    if spin:
        hip = rot.from_axis_angle(y, np.radians(60.0) * np.sin(2 * np.pi * t))
    else:
        hip = rot.mul(rot.from_axis_angle(y, turn), rot.from_axis_angle(Z, swing))
    q_thigh = rot.mul(q_pelvis, hip)
    drift = np.radians(drift_deg_s) * t
    return t, q_pelvis, rot.mul(rot.from_axis_angle(Z, -drift), q_thigh), drift


def test_straight_walking_measures_the_drift_plus_the_hips_mean_rotation():
    t, qp, qd, drift = _walk(60.0, 0.3, 4.0)
    times, deltas = heading.walk_anchors(t, qp, qd)
    assert len(times) > 40
    # δ turns the thigh back onto the pelvis: the drift, and the mean hip rotation with it
    expected = np.interp(times, t, drift) - np.radians(4.0)
    np.testing.assert_allclose(np.degrees(deltas - expected), 0.0, atol=0.5)
    qp = qp.copy()
    qp[1000:1100] = np.nan  # a gap in the pelvis's orientations: only its windows are lost
    gap_times, _ = heading.walk_anchors(t, qp, qd)
    assert len(gap_times) >= len(times) - 6 and gap_times[-1] == times[-1]


def test_the_stand_ties_the_walks_mean_hip_rotation_back_to_zero():
    """With a pose anchor at the stand (δ 0: no drift yet), the walk's anchors are put on its
    track: the hip's mean walking rotation stays in the angles, the drift goes."""
    t, qp, qd, drift = _walk(100.0, 0.3, 4.0)
    times, deltas = heading.walk_anchors(t, qp, qd)
    offset = heading.pose_offset(np.array([0.0]), np.array([0.0]), times, deltas)
    assert offset == pytest.approx(np.radians(4.0), abs=np.radians(0.8))
    np.testing.assert_allclose(
        np.degrees(deltas + offset - np.interp(times, t, drift)), 0.0, atol=1.0
    )
    far = heading.pose_offset(np.array([-100.0]), np.array([0.0]), times, deltas)
    assert far is None  # no walking near a pose: nothing ties the walk to it
    joined_times, joined = heading.with_walk_anchors([0.0], [0.0], times, deltas)
    assert joined_times[0] == 0.0 and np.all(joined_times[1:] > heading.WALK_FAR_S)
    np.testing.assert_allclose(  # the pose's own tie near it, the walk's (on its track) beyond
        np.degrees(joined[1:] - np.interp(joined_times[1:], t, drift)), 0.0, atol=1.0
    )
    near = times < heading.WALK_FAR_S
    assert heading.with_walk_anchors([0.0], [0.0], times[near], deltas[near]) is None


def test_turns_standing_and_a_thigh_that_is_not_swinging_give_no_anchors():
    t, qp, qd, _ = _walk(20.0, 0.0, 0.0, turn_at=9.0)
    times, _ = heading.walk_anchors(t, qp, qd)
    assert len(times) and not np.any((times > 8.5) & (times < 11.5))  # the turn left out
    t, qp, qd, _ = _walk(20.0, 0.0, 0.0, spin=True)
    assert len(heading.walk_anchors(t, qp, qd)[0]) == 0  # a thigh turning about its long axis
    still = np.broadcast_to(qd[:1], qd.shape)
    assert len(heading.walk_anchors(t, qp, still)[0]) == 0  # standing


def test_a_thigh_gyroscope_drifting_during_a_long_walk_is_tied_back_by_the_walk():
    """A stand, 3.1 min of walking and a stand, the right thigh's gyroscope bias about its long
    axis growing from 0 to 2 °/s over the walk (in 6-D the swing makes only part of it
    observable). The stands alone tie the hip's heading at both ends, linearly in between, and
    left it 2.5° (flexion), 8.0° (adduction) and 26.9° (rotation) off mid-walk; the walk ties
    it wherever it goes straight a minute or more from the stands: 2.1 / 0.5 / 0.3°. (On the
    30-min walk of docs/kinematics.md, with its stand the only pose, the walk's ties kept the
    right hip within 0.6-1.8° per 5 min where the stand alone left 4-36° of flexion and
    29-154° of rotation.)"""
    proto = load_protocol("walk")
    session, truth = simulate(proto, 200.0, 1, "typical", rate_hz=50.0)
    walk = next(s for s in truth.steps if s["phase"] == "task")
    s = session.sensors["thigh_r"]
    grows = np.clip((s.time - walk["start_s"]) / (walk["end_s"] - walk["start_s"]), 0.0, 1.0)
    session.sensors["thigh_r"] = dataclasses.replace(
        s, gyr=s.gyr + np.radians(2.0) * grows[:, None] * np.array([0.0, 1.0, 0.0])
    )
    prepare_sensors(session)
    analyse(session, PipelineOptions(proto, progress=False))
    cal = session.results.calibration
    for hip in ("hip_r", "hip_l"):
        tie = cal.headings.joints[hip]
        assert tie.source == "walk" and len(tie.times) > 30  # every straight second 30 s out
    # the pose ties the first and last minute, the walk the rest: never a minute from an anchor
    assert max(unheld_headings(session, proto, cal.headings).values()) < 60.0
    # mid-walk, farthest from both stands (each IMU's own clock is within ~10 ms of the
    # truth's: a fraction of a degree here)
    table = session.results.angles.columns()
    middle = 0.5 * (walk["start_s"] + walk["end_s"])
    mid = np.abs(table["time_s"] - middle) < 20.0
    for col, limit in (("hip_r_flexion_deg", 3.0), ("hip_r_adduction_deg", 2.0),
                       ("hip_r_rotation_deg", 3.0)):  # fmt: skip
        err = table[col] - np.interp(table["time_s"], truth.time, truth.joint_angles[col])
        assert np.sqrt(np.nanmean(err[mid] ** 2)) < limit, col
