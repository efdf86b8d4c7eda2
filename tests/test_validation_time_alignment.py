"""Time synchronisation: clock model from angular speed, RANSAC, sub-sample peaks."""

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.validation.optical import resample_quat
from motionlab.validation.time_alignment import (
    ClockModel,
    _parabola,
    ransac_line,
    speed_signal,
    synchronise,
)

OFFSET, DRIFT = 0.137, 100e-6


def _recording(seed: int, noise_rad: float, duration: float = 90.0, imu_drift: float = 0.0):
    """A body turning with smooth random angular velocity (pauses included), seen by an IMU at
    100 Hz on the true clock and by a camera at 120 Hz on the clock ``OFFSET + (1+DRIFT) t``.
    ``imu_drift``: the IMU's clock runs that fast instead (a fraction), agreeing with the true
    clock at the middle of the recording (as an IMU-to-IMU sync leaves a sensor)."""
    rng = np.random.default_rng(seed)
    fine = np.arange(0.0, duration, 1e-3)
    sos = butter(2, 2.0, fs=1000, output="sos")
    w = sosfiltfilt(sos, rng.normal(size=(len(fine), 3)), axis=0)
    w *= 2.0 / w.std() * 0.5 * (1 + np.tanh(4 * np.sin(2 * np.pi * fine / 20) + 1.2))[:, None]
    q = rot.integrate_gyro(rot.IDENTITY, w, 1e-3)
    t_imu = np.arange(0.0, duration - 0.01, 0.01)
    mid = 0.5 * duration
    t_true = mid + (t_imu - mid) / (1 + imu_drift) if imu_drift else t_imu
    gyr = np.column_stack([np.interp(t_true, fine, w[:, i]) for i in range(3)])
    stamps = np.arange(int((OFFSET + (1 + DRIFT) * duration) * 120)) / 120.0
    t_true = (stamps - OFFSET) / (1 + DRIFT)
    keep = (t_true >= 0) & (t_true < duration - 0.01)
    q_opt = resample_quat(fine, q, t_true[keep])
    q_opt = rot.mul(q_opt, rot.from_rotvec(rng.normal(0, noise_rad, (keep.sum(), 3))))
    return (t_imu, gyr + rng.normal(0, 0.005, gyr.shape)), (stamps[keep], q_opt)


def test_clock_model_maps_both_ways():
    m = ClockModel(0.137, 1e-4)
    t = np.array([0.0, 10.0, 100.0])
    np.testing.assert_allclose(m.to_imu(m.to_reference(t)), t)
    assert m.to_reference(10.0) == pytest.approx(0.137 + 10.001)


def test_noise_free_offset_and_drift_are_exact():
    imu, ref = _recording(0, 0.0)
    res = synchronise([imu], [ref])
    assert res.model.offset_s == pytest.approx(OFFSET, abs=1e-4)
    assert res.model.drift == pytest.approx(DRIFT, abs=3e-6)
    assert res.inlier_ratio == 1.0 and len(res.window_time_s) >= 10


def test_marker_noise_costs_little_precision():
    imu, ref = _recording(1, np.radians(0.5))  # 0.5° per camera frame, as with 1 mm markers
    res = synchronise([imu], [ref])
    assert res.model.offset_s == pytest.approx(OFFSET, abs=1e-3)
    assert res.model.drift == pytest.approx(DRIFT, abs=20e-6)
    d = res.record("gyroscope", ["s"])
    assert d.drift_ppm == pytest.approx(res.model.drift * 1e6)
    assert len(d.window_lag_s) == len(d.inliers) == d.n_windows
    assert list(d.sensor_residual_s) == ["s"] and d.signal == "gyroscope"


def test_a_large_offset_is_found_by_the_coarse_search():
    (t_imu, gyr), (t_ref, q) = _recording(2, 0.0)
    res = synchronise([(t_imu, gyr)], [(t_ref + 7.3, q)])
    assert res.model.offset_s == pytest.approx(OFFSET + 7.3, abs=1e-3)


