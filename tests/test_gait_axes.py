"""A knee's flexion axis from a stand and a walk (motionlab/segments/gait_axes.py), and what
bad recordings make of it: no straight walking, no stand, a sensor on the other leg, thigh and
shank swapped, a sensor upside down."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab import stages
from motionlab.errors import InputError
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.segments import gait_axes, movement, streams_of, walk_checks
from motionlab.segments.sensors import sensor_orientation
from motionlab.segments.steps import find_steps
from motionlab.simulate import simulate
from motionlab.simulate.errors import get_preset

Z = np.array([0.0, 0.0, 1.0])


def _one_clock():
    preset = get_preset("typical")
    timing = dataclasses.replace(preset.timing, clock_offset_sigma_s=0.0, clock_drift_sigma=0.0)
    return dataclasses.replace(preset, timing=timing)


@pytest.fixture(scope="module")
def walk():
    """A stand, then 35 s of walking, sensors at random places and orientations, soft tissue."""
    proto = load_protocol("walk")
    session, truth = simulate(proto, 40.0, 4, _one_clock(), mounting="random", soft_tissue="motion")
    prepare_sensors(session)
    analyse(session, PipelineOptions(proto, progress=False, clock_sync=False))
    return proto, session, truth


def _rmse(session, truth, column: str) -> float:
    ang = session.results.angles.columns()
    step = truth.step("walk")
    w = (ang["time_s"] > step["start_s"] + 3) & (ang["time_s"] < step["end_s"] - 3)
    err = ang[column] - np.interp(ang["time_s"], truth.time, truth.joint_angles[column])
    return float(np.sqrt(np.mean(err[w] ** 2)))


def _side(session, seg: str):
    s = session.sensors[seg]
    return s.time, s.gyr, sensor_orientation(session, seg)


def test_walk_determines_both_knees_flexion_and_not_their_other_planes(walk):
    proto, session, truth = walk
    cal = session.results.calibration
    for side in "rl":
        fit = cal.hinges[f"knee_{side}"]
        assert fit.method == "principal" and fit.verdict == "determined", fit.reasons
        # the relative sign from the rates, or (the pelvis's obliquity tilting the swings) from
        # the anatomy: the knee flexes one way from its straight stand
        assert fit.sign == "anatomy" and fit.relative_sign in ("measured", "anatomy")
        assert fit.witness_deg < 12.0 and fit.consistency_deg < 5.0
        grades = cal.grades[f"knee_{side}"].grades
        assert grades[0] == "determined"
        # the axis is known to 5° at best: 60° of flexion can put 5° into the other planes
        assert grades[1] != "determined" and grades[2] != "determined"
        assert _rmse(session, truth, f"knee_{side}_flexion_deg") < 2.5


def test_the_principal_axis_is_perpendicular_to_the_long_axis_and_agrees_with_its_parts(walk):
    proto, session, _ = walk
    cal = session.results.calibration
    t, g1, g2, q1, q2, speed = movement.shared_movement(
        "knee_r", _side(session, "thigh_r"), _side(session, "shank_r")
    )
    stand = cal.steps["standing"]
    ref = (t >= stand[0]) & (t <= stand[1])
    axes = gait_axes.principal_axes(t, g1, g2, q1, q2, ref, speed > 0.3)
    assert abs(axes.axis_proximal @ axes.long_proximal) < 1e-9
    assert abs(axes.axis_distal @ axes.long_distal) < 1e-9
    assert axes.dominance < 0.5 and axes.consistency_deg < 5.0
    fit = cal.hinges["knee_r"]
    assert abs(abs(axes.axis_proximal @ fit.axis_proximal) - 1.0) < 1e-3


def test_a_walk_too_short_to_compare_its_parts_is_weak_at_best(walk):
    """Under ``MIN_SAMPLES // 2`` samples of swing in a part (a real DOT walk in circles,
    172 samples outside its turns, read ``determined`` with its parts never compared): the
    consistency is unmeasured and the knee ``weak``, saying why; the same walk's swings in
    full are ``determined``."""
    proto, session, _ = walk
    t, g1, g2, q1, q2, speed = movement.shared_movement(
        "knee_r", _side(session, "thigh_r"), _side(session, "shank_r")
    )
    stand = session.results.calibration.steps["standing"]
    ref = (t >= stand[0]) & (t <= stand[1])
    swings = speed > 0.3
    few = swings & (np.cumsum(swings) <= 180)  # the first 180 samples of swing: 45 per part
    axes = gait_axes.principal_axes(t, g1, g2, q1, q2, ref, few)
    assert axes is not None and np.isnan(axes.consistency_deg)
    reasons: list[str] = []
    assert gait_axes._verdict(axes, 0.0, reasons, hinted=False) == "weak"
    assert "too little straight walking to check the axis between its parts" in reasons[0]
    full = gait_axes.principal_axes(t, g1, g2, q1, q2, ref, swings)
    assert gait_axes._verdict(full, 0.0, [], hinted=False) == "determined"


def test_a_movement_with_one_part_to_fit_is_not_consistent_by_default():
    """A hinge fit whose movement lies in one of its four parts: nothing to compare it with
    (before: 0°, as consistent as can be); now NaN and ``weak`` at best."""
    axis = np.array([0.0, 0.0, 1.0])
    fits = iter([None, (axis, axis), None, None])
    worst = movement._consistency(400, lambda a, b: next(fits), axis, axis)
    assert np.isnan(worst)
    reasons: list[str] = []
    assert movement._verdict(worst, 0.1, False, reasons, "the axis differs", "one axis") == "weak"
    assert "too little movement" in reasons[0]
    fits = iter([None, (axis, axis), (axis, axis), None])
    assert movement._consistency(400, lambda a, b: next(fits), axis, axis) == 0.0


def test_a_walk_that_only_turns_leaves_the_knee_not_determined(walk):
    """Walking round a tight circle all the time: no straight walking to take the axis from."""
    _, session, truth = walk
    stand = session.results.calibration.steps["standing"]
    spun = []
    for seg in ("thigh_r", "shank_r"):
        t, gyr, q = _side(session, seg)
        turn = rot.from_axis_angle(Z, 0.6 * np.clip(t - stand[1], 0.0, None))  # 0.6 rad/s
        q_new = rot.mul(turn, q)
        rate = 0.6 * (t > stand[1])
        spun.append((t, gyr + rot.rotate(rot.conj(q_new), np.outer(rate, Z)), q_new))
    fit = gait_axes.fit_knee("knee_r", *spun, np.array([0, 0, 1.0]), np.array([0, 0, 1.0]),
                             tuple(stand))  # fmt: skip
    assert fit.verdict == "not determined"
    assert "straight walking" in fit.reasons[0]


def test_a_walk_without_a_stand_is_refused_in_one_line(walk):
    proto, session, truth = walk
    stand_end = session.results.calibration.steps["standing"][1]
    walk_end = truth.step("walk")["end_s"]
    cut = {}
    for seg, (t, acc, gyr) in streams_of(session, proto).items():
        keep = (t > stand_end + 1.0) & (t < walk_end - 1.0)
        cut[seg] = (t[keep], acc[keep], gyr[keep])
    with pytest.raises(InputError) as exc:
        find_steps(cut, proto)
    assert "'standing' (static) not found" in str(exc.value)
    assert "'standing' needs the standing pose held still for at least 2.5 s" in str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_stand_a_little_too_short_is_said_exactly(walk):
    """A short stand is refused, and the line says how long the rest was to two decimals (to
    one, a 2.46-s rest read "2.5 s" beside "needs at least 2.5 s")."""
    proto, session, truth = walk
    walk_start, walk_end = truth.step("walk")["start_s"], truth.step("walk")["end_s"]
    cut = {}
    for seg, (t, acc, gyr) in streams_of(session, proto).items():
        keep = (t > walk_start - 1.5) & (t < walk_end - 1.0)
        cut[seg] = (t[keep], acc[keep], gyr[keep])
    with pytest.raises(InputError) as exc:
        find_steps(cut, proto)
    text = str(exc.value)
    assert "'standing' (static) not found" in text and "\n" not in text
    longest = float(text.split("(the longest rest is ")[1].split(" s)")[0])
    assert 1.0 < longest < 2.5


def _refused_as_mapped(proto, session, segments: dict[str, str]) -> str:
    """The one line the calibration refuses ``session`` with when each sensor labelled as a key
    of ``segments`` is mapped to its value's segment (and side) instead."""
    swapped = copy.deepcopy(session)
    for label, seg in segments.items():
        swapped.sensors[label].segment, swapped.sensors[label].side = seg, seg[-1]
    with pytest.raises(InputError) as exc:
        stages.calibrate(swapped, proto, force=True)
    line = str(exc.value)
    assert "\n" not in line and "sensor map" in line
    return line


