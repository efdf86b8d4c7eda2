"""Spatial alignment AX = YB: full, heading and none, on synthetic orientation pairs."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.validation.align import align

RATE = 100.0


def _optical(seed: int, n: int = 3000) -> np.ndarray:
    """A cluster turning about changing axes (cluster → lab)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None] / RATE
    w = np.sin(2 * np.pi * t * rng.uniform(0.2, 0.7, 3) + rng.uniform(0, 6, 3)) * 2.0
    return rot.integrate_gyro(rot.normalize(rng.normal(size=4)), w, 1 / RATE)


def _pairs(y, xs, headings=None, noise_deg=0.0, seed=0):
    rng = np.random.default_rng(seed)
    out = {}
    for i, (label, x) in enumerate(xs.items()):
        b = _optical(10 + i)
        yi = (
            y if headings is None else rot.mul(rot.from_axis_angle([0, 0, 1.0], headings[label]), y)
        )
        a = rot.mul(rot.mul(yi, b), x)
        a = rot.mul(a, rot.from_rotvec(rng.normal(0, np.radians(noise_deg), (len(a), 3))))
        out[label] = (a, b)
    return out


def _random(seed: int) -> np.ndarray:
    return rot.normalize(np.random.default_rng(seed).normal(size=4))


def test_full_mode_recovers_both_rotations():
    y = _random(1)
    xs = {"thigh": _random(2), "shank": _random(3), "foot": _random(4)}
    pairs = _pairs(y, xs, noise_deg=0.5)
    pairs["shank"][1][100:200] = np.nan  # an optical gap
    al = align(pairs, "full", RATE)
    assert np.degrees(rot.angle_between(al.lab_to_earth, y)) < 0.05
    for k, x in xs.items():
        assert np.degrees(rot.angle_between(al.sensor_to_cluster[k], x)) < 0.05
        assert al.residual_rms_deg[k] == pytest.approx(0.5 * np.sqrt(3), rel=0.1)
    d = al.record()
    assert d.lab_to_earth.angle_deg == pytest.approx(np.degrees(rot.angle(y)), abs=0.05)


def test_heading_mode_allows_a_heading_per_sensor():
    y = _random(5)
    xs = {"a": _random(6), "b": _random(7)}
    headings = {"a": 0.0, "b": np.radians(25.0)}
    pairs = _pairs(y, xs, headings)
    al = align(pairs, "heading", RATE)
    assert np.degrees(al.heading["b"] - al.heading["a"]) == pytest.approx(25.0, abs=0.01)
    for k in xs:
        assert np.degrees(rot.angle_between(al.sensor_to_cluster[k], xs[k])) < 0.01
        assert al.residual_rms_deg[k] < 0.01
    full = align(pairs, "full", RATE)  # one shared earth frame cannot explain 25°
    assert max(full.residual_rms_deg.values()) > 5.0


def test_none_mode_compares_as_given():
    b = _optical(1)
    tilt = rot.from_axis_angle([1.0, 0, 0], np.radians(3.0))
    al = align({"imu": (rot.mul(tilt, b), b)}, "none", RATE)
    np.testing.assert_allclose(al.lab_to_earth, rot.IDENTITY)
    assert al.residual_rms_deg["imu"] == pytest.approx(3.0)


def test_rotation_about_one_fixed_axis_is_refused_or_flagged():
    b = np.tile(rot.IDENTITY, (500, 1))
    with pytest.raises(InputError, match="too little rotation"):
        align({"imu": (b, b)}, "full", RATE)
    with pytest.raises(InputError, match="mode"):
        align({"imu": (b, b)}, "sideways", RATE)
    hinge = rot.from_axis_angle([0, 0, 1.0], np.sin(np.arange(500) / 20.0))
    al = align({"imu": (hinge, hinge)}, "full", RATE)
    assert al.conditioning["imu"] < 0.01  # X about the hinge axis is not determined


def test_sparsity_pattern():
    """Y's three columns every row; a heading and three X columns only their sensor's rows."""
    from motionlab.validation.align import _sparsity

    got = _sparsity(["a", "b", "c"], ["b", "c"], {"a": 2, "b": 1, "c": 3}).toarray()
    want = np.zeros((18, 14), dtype=int)  # rows: a 0-5, b 6-8, c 9-17
    want[:, :3] = 1  # Y
    want[6:9, 3] = want[9:, 4] = 1  # the headings of b and c
    want[:6, 5:8] = want[6:9, 8:11] = want[9:, 11:14] = 1  # X of a, b, c
    assert np.array_equal(got, want)