def test_ransac_rejects_outliers_and_weights_by_precision():
    t = np.arange(0.0, 100.0, 5.0)
    y = 0.2 + 1e-4 * t
    y[[3, 11]] += [0.4, -0.25]  # windows matched to the wrong movement cycle
    a, b, inliers = ransac_line(t, y, threshold=0.002)
    assert a == pytest.approx(0.2) and b == pytest.approx(1e-4)
    assert inliers.tolist() == [i not in (3, 11) for i in range(len(t))]
    y2 = 0.2 + 1e-4 * t
    y2[0] += 0.0015  # imprecise window: inside the threshold, but with a large SD
    sd = np.full(len(t), 1e-4)
    sd[0] = 1e-1
    a, b, _ = ransac_line(t, y2, threshold=0.002, sd=sd)
    assert a == pytest.approx(0.2, abs=1e-6)
    with pytest.raises(InputError, match="window"):
        ransac_line(t[:1], y[:1], 0.002)


def test_parabola_vertex():
    c = -((np.arange(5) - 2.3) ** 2)
    assert 2 + _parabola(c, 2) == pytest.approx(2.3)
    assert _parabola(c, 0) == 0.0


def test_no_movement_cannot_be_synchronised():
    t = np.arange(0.0, 30.0, 0.01)
    still = (t, np.zeros((len(t), 3)) + 1e-3)
    q = np.tile(rot.IDENTITY, (len(t), 1))
    with pytest.raises(InputError, match="clock=False"):
        synchronise([still], [(t, q)])


def test_windows_evaluated_at_once_as_one_by_one():
    """window_lags evaluates every window's spline values and validity in one call: to the bit
    what each window's own call gives (including windows reaching past the recording)."""
    (t, gyr), _ = _recording(1, 0.0, duration=30.0)
    spline, valid = speed_signal(t, gyr)
    starts = np.arange(-2.0, 29.0, 5.0)
    windows = starts[:, None] + np.arange(300) / 100.0
    at_once, masks = spline(windows), valid(windows)
    for k, s in enumerate(starts):
        one = s + np.arange(300) / 100.0
        assert np.array_equal(at_once[k], spline(one)) and np.array_equal(masks[k], valid(one))


def test_a_reference_faster_than_its_imu_is_a_marker_jump():
    """A rigid body cannot turn faster than the sensor on it: the optical rate's samples above
    twice the IMU's fastest (99.5th percentile) are a marker solution jumping and become gaps;
    the body's own movement, up to that fastest and a little over, stays."""
    from motionlab.validation.time_alignment import without_jumps

    imu, ref = _recording(3, 0.0, duration=15.0)
    t_mid, omega = angular_velocity_of(ref)
    omega = omega[10:]  # the simulated camera's first frames jump onto the track
    fastest = np.percentile(np.linalg.norm(imu[1], axis=1), 99.5)
    spiked = omega.copy()
    spiked[[100, 101, 900]] = [[60.0, 0, 0], [-60.0, 0, 0], [0, 0, 3.0 * fastest]]
    out = without_jumps(spiked, imu[1])
    assert np.isnan(out[[100, 101, 900]]).all()
    rest = np.delete(np.arange(len(out)), [100, 101, 900])
    np.testing.assert_array_equal(out[rest], spiked[rest])
    np.testing.assert_array_equal(without_jumps(omega, imu[1]), omega)


def test_the_coarse_lag_needs_half_the_overlap():
    """Real trunk trials of 12-16 s locked onto lags of ±10-14 s, where 1.7 s of the two
    recordings overlapped and happened to correlate: a lag that shares less than half of what
    the best lag shares is not considered."""
    from motionlab.validation.time_alignment import MIN_OVERLAP, coarse_lag

    imu, ref = _recording(4, 0.0, duration=12.0)
    sig_i = [(*speed_signal(*imu), imu[0][0], imu[0][-1])]
    t_mid, omega = angular_velocity_of(ref)
    sig_r = [(*speed_signal(t_mid, omega), t_mid[0], t_mid[-1])]
    lag, _ = coarse_lag(sig_i, sig_r, 100.0)
    assert lag == pytest.approx(OFFSET, abs=0.02) and MIN_OVERLAP == 0.5