def test_shanks_swapped_between_the_legs_are_refused_naming_them(walk):
    """Each shank's sensor mapped to the other leg: the pelvis is pushed towards the leg whose
    shank swings (:mod:`motionlab.segments.walk_checks`), so the swap shows in one line naming
    both shanks' sensors, before any knee is graded."""
    proto, session, _ = walk
    line = _refused_as_mapped(proto, session, {"shank_r": "shank_l", "shank_l": "shank_r"})
    assert "look swapped left for right" in line
    assert "shank_r's sensor shank_l" in line and "shank_l's sensor shank_r" in line
    corr = float(line.split("(correlation ")[1].split(";")[0])
    assert corr < walk_checks.SIDES_CORR


def test_legs_swapped_left_for_right_are_refused_and_the_map_as_made_is_not(walk):
    """Thigh and shank of each leg mapped to the other side: every knee's fit holds and its
    flexion is right, but every finding would be told of the other leg. The pelvis's sway
    against the shanks' swing says so (correlation negative); the map as made gives +0.5 or
    more (simulated walks +0.56 to +0.94, the real walk +0.50)."""
    proto, session, _ = walk
    streams = streams_of(session, proto)
    cal = session.results.calibration
    after = cal.steps["standing"][1]
    corr, seconds = walk_checks.sway_swing_correlation(
        session, streams, np.asarray(cal.segments["pelvis"].mounting, float), after
    )
    assert corr > 0.4 and seconds > 15.0
    other = {"thigh_r": "thigh_l", "thigh_l": "thigh_r", "shank_r": "shank_l", "shank_l": "shank_r"}
    line = _refused_as_mapped(proto, session, other)
    assert "the legs' sensors look swapped left for right" in line


