"""Hinge axes from ordinary movement, their signs and verdicts, on a hinge with a known truth."""

import dataclasses

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.protocol import load_protocol
from motionlab.results import HingeFit
from motionlab.segments import heading, movement
from motionlab.segments.gait_axes import fit_knee
from motionlab.segments.movement import (
    anatomical_sign,
    autocorrelation_time,
    fit_hinge,
    fit_two_dof,
    relative_sign,
    swing_sign,
)
from motionlab.segments.placement import fills_hint

RATE = 100.0
STAND_S = 3.0
UPRIGHT = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)  # segment y → earth z
FLEXION_AXIS = np.array([0.0, 0.0, -1.0])  # knee: flexion turns the shank about -z


def _smooth(t: np.ndarray, rng: np.random.Generator, amp: float, n: int = 4) -> np.ndarray:
    out = np.zeros_like(t)
    for _ in range(n):
        f = rng.uniform(0.1, 0.8)
        out += amp / n * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    return out


def _gyr(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Body-frame angular velocity (rad/s) of an orientation series (forward differences)."""
    step = rot.to_rotvec(rot.mul(rot.conj(q[:-1]), q[1:])) / np.diff(t)[:, None]
    return np.vstack([step, step[-1:]])


def _stand_then_tumble(seed: int, duration: float, amp: float, swing: bool = False):
    """``(rng, t s, ramp, q)``: a proximal segment upright for ``STAND_S``, then tumbling (smooth
    rotation vectors of amplitude ``amp`` rad, ramped in over 2 s); ``rng`` seeded by ``seed``
    and drawn from for the tumbling, to draw the rest of the recording. ``swing``: about
    horizontal axes only (no turn about the segment's own long axis away from the stand)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / RATE)
    ramp = np.clip((t - STAND_S) / 2.0, 0.0, 1.0)
    rv = np.column_stack([ramp * _smooth(t, rng, amp) for _ in range(3)])
    if swing:
        rv[:, 2] = 0.0
    return rng, t, ramp, rot.mul(rot.from_rotvec(rv), UPRIGHT)


def hinge_recording(seed: int, duration: float = 40.0, second_axis: bool = False):
    """A stand, then a hinge moving one way (0-60°) while its proximal segment tumbles.

    Returns the two sensors' ``(time, gyr, q_sensor)`` and the true axis in each sensor frame.
    ``second_axis``: after half the recording the distal segment turns about another axis, as a
    sensor that slipped by 40° would.
    """
    rng, t, ramp, q_p = _stand_then_tumble(seed, duration, 0.8)
    theta = ramp * np.radians(30.0) * (1 - np.cos(2 * np.pi * 0.9 * (t - STAND_S)))
    q_d = rot.mul(q_p, rot.from_axis_angle(FLEXION_AXIS, theta))
    mounts = rot.normalize(rng.normal(size=(2, 4)))  # segment → sensor, anywhere
    if second_axis:
        slip = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.radians(40.0) * (t > duration / 2))
        q_d = rot.mul(q_d, slip)
    sensors = []
    for q_seg, m in ((q_p, mounts[0]), (q_d, mounts[1])):
        q_s = rot.mul(q_seg, rot.conj(m))
        sensors.append((t, _gyr(t, q_s), q_s))
    truth = [rot.rotate(m, FLEXION_AXIS) for m in mounts]
    return sensors, truth


def _deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_axes_signs_and_verdict_recovered_from_any_mounting(seed):
    (prox, dist), (j_p, j_d) = hinge_recording(seed)
    # the nominal placement is of no help: a random prior, even the wrong way round
    prior = np.array([1.0, 0.0, 0.0])
    fit = fit_hinge("knee_r", prox, dist, prior, -prior, (0.5, 2.5), anatomical=True)
    assert _deg(fit.axis_proximal, j_p) < 1.0
    assert _deg(fit.axis_distal, j_d) < 1.0
    assert fit.sign == "anatomy" and fit.relative_sign == "measured"
    assert fit.verdict == "determined", fit.reasons
    assert fit.excursion_deg[0] == pytest.approx(60.0, abs=3.0)  # flexion side
    assert fit.excursion_deg[1] < 3.0


def test_without_a_stand_the_sign_follows_the_hint_and_is_weak():
    (prox, dist), (j_p, j_d) = hinge_recording(3)
    fit = fit_hinge("knee_r", prox, dist, -j_p, -j_d, None, anatomical=True)
    assert _deg(fit.axis_proximal, -j_p) < 1.0  # the hint's (wrong) direction, said so
    assert fit.sign == "nominal" and fit.verdict == "weak"
    assert any("nominal placement" in r for r in fit.reasons)


def test_a_sensor_that_slips_is_not_determined():
    (prox, dist), _ = hinge_recording(4, duration=60.0, second_axis=True)
    prior = np.array([0.0, 0.0, 1.0])
    fit = fit_hinge("knee_r", prox, dist, prior, prior, (0.5, 2.5), anatomical=True)
    assert fit.verdict != "determined"
    assert fit.consistency_deg > 5.0


def test_relative_sign_from_the_vertical_component():
    (prox, dist), (j_p, j_d) = hinge_recording(5)
    assert relative_sign(prox[2], dist[2], j_p, j_d)[0] == 1.0
    sign, margin = relative_sign(prox[2], dist[2], j_p, -j_d)
    assert sign == -1.0 and margin > 0.9


def test_anatomical_sign_is_the_larger_excursion():
    (prox, dist), (j_p, j_d) = hinge_recording(6)
    t = prox[0]
    assert anatomical_sign(t, prox[2], dist[2], j_p, j_d, (0.5, 2.5))[0] == 1.0
    assert anatomical_sign(t, prox[2], dist[2], -j_p, -j_d, (0.5, 2.5))[0] == -1.0


def elbow_recording(
    seed: int, duration: float = 40.0, axial_follow: float = 1.0, flexion_axis=(0.0, 0.0, 1.0)
):
    """A stand (arm hanging), then flexion 0-120° and pronation ±60° while the upper arm moves;
    a 10° carrying angle between the axes. Returns both sensors' ``(time, gyr, q)``, the true
    flexion axis in the upper-arm sensor and long axis in the forearm sensor, and each sensor's
    heading drift (rad/s) applied to its own 6-D earth frame.

    ``axial_follow`` < 1: the humerus also turns ±60° about its own long axis, and the upper-arm
    sensor's skin follows only that fraction of it (the humerus turns ``1 / axial_follow`` times
    as fast about its long axis as the sensor does). ``flexion_axis``: in the upper arm's frame
    (an elbow's is its z, across the humerus' long axis y)."""
    rng, t, ramp, q_u = _stand_then_tumble(seed, duration, 0.7, swing=axial_follow < 1.0)
    flex = ramp * np.radians(60.0) * (1 - np.cos(2 * np.pi * 0.4 * (t - STAND_S)))
    pron = ramp * np.radians(60.0) * np.sin(2 * np.pi * 0.27 * (t - STAND_S))
    z, x, y = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
    q_skin = q_u
    if axial_follow < 1.0:
        axial = ramp * np.radians(60.0) * np.sin(2 * np.pi * 0.21 * (t - STAND_S) + 1.0)
        q_u = rot.mul(q_u, rot.from_axis_angle(y, axial))
        q_skin = rot.mul(q_u, rot.from_axis_angle(y, -(1.0 - axial_follow) * axial))
    carrying = rot.from_axis_angle(x, np.radians(10.0))
    axis = np.asarray(flexion_axis, float) / np.linalg.norm(flexion_axis)
    q_f = rot.mul(rot.mul(rot.mul(q_u, rot.from_axis_angle(axis, flex)), carrying),
                  rot.from_axis_angle(y, pron))  # fmt: skip
    mounts = rot.normalize(rng.normal(size=(2, 4)))
    out = []
    for q_seg, m, drift in ((q_skin, mounts[0], 0.002), (q_f, mounts[1], -0.003)):
        q_s = rot.mul(q_seg, rot.conj(m))
        q_6d = rot.mul(rot.from_axis_angle(z, 0.7 + drift * t), q_s)  # own heading, drifting
        out.append((t, _gyr(t, q_s), q_6d))
    return out, (rot.rotate(mounts[0], axis), rot.rotate(mounts[1], y))


def test_elbow_axes_from_free_movement():
    (upper, fore), (j1, j2) = elbow_recording(7)
    fit = fit_two_dof("elbow_r", upper, fore, np.eye(3)[0], np.eye(3)[1], (0.5, 2.5))
    assert _deg(fit.axis_proximal, j1) < 1.0  # flexion direction by anatomy
    assert _deg(fit.axis_distal, j2) < 1.0  # long axis up in the stand
    assert fit.sign == "anatomy" and fit.verdict == "determined", fit.reasons
    assert fit.flexion_distal @ j2 == pytest.approx(np.sin(np.radians(10.0)), abs=0.02)


def test_elbow_axes_when_the_upper_arm_skin_lags_the_humerus():
    """The upper-arm sensor follows 0.6 of the humerus' axial rotation (docs/simulator.md, "The
    upper arm under the skin"): read as a turn off the two axes, the lag makes the parts of the
    movement disagree by 20° (not determined); fitted as the humerus turning ``1 + k`` times as
    fast about its long axis (``axial_lag``), they agree within 15° and the fraction followed
    comes back."""
    (upper, fore), (j1, j2) = elbow_recording(3, axial_follow=0.6)
    prior = (np.eye(3)[0], np.eye(3)[1])
    old = fit_two_dof("elbow_r", upper, fore, *prior, (0.5, 2.5))
    new = fit_two_dof("elbow_r", upper, fore, *prior, (0.5, 2.5), axial_lag=True)
    assert old.verdict == "not determined" and np.isnan(old.axial_follow)
    assert old.consistency_deg > 18.0
    assert new.verdict == "weak" and new.consistency_deg < 12.0, new.reasons
    assert new.axial_follow == pytest.approx(0.6, abs=0.05)
    assert new.relative_residual < 0.85 * old.relative_residual
    # the axis turns with the lag (±24° about the long axis): its mean is what is fitted
    assert _deg(new.axis_proximal, j1) < 4.0 and _deg(new.axis_distal, j2) < 2.0
    assert new.sign == "anatomy"


def test_a_flexion_axis_along_the_upper_arm_is_not_an_elbow():
    """A joint flexing about an axis 20° from the upper arm's long axis (the real 16-IMU
    recording's right elbow: 4-7°) fits well, but it is not an elbow: not determined."""
    tilt = np.radians(70.0)  # from z towards the long axis y
    (upper, fore), (j1, _) = elbow_recording(7, flexion_axis=(0.0, np.sin(tilt), np.cos(tilt)))
    prior = (np.eye(3)[0], np.eye(3)[1])
    fit = fit_two_dof("elbow_r", upper, fore, *prior, (0.5, 2.5), axial_lag=True)
    assert fit.consistency_deg < 5.0 and fit.relative_residual < 0.35  # a good two-axis fit
    assert fit.verdict == "not determined"
    assert any("20° from the long axis" in r for r in fit.reasons), fit.reasons
    assert fit.across_deg == pytest.approx(70.0, abs=3.0)  # off the perpendicular
    assert HingeFit.from_tree(fit.to_tree()).across_deg == fit.across_deg
    # not an elbow's axis: it stands in for no placement hint (placement.fills_hint)
    arm = load_protocol("arm")
    assert arm.segments["upperarm_r"].any_orientation and fit.sign == "anatomy"
    assert not fills_hint(arm, "upperarm_r", fit, set())


def test_a_fit_not_determined_stands_in_only_for_a_hint_that_says_nothing():
    """Right seed 0 of ``bench/real_world.py --protocols arm``: the fit's parts disagree by
    15.2° (``not determined``), but the anatomy signs it; the upper arm's hint, turned about the
    stand's vertical as the protocol's ``sensor_axes`` say, put its flexion axis 165° from the
    truth. A sensor that may sit any way round (``any_orientation``) or a contradicted hint
    takes the fit's axes; a strapped hint (``elbow`` protocol) keeps its own, and so does a fit
    whose direction of flexion follows the hint."""
    (upper, fore), _ = elbow_recording(3, axial_follow=0.6)
    fit = fit_two_dof("elbow_r", upper, fore, np.eye(3)[0], np.eye(3)[1], (0.5, 2.5))
    assert fit.verdict == "not determined" and fit.sign == "anatomy"
    assert np.isnan(fit.across_deg)  # not checked without the axial lag
    arm, elbow = load_protocol("arm"), load_protocol("elbow")
    assert fills_hint(arm, "upperarm_r", fit, set()) and fills_hint(arm, "forearm_r", fit, set())
    assert not elbow.segments["upperarm_r"].any_orientation
    assert not fills_hint(elbow, "upperarm_r", fit, set())
    assert fills_hint(elbow, "upperarm_r", fit, {"upperarm_r"})
    assert not fills_hint(arm, "upperarm_r", dataclasses.replace(fit, sign="nominal"), set())
    assert not fills_hint(arm, "upperarm_r", dataclasses.replace(fit, verdict="weak"), set())
    back = HingeFit.from_tree(fit.to_tree())
    assert np.isnan(back.across_deg) and "across_deg" not in fit.to_tree()


def test_a_pause_longer_than_a_heading_window_leaves_no_empty_window():
    """The arms rest for 15 s in the middle of the movement: no 10-s heading window is left
    without samples (its time would be NaN and the angles could not be made)."""
    (upper, fore), (j1, j2) = elbow_recording(7, duration=40.0)
    cut, pause = int(20.0 * RATE), 15.0
    sides = []
    for t, gyr, q in (upper, fore):
        t2 = np.r_[t[:cut], t[cut] + np.arange(1, int(pause * RATE)) / RATE, t[cut:] + pause]
        still = np.zeros((int(pause * RATE) - 1, 3))
        q_still = np.repeat(q[cut : cut + 1], len(still), axis=0)
        sides.append((t2, np.vstack([gyr[:cut], still, gyr[cut:]]),
                      np.vstack([q[:cut], q_still, q[cut:]])))  # fmt: skip
    fit = fit_two_dof("elbow_r", *sides, np.eye(3)[0], np.eye(3)[1], (0.5, 2.5), axial_lag=True)
    assert np.all(np.isfinite(fit.heading_times)) and np.all(np.isfinite(fit.heading_deltas))
    assert np.all(np.diff(fit.heading_times) > 0)
    assert _deg(fit.axis_proximal, j1) < 1.0 and fit.verdict == "determined", fit.reasons


def test_elbow_axial_lag_fits_no_lag_where_the_skin_follows():
    (upper, fore), (j1, j2) = elbow_recording(7)
    fit = fit_two_dof("elbow_r", upper, fore, np.eye(3)[0], np.eye(3)[1], (0.5, 2.5),
                      axial_lag=True)  # fmt: skip
    assert _deg(fit.axis_proximal, j1) < 1.0 and _deg(fit.axis_distal, j2) < 1.0
    assert fit.axial_follow > 0.97 and fit.verdict == "determined"


def test_joints_are_aligned_along_the_chain():
    from motionlab.protocol import Joint, Protocol, Segment
    from motionlab.segments import chain_order

    segs = {s: Segment(s) for s in ("thorax", "upperarm", "forearm")}
    joints = {
        "elbow": Joint("elbow", "hinge", "upperarm", "forearm", axis="z"),
        "shoulder": Joint("shoulder", "ball", "thorax", "upperarm"),
    }
    order = chain_order(Protocol("p", segs, joints))
    assert [j.name for j in order] == ["shoulder", "elbow"]


def test_swing_sign_from_the_whole_orientation():
    (prox, dist), (j_p, j_d) = hinge_recording(8)
    t = prox[0]
    assert swing_sign(t, prox[2], dist[2], j_p, j_d)[0] == 1.0
    sign, margin = swing_sign(t, prox[2], dist[2], j_p, -j_d)
    assert sign == -1.0 and margin > 0.5


def test_knee_axis_from_a_walk_keeps_a_coupled_rotation_about_the_shank_out():
    """A walking leg (the thigh swings about its flexion axis, with some wobble) whose shank turns
    about its own long axis with flexion (screw home, 0.12°/°) and wobbles in ab/adduction: the
    principal axes of the walk (:func:`motionlab.segments.gait_axes.fit_knee`) are the segments'
    flexion axis, not tilted by the rotation, while Seel's constraint alone is pulled off."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 40.0, 1.0 / RATE)
    ramp = np.clip((t - STAND_S) / 2.0, 0.0, 1.0)
    phase = 2 * np.pi * 0.9 * (t - STAND_S)
    rv = np.column_stack([ramp * _smooth(t, rng, 0.05) for _ in range(3)])
    swing = rot.from_axis_angle(FLEXION_AXIS, -ramp * np.radians(25.0) * np.sin(phase))
    q_p = rot.mul(rot.mul(rot.from_rotvec(rv), UPRIGHT), swing)
    theta = ramp * np.radians(30.0) * (1 - np.cos(phase - 1.0))
    ab = ramp * np.radians(2.0) * np.sin(2 * np.pi * 1.3 * t)
    rel = rot.mul(
        rot.mul(rot.from_axis_angle(FLEXION_AXIS, theta), rot.from_axis_angle(np.eye(3)[0], ab)),
        rot.from_axis_angle(np.eye(3)[1], 0.12 * theta),
    )
    q_d = rot.mul(q_p, rel)
    mounts = rot.normalize(rng.normal(size=(2, 4)))
    sensors = []
    for q_seg, m in ((q_p, mounts[0]), (q_d, mounts[1])):
        q_s = rot.mul(q_seg, rot.conj(m))
        sensors.append((t, _gyr(t, q_s), q_s))
    j_p, j_d = (rot.rotate(m, FLEXION_AXIS) for m in mounts)
    prior = np.array([1.0, 0.0, 0.0])
    fit = fit_knee("knee_r", *sensors, prior, prior, (0.5, 2.5))
    plain = fit_hinge("knee_r", *sensors, prior, prior, (0.5, 2.5), True)
    assert fit.sign == "anatomy" and fit.method == "principal"
    assert _deg(fit.axis_proximal, j_p) < 1.0
    # seen from the shank the flexion axis turns with the screw-home rotation, by up to
    # 0.12 × 60° = 7.2° at full flexion: the principal axis is its mean direction (3.6°)
    assert _deg(fit.axis_distal, j_d) < 4.5
    # the constraint fit alone is pulled off by the rotation
    assert max(_deg(plain.axis_proximal, j_p), _deg(plain.axis_distal, j_d)) > 2.0


def test_smoothed_headings_weigh_each_window_by_its_variance():
    """Two windows 10 s apart, each measured with variance 0.01 and a drift of variance 0.02 between
    them (rad²): the RTS smoother puts each a quarter of the way towards the other (by hand:
    ``x₁ = z₁ + r/(2r + q)·(z₂ − z₁)``); no drift gives both the mean, a free drift the
    measurements, and a window measured poorly follows its neighbours."""
    times, z, r = np.array([0.0, 10.0]), np.array([0.0, 0.4]), np.full(2, 0.01)
    drift = np.sqrt(0.02 / 10.0)
    np.testing.assert_allclose(heading.smoothed_track(times, z, r, drift), [0.1, 0.3])
    np.testing.assert_allclose(heading.smoothed_track(times, z, r, 0.0), [0.2, 0.2])
    np.testing.assert_allclose(heading.smoothed_track(times, z, r, 1e6), z, atol=1e-6)
    out = heading.smoothed_track(np.arange(3.0), [0.0, 9.0, 0.0], [1e-4, 1e4, 1e-4], 0.1)
    assert abs(out[1]) < 0.01
    # across ±π the offsets are unwrapped first
    near_pi = heading.smoothed_track(times, [np.pi - 0.1, -np.pi + 0.1], np.ones(2), 0.0)
    np.testing.assert_allclose(near_pi, [np.pi, np.pi])


def test_a_window_whose_heading_settled_half_a_turn_off_is_left_out():
    """Left elbow, seed 3 of ``bench/real_world.py --protocols arm`` with 5-s windows: two of
    twelve windows' offsets came out about 180° from their neighbours (another solution of the
    fit, not a drift) and, smoothed in, put flexion 164° off; left out, the track stays with the
    others (flexion 3.6°)."""
    deg = np.array([50, 49, 43, 46, 40, 38, 47, 42, 220, 398, 406, 239], float)
    flagged = heading.outlying_anchors(np.radians(deg))
    assert flagged.tolist() == [False] * 8 + [True, False, False, True]
    times = 5.0 * np.arange(len(deg))
    out = np.degrees(heading.smoothed_track(times, np.radians(deg), np.full(12, 1e-3), 0.01))
    assert np.all(np.abs(out - 44.0) < 7.0)
    # a slow drift of the same size is no outlier, nor are offsets across ±180°
    assert not heading.outlying_anchors(np.radians(np.linspace(0.0, 120.0, 12))).any()
    assert not heading.outlying_anchors(np.radians([178.0, -179.0, 179.0, -177.0])).any()
    assert not heading.outlying_anchors(np.radians([0.0, 90.0])).any()  # too few to tell


def test_autocorrelation_time_counts_the_samples_one_independent_sample_is_worth():
    rng = np.random.default_rng(1)
    assert autocorrelation_time(rng.normal(size=20000)) == pytest.approx(1.0, abs=0.15)
    phi, e = 0.8, rng.normal(size=50000)
    x = np.zeros_like(e)
    for i in range(1, len(e)):
        x[i] = phi * x[i - 1] + e[i]
    assert autocorrelation_time(x) == pytest.approx((1 + phi) / (1 - phi), rel=0.15)
    assert autocorrelation_time(np.zeros(10)) == 1.0 and autocorrelation_time(np.ones(2)) == 1.0


@pytest.mark.parametrize("seed", [3, 7])
def test_elbow_headings_follow_the_drift_and_smoothing_steadies_them(seed, monkeypatch):
    """The two sensors' 6-D headings drift apart by 0.005 rad/s (``elbow_recording``): without
    skin lag the fitted offsets follow it within 0.5°; with the upper arm's skin following 0.6
    of the humerus' axial rotation each window's offset errs by several degrees, and smoothing
    them as a random walk (``TWO_AXIS_DRIFT_DEG_S``) brings their scatter about the true drift
    down (seed 3: from 2.0° to 1.6° standard deviation, seed 7: from 3.9° to 2.5°)."""
    prior = (np.eye(3)[0], np.eye(3)[1], (0.5, 2.5))
    (upper, fore), _ = elbow_recording(7)
    fit = fit_two_dof("elbow_r", upper, fore, *prior, axial_lag=True)
    assert np.degrees(np.abs(fit.heading_deltas - 0.005 * fit.heading_times)).max() < 0.5

    def scatter() -> float:
        (u, f), _ = elbow_recording(seed, axial_follow=0.6)
        fit = fit_two_dof("elbow_r", u, f, *prior, axial_lag=True)
        return float(np.degrees(np.std(fit.heading_deltas - 0.005 * fit.heading_times)))

    smoothed = scatter()
    monkeypatch.setattr(movement, "TWO_AXIS_DRIFT_DEG_S", 1e4)
    assert smoothed < 0.85 * scatter() and smoothed < 3.0