def angular_velocity_of(ref):
    from motionlab.rotations import angular_velocity

    return angular_velocity(*ref)


def test_a_reference_clock_on_an_epoch_or_in_ms():
    """A reference whose clock reads epoch seconds (1.7e9 s) asked for one grid over both
    clocks' spans ("Maximum allowed size exceeded": internal error); one in ms hung. Each side
    now has its own grid; a span of more than a day is no recording in seconds."""
    imu, (t_ref, q) = _recording(2, 0.0, duration=30.0)
    res = synchronise([imu], [(t_ref + 1.7e9, q)])
    assert res.model.offset_s == pytest.approx(1.7e9 + OFFSET, abs=2e-3)
    with pytest.raises(InputError, match="spans .* s — give the reference's time in seconds"):
        synchronise([imu], [(t_ref * 1e4, q)])


#: the drift of each IMU's clock against the session's after an IMU-to-IMU sync, and the
#: camera's noise on its body (rad a frame): the first body the best-seen, as a harsh walk's
#: right shank was (its sensor −85 ppm against the cameras, the session's clock +17 ppm)
STRAYING = [(90e-6, 0.001), (-60e-6, 0.01), (40e-6, 0.01), (-70e-6, 0.01)]


def _bodies(strays: list[tuple[float, float]], duration: float = 90.0):
    """Four bodies (seeds 20-23) seen by IMUs whose clocks drift by ``strays`` against the
    session's and by the cameras (``OFFSET + (1 + DRIFT) t`` on the session's clock)."""
    pairs = [_recording(20 + i, noise, duration, drift) for i, (drift, noise) in enumerate(strays)]
    return [imu for imu, _ in pairs], [ref for _, ref in pairs]


def _clock_error_at_ends(res, duration: float = 90.0) -> float:
    """The largest error (s) of the fitted clock over the recording, against the true one."""
    t = np.array([0.0, duration])
    return float(np.abs(res.model.to_reference(t) - (OFFSET + (1 + DRIFT) * t)).max())


def test_a_drift_the_sensors_disagree_about_is_not_graded_good():
    """A simulated harsh walk: each IMU kept a drift of its own from the IMU-to-IMU sync, and
    the best-correlating one set the one line through all windows: its drift (−69 ppm where the
    session's clock is +17) stated to a few ppm and graded good. The line now lets each
    sensor's clock stray: the drift the windows show comes with the sensors' disagreement in
    its standard error, a drift they do not determine is not corrected, and the grade is of the
    clock's standard error at the recording's ends, which covers its error there."""
    imu, ref = _bodies(STRAYING)
    res = synchronise(imu, ref)
    d = res.record("gyroscope", ["a", "b", "c", "d"])
    assert d.grade != "good"
    assert d.drift_se_ppm > 25.0  # the four sensors' drifts spread by 160 ppm
    if d.drift_grade == "determined":
        assert abs(d.drift_ppm - DRIFT * 1e6) < 3 * d.drift_se_ppm
    else:
        assert d.drift_grade == "not determined" and d.drift_ppm == 0.0
        assert abs(d.drift_measured_ppm - DRIFT * 1e6) < 3 * d.drift_se_ppm
    assert _clock_error_at_ends(res) < 3 * d.ends_standard_error_s
    assert "not corrected" in d.drift_words() or "±" in d.drift_words()


def test_sensors_on_one_clock_keep_a_determined_drift():
    """The same bodies with every IMU on the session's clock: the sensors agree, the drift is
    determined to a few ppm and corrected, and the clock is good to its ends."""
    imu, ref = _bodies([(0.0, noise) for _, noise in STRAYING])
    d = synchronise(imu, ref).record("gyroscope", ["a", "b", "c", "d"])
    assert d.drift_grade == "determined" and d.grade == "good"
    assert d.drift_se_ppm < 10.0 and abs(d.drift_ppm - DRIFT * 1e6) < 3 * d.drift_se_ppm
    assert d.time_offset_s == pytest.approx(OFFSET, abs=1e-3)
    assert d.drift_words() == f"{d.drift_ppm:+.1f} ± {d.drift_se_ppm:.1f} ppm"