def test_thigh_and_shank_swapped_on_one_leg_are_refused_in_one_line(walk):
    """The right thigh's and shank's sensors mapped the wrong way round: the knee's flexion
    looks right (the same rotation, inverted), but the hip would be the hip and knee together and
    the gait events would come from the thigh. The thigh turning faster than the shank says so."""
    proto, session, _ = walk
    t, g1, g2, q1, q2, speed = movement.shared_movement(
        "knee_r", _side(session, "thigh_r"), _side(session, "shank_r")
    )
    stand = session.results.calibration.steps["standing"]
    ref = (t >= stand[0]) & (t <= stand[1])
    ratio = gait_axes.principal_axes(t, g1, g2, q1, q2, ref, speed > 0.3).speed_ratio
    assert 0.3 < ratio < gait_axes.SWING_SPEED_RATIO[0]  # as on real walks: 0.49-0.64
    line = _refused_as_mapped(proto, session, {"thigh_r": "shank_r", "shank_r": "thigh_r"})
    assert "look swapped" in line
    assert "thigh_r's sensor shank_r" in line and "shank_r's sensor thigh_r" in line
    said = float(line.split(" turns ")[1].split(" times")[0])
    assert said > gait_axes.SWING_SPEED_RATIO[1] and abs(said * ratio - 1.0) < 0.15


def test_the_swap_check_is_for_a_stand_and_a_walk_only(walk):
    """Other movement turns a thigh faster than its shank (the knee protocol's hip flexions,
    a leg raised with the knee bending): there the ratio is not judged. A randomly mounted
    knee-protocol session (its knee axes' direction from the whole recording) was refused as
    swapped (2.1) while the check looked only for a gait task among the protocol's tasks."""
    assert walk_checks.stand_and_walk(load_protocol("walk"))
    assert not walk_checks.stand_and_walk(load_protocol("knee"))  # hip flexions, squats
    assert not walk_checks.stand_and_walk(load_protocol("lumbar_seated"))  # no task
    proto, session, _ = walk
    stand = tuple(session.results.calibration.steps["standing"])
    z = np.array([0.0, 0.0, 1.0])
    sides = (_side(session, "shank_r"), _side(session, "thigh_r"))  # swapped
    with pytest.raises(gait_axes.SwappedSensors):
        gait_axes.fit_knee("knee_r", *sides, z, z, stand)
    fit = gait_axes.fit_knee("knee_r", *sides, z, z, stand, walking=False)
    assert np.isnan(fit.speed_ratio) and not any("swapped" in r for r in fit.reasons)
    knee = load_protocol("knee")
    sim, _ = simulate(knee, 115.0, 1, "typical", mounting="random")
    prepare_sensors(sim)
    analyse(sim, PipelineOptions(knee, progress=False, clock_sync=False))
    fit = sim.results.calibration.hinges["knee_r"]
    assert fit.method == "principal" and np.isnan(fit.speed_ratio)


