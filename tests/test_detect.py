"""Rest and magnetic-disturbance detectors on hand-built signals."""

import numpy as np
from fusion_signals import FIELD, constant_rotation

from motionlab import rotations as rot
from motionlab.fusion import detect


def test_rest_mask_finds_the_still_phases():
    rate = 100.0
    rng = np.random.default_rng(3)
    n = 1500
    gyr = 0.002 * rng.standard_normal((n, 3))
    acc = np.array([0.0, 0.0, 9.81]) + 0.02 * rng.standard_normal((n, 3))
    gyr[500:1000] += [0.0, 1.0, 0.3]  # 5 s of motion between 5 s of rest on each side
    acc[500:1000] += 2.0 * np.sin(np.arange(500) / 10.0)[:, None]
    rest = detect.rest_mask(gyr, acc, rate)
    assert rest[100:440].all() and rest[1060:1400].all()
    assert not rest[500:1000].any()


def test_rest_mask_ignores_short_pauses():
    rate = 100.0
    gyr = np.tile([0.0, 0.0, 0.5], (1000, 1))
    gyr[400:480] = 0.0  # 0.8 s pause, shorter than min_duration
    acc = np.tile([0.0, 0.0, 9.81], (1000, 1))
    assert not detect.rest_mask(gyr, acc, rate).any()


def test_field_reference_is_the_undisturbed_field():
    sig = constant_rotation(seconds=20.0)
    mag = sig["mag"].copy()
    mag[:600] += [30.0, -10.0, 5.0]  # a magnet near the sensor for 30 % of the time
    norm, dip = detect.field_reference(mag, sig["acc"])
    assert abs(norm - np.linalg.norm(FIELD)) < 0.3
    assert abs(dip - np.deg2rad(65.0)) < np.deg2rad(0.5)


def test_mag_disturbance_by_norm_and_by_dip():
    sig = constant_rotation(seconds=20.0)
    rate, q = sig["rate"], sig["quat"]
    mag = sig["mag"].copy()
    mag[500:800] *= 1.3  # norm change only
    # direction change only: the earth-frame field tilted 20° (dip 65° → 45°), same norm
    bent = rot.rotate(rot.from_axis_angle([1.0, 0, 0], 0.35), FIELD)
    mag[1200:1500] = rot.rotate(rot.conj(q[1200:1500]), bent)
    by_norm = detect.mag_disturbance(mag, sig["acc"], None, rate)
    assert by_norm[520:780].all() and not by_norm[1200:1500].all()
    with_q = detect.mag_disturbance(mag, sig["acc"], q, rate)
    assert with_q[520:780].all() and with_q[1220:1480].all()
    clean = np.r_[0:400, 900:1100, 1600:2000]
    assert not with_q[clean].any() and not by_norm[clean].any()
    assert detect.mag_usable(with_q) and not detect.mag_usable(np.ones(100, bool))


def test_in_loop_check_agrees_with_the_vectorised_one():
    sig = constant_rotation(seconds=2.0, mag_noise=0.0)
    q, mag = sig["quat"], sig["mag"].copy()
    mag[100:] = rot.rotate(rot.from_axis_angle([0, 1.0, 0], 0.3), mag[100:])
    ref = (float(np.linalg.norm(FIELD)), np.deg2rad(65.0))
    flags = [
        detect.nb_field_disturbed(*q[k], *mag[k], ref[0], ref[1], 4.0, np.deg2rad(6.0))
        for k in range(len(q))
    ]
    _, dip = detect.field_norm_dip(mag, sig["acc"], q)
    np.testing.assert_array_equal(flags, np.abs(dip - ref[1]) > np.deg2rad(6.0))
    assert not any(flags[:100])


def _swaying_rest(rate: float, sway_deg_s: float) -> np.ndarray:
    """10 s of a sensor's rate (rad/s) at rest: a bias of 0.5°/s about z, white noise of
    0.1°/s, and a person's sway: sinusoids of ``sway_deg_s`` amplitude at 0.3 and 0.7 Hz."""
    t = np.arange(int(10 * rate)) / rate
    rng = np.random.default_rng(5)
    gyr = np.deg2rad(0.1) * rng.standard_normal((len(t), 3))
    gyr[:, 2] += np.deg2rad(0.5)
    sway = np.sin(2 * np.pi * 0.3 * t) + np.sin(2 * np.pi * 0.7 * t + 1.0)
    gyr += np.deg2rad(sway_deg_s) * np.column_stack([0.6 * sway, 0.4 * sway[::-1], sway])
    return gyr


def test_steady_mask_tells_a_bias_from_a_sway():
    """A constant rate with white noise is steady at any rate; a sway of ±0.5°/s is not
    (but for a few moments where the two sinusoids level off together)."""
    for rate in (50.0, 285.7):
        assert detect.steady_mask(_swaying_rest(rate, 0.0), rate).all()
        assert detect.steady_mask(_swaying_rest(rate, 0.5), rate).mean() < 0.1


def test_the_smoother_takes_no_bias_from_a_sway():
    """At a rest whose rate sways, the bias update is left out: the smoother's bias about the
    vertical stays at its prior (0), not the sway's mean over the rest; a steady rest gives
    the constant rate as the bias (0.5°/s)."""
    from motionlab.fusion import estimate

    rate = 50.0
    acc = np.tile([0.0, 0.0, 9.81], (int(10 * rate), 1))
    steady = estimate("smoother", _swaying_rest(rate, 0.0), acc, None, rate=rate)
    assert abs(np.degrees(steady.gyro_bias[:, 2]).mean() - 0.5) < 0.05
    gyr = _swaying_rest(rate, 0.5)
    gyr[:, 2] += np.deg2rad(0.4)  # the person turned slowly: the rest's mean is 0.9°/s
    swaying = estimate("smoother", gyr, acc, None, rate=rate)
    assert abs(np.degrees(swaying.gyro_bias[:, 2]).mean()) < 0.1
