"""The quaternion particle filter (motionlab.fusion.particle) on simulated signals with truth."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion import estimate
from motionlab.fusion.particle import ParticleParams, particle_filter

RATE = 100.0
FIELD = np.array([0.0, 20.0 * np.cos(1.1), -20.0 * np.sin(1.1)])  # µT, north with 63° dip


def _signals(seconds=30.0, bias=(0.0, 0.0, 0.0), rest=5.0, seed=0):
    """Truth and IMU signals: rest, then a smooth 3-axis rotation; white noise, constant bias."""
    n = int(seconds * RATE)
    t = np.arange(n) / RATE
    on = (t > rest).astype(float)
    w = on[:, None] * np.stack(
        [0.8 * np.sin(0.9 * t), 0.6 * np.sin(0.5 * t + 1.0), 1.2 * np.sin(0.3 * t + 2.0)], axis=1
    )
    q = rot.integrate_gyro(rot.from_axis_angle([1, 1, 0], 0.5), w, 1.0 / RATE)
    rng = np.random.default_rng(seed)
    gyr = w + np.asarray(bias) + rng.normal(0, 0.003, (n, 3))
    acc = rot.rotate(rot.conj(q), [0.0, 0.0, 9.81]) + rng.normal(0, 0.03, (n, 3))
    mag = rot.rotate(rot.conj(q), FIELD) + rng.normal(0, 0.2, (n, 3))
    return q, gyr, acc, mag


def _deg(a, b):
    return np.rad2deg(rot.angle_between(a, b))


def test_tracks_known_rotation_9d_and_6d():
    q, gyr, acc, mag = _signals()
    res = estimate("particle", gyr, acc, mag, rate=RATE, n_particles=256)
    assert np.percentile(_deg(res.quat, q), 95) < 2.0
    assert res.quat.shape == (len(q), 4) and res.gyro_bias.shape == (len(q), 3)
    assert (np.einsum("ij,ij->i", res.quat[1:], res.quat[:-1]) >= 0).all()
    six = estimate("particle", gyr, acc, None, rate=RATE, n_particles=256)
    up_est = rot.rotate(rot.conj(six.quat), [0, 0, 1])
    up_true = rot.rotate(rot.conj(q), [0, 0, 1])
    incl = np.rad2deg(np.arccos(np.clip(np.sum(up_est * up_true, axis=1), -1, 1)))
    assert np.percentile(incl, 95) < 2.0 and six.extra["six_d"]


@pytest.mark.parametrize("proposal", ["vmf", "bingham"])
@pytest.mark.parametrize("scheme", ["systematic", "residual", "deterministic", "auxiliary"])
def test_every_proposal_and_scheme_tracks(proposal, scheme):
    q, gyr, acc, mag = _signals(seconds=15.0)
    p = ParticleParams(n_particles=128, proposal=proposal, resampling=scheme, acc_sigma=0.3)
    res = particle_filter(gyr, acc, mag, RATE, p)
    assert np.sqrt(np.mean(_deg(res.quat, q) ** 2)) < 3.0


def test_converges_from_wrong_start():
    # in motion from the first sample (weak accelerometer weight), 17° off in tilt: below the
    # reset angle, so the filter itself must converge. Slowly: the heading-only magnetometer
    # turns a tilt error into a heading error of up to tan(dip) times it until the accelerometer
    # (σ = 1.5 g in motion) has removed the tilt (the MEKF is slower still on this signal).
    q, gyr, acc, mag = _signals(seconds=40.0, rest=0.0)
    wrong = rot.mul(rot.from_axis_angle([0, 1, 0], 0.3), q[0])
    res = particle_filter(gyr, acc, mag, RATE, ParticleParams(n_particles=256), q0=wrong)
    err = _deg(res.quat, q)
    assert err[:10].min() > 10 and len(res.extra["resets"]) == 0
    assert err[-500:].max() < 6.0 and err[-500:].max() < 0.6 * err[1000]


def test_estimates_known_gyro_bias():
    bias = np.deg2rad([0.5, -0.3, 0.4])
    q, gyr, acc, mag = _signals(seconds=20.0, bias=bias, rest=10.0)
    res = estimate("particle", gyr, acc, mag, rate=RATE, n_particles=128)
    np.testing.assert_allclose(res.gyro_bias[int(9 * RATE)], bias, atol=np.deg2rad(0.05))
    assert res.rest[int(8 * RATE)]
    assert np.sqrt(np.mean(_deg(res.quat, q) ** 2)) < 1.5


def test_same_seed_same_output():
    q, gyr, acc, mag = _signals(seconds=8.0)
    a = estimate("particle", gyr, acc, mag, rate=RATE, n_particles=128, seed=3)
    b = estimate("particle", gyr, acc, mag, rate=RATE, n_particles=128, seed=3)
    c = estimate("particle", gyr, acc, mag, rate=RATE, n_particles=128, seed=4)
    np.testing.assert_array_equal(a.quat, b.quat)
    np.testing.assert_array_equal(a.extra["ess"], b.extra["ess"])
    assert not np.array_equal(a.quat, c.quat)


def test_divergence_reset_on_injected_fault():
    q, gyr, acc, mag = _signals(seconds=25.0, rest=25.0)
    k = int(10 * RATE)
    gyr = gyr.copy()
    gyr[k : k + 5] += [np.pi / 0.05, 0.0, 0.0]  # a 5-sample glitch: the gyro integral flips 180°
    res = estimate("particle", gyr, acc, mag, rate=RATE, n_particles=256)
    resets = res.extra["resets"]
    assert len(resets) >= 1 and k < resets[0] < k + 3 * RATE
    assert _deg(res.quat, q)[-100:].max() < 2.0
    ok = estimate("particle", *_signals(seconds=25.0, rest=25.0)[1:], rate=RATE, n_particles=256)
    assert len(ok.extra["resets"]) == 0


def test_bad_parameters_raise_input_error():
    q, gyr, acc, mag = _signals(seconds=2.0)
    with pytest.raises(InputError):
        estimate("particle", gyr, acc, mag, rate=RATE, proposal="gauss")
    with pytest.raises(InputError):
        estimate("particle", gyr, acc, mag, rate=RATE, resampling="stratified-ish")
    with pytest.raises(InputError):
        estimate("particle", gyr, acc, mag, rate=RATE, n_particles=2)