def test_a_shank_that_hardly_turns_is_no_swap(walk):
    """A shank sensor that reads noise only (off, or no walk): the ratio was infinite and the
    pair refused as swapped. A segment that hardly turns says nothing about the order."""
    proto, session, _ = walk
    t, g1, g2, q1, q2, speed = movement.shared_movement(
        "knee_r", _side(session, "thigh_r"), _side(session, "shank_r")
    )
    stand = session.results.calibration.steps["standing"]
    ref = (t >= stand[0]) & (t <= stand[1])
    quiet = np.random.default_rng(0).normal(0.0, 0.01, g2.shape)
    axes = gait_axes.principal_axes(t, g1, quiet, q1, q2, ref, speed > 0.3)
    assert np.isnan(axes.speed_ratio)
    assert gait_axes._verdict(axes, 0.0, [], hinted=False) != "determined"


def test_the_axes_come_from_what_both_sensors_recorded():
    """A gap the ingest kept (NaN rates) is bridged for the filters, not counted as swings: a
    shank flat across a 200-s gap beside its walking thigh was refused as "swapped"."""
    t_s = np.arange(0.0, 10.0, 0.01)
    gyr = np.ones((len(t_s), 3))
    gyr[300:500] = np.nan  # 3-5 s lost
    t = np.arange(0.0, 10.0, 0.005)
    got = gait_axes.recorded_on(t, t_s, gyr)
    assert got[(t < 2.99) | (t > 5.01)].all() and not got[(t > 3.01) & (t < 4.99)].any()
    assert not gait_axes.recorded_on(t, t_s, np.full_like(gyr, np.nan)).any()
    kept = np.r_[0:300, 500:1000]  # the same gap as missing samples (a counter jump)
    got = gait_axes.recorded_on(t, t_s[kept], np.ones((len(kept), 3)))
    assert got[(t < 2.99) | (t > 5.01)].all() and not got[(t > 3.01) & (t < 4.99)].any()


def test_a_thigh_turning_about_as_fast_as_its_shank_makes_the_knee_weak(walk):
    """Between a stiff knee (about 1) and a clear swap (above 1.25): weak, saying why."""
    proto, session, _ = walk
    t, g1, g2, q1, q2, speed = movement.shared_movement(
        "knee_r", _side(session, "thigh_r"), _side(session, "shank_r")
    )
    stand = session.results.calibration.steps["standing"]
    axes = gait_axes.principal_axes(t, g1, g2, q1, q2, (t >= stand[0]) & (t <= stand[1]),
                                    speed > 0.3)  # fmt: skip
    reasons: list[str] = []
    assert gait_axes._verdict(axes, 0.0, reasons, hinted=False) == "determined"
    reasons = []
    slow_shank = dataclasses.replace(axes, speed_ratio=1.1)
    assert gait_axes._verdict(slow_shank, 0.0, reasons, hinted=False) == "weak"
    assert "swapped" in reasons[-1]


def test_a_seated_rest_is_no_stand_before_a_walk(walk):
    """In the stand each segment's up lies within 20° of its mean up while walking (here under
    15°). A rest with the thighs horizontal (both thigh sensors turned 80° about a horizontal
    axis over the stand) is no stand: the step search passes it over, saying why, naming the
    thighs, and takes the stand that ends the recording; with that one seated too the step is
    missing."""
    proto, session, truth = walk
    steps = session.results.calibration.steps
    span = tuple(steps["standing"])
    stand = next(s for s in proto.calibration if s.name == "standing")
    streams = streams_of(session, proto)
    tilts = walk_checks.stand_tilts(session, proto, streams, "standing", span)
    assert set(tilts) == {"pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l"}
    assert max(tilts.values()) < 15.0
    assert walk_checks.pose_check(session, proto, streams)(stand, span) is None
    assert walk_checks.pose_check(session, load_protocol("knee"), streams) is None
    seated = copy.deepcopy(session)
    tilt = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.radians(80.0))
    for seg in ("thigh_r", "thigh_l"):
        entry, t = seated.results.fusion[seg], seated.sensors[seg].time
        pose = (t >= span[0] - 1.0) & (t <= span[1] + 0.2)
        entry.quat[pose] = rot.mul(tilt, entry.quat[pose])
    streams = streams_of(seated, proto)
    why = walk_checks.pose_check(seated, proto, streams)(stand, span)
    named = dict(
        part.rsplit(" ", 1) for part in why.split("while walking (")[1].split(";")[0].split(", ")
    )
    assert "is no standing pose" in why and set(named) == {"thigh_r", "thigh_l"}
    assert all(float(deg.rstrip("°")) > walk_checks.STAND_WALK_DEG for deg in named.values())
    # the rest that ends the recording, after the walk, is a stand: it is taken instead
    check = walk_checks.pose_check(seated, proto, streams)
    end = find_steps(streams, proto, pose_check=check)["standing"]
    assert end[0] > truth.step("walk")["end_s"]
    for seg in ("thigh_r", "thigh_l"):  # seated there too: no stand is left
        entry, t = seated.results.fusion[seg], seated.sensors[seg].time
        pose = (t >= end[0] - 1.0) & (t <= end[1] + 1.0)
        entry.quat[pose] = rot.mul(tilt, entry.quat[pose])
    streams = streams_of(seated, proto)
    with pytest.raises(InputError) as err:
        find_steps(streams, proto, pose_check=walk_checks.pose_check(seated, proto, streams))
    assert "'standing' (static) not found" in str(err.value) and why in str(err.value)


def test_a_sensor_upside_down_gives_the_same_knee_angles(walk):
    """The shank sensor turned half a turn on the skin (its data and its fused orientation
    turned with it): the calibration reads its placement from the data, so the angles stay."""
    proto, session, _ = walk
    flipped = copy.deepcopy(session)
    r = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi)  # new sensor frame in the old
    s = flipped.sensors["shank_r"]
    for channel in ("acc", "gyr", "mag"):
        if getattr(s, channel) is not None:
            setattr(s, channel, rot.rotate(rot.conj(r), getattr(s, channel)))
    entry = flipped.results.fusion["shank_r"]
    entry.quat = rot.mul(entry.quat, r)
    for name in ("acc_bias", "gyro_bias"):
        if getattr(entry, name) is not None:
            setattr(entry, name, rot.rotate(rot.conj(r), getattr(entry, name)))
    stages.calibrate(flipped, proto, force=True)
    stages.angles(flipped, proto, force=True)
    before = session.results.angles.columns()["knee_r_flexion_deg"]
    after = flipped.results.angles.columns()["knee_r_flexion_deg"]
    assert flipped.results.calibration.grades["knee_r"].grades[0] == "determined"
    assert np.nanmax(np.abs(after - before)) < 0.5


def _knee_after_slow_movement(t: np.ndarray) -> tuple[tuple, tuple]:
    """A stand (0-3 s), 10 s of slow movement of the leg about another axis (x, ±25°, 4-s
    period: sitting down, shuffling), then a walk: thigh swinging ±20° and the knee flexing
    0-60° about y. ``(t, gyr rad/s, q)`` of thigh and shank."""
    y, x = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])
    walking, slow = t >= 13.0, (t >= 3.0) & (t < 13.0)
    phase = 2.0 * np.pi * (t - 13.0) / 1.1
    flexion = np.where(walking, np.radians(30.0) * (1.0 - np.cos(phase)), 0.0)
    swing = np.where(walking, np.radians(20.0) * np.sin(phase), 0.0)
    other = np.where(slow, np.radians(25.0) * np.sin(2.0 * np.pi * (t - 3.0) / 4.0), 0.0)
    q_p = rot.mul(rot.from_rotvec(other[:, None] * x), rot.from_rotvec(swing[:, None] * y))
    q_d = rot.mul(q_p, rot.from_rotvec(flexion[:, None] * y))

    def side(q):
        mid, w = rot.angular_velocity(t, q)
        return t, np.column_stack([np.interp(t, mid, w[:, k]) for k in range(3)]), q

    return side(q_p), side(q_d)


def test_the_knee_axes_come_from_the_swings_not_the_slow_movement_around_the_walk():
    """Samples under ``SWING_FRACTION`` of the knee's 95th-percentile speed are left out: at a
    tenth, the slow movement filled one of the four parts and turned its axis 90°."""
    y = np.array([0.0, 1.0, 0.0])
    thigh, shank = _knee_after_slow_movement(np.arange(0.0, 30.0, 0.01))
    fit = gait_axes.fit_knee("knee_r", thigh, shank, y, y, (0.5, 2.5))
    assert fit.verdict == "determined" and fit.consistency_deg < 1.0
    assert abs(fit.axis_proximal @ y) > np.cos(np.radians(0.5))
    assert abs(fit.axis_distal @ y) > np.cos(np.radians(0.5))
