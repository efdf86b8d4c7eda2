"""Allan deviation recovers known white-noise density, bias instability and rate random walk."""

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.sensorcal import allan_analysis, allan_deviation

DEG = np.pi / 180


def white_and_walk(n: int, rate: float, density: float, walk: float, seed: int) -> np.ndarray:
    """White noise of ``density`` (unit/√Hz) plus a random walk of ``walk`` (unit/√s)."""
    rng = np.random.default_rng(seed)
    white = rng.normal(0.0, density * np.sqrt(rate), (n, 3))
    return white + np.cumsum(rng.normal(0.0, walk / np.sqrt(rate), (n, 3)), axis=0)


def flicker(n: int, rate: float, b: float, seed: int) -> np.ndarray:
    """Flicker noise with two-sided PSD ``b² / (2π f)`` (IEEE Std 952: ADEV floor 0.664 b)."""
    rng = np.random.default_rng(seed)
    spec = np.fft.rfft(rng.normal(size=(n, 3)), axis=0)
    f = np.fft.rfftfreq(n, 1.0 / rate)
    f[0] = np.inf
    return np.fft.irfft(spec * np.sqrt(rate * b**2 / (2 * np.pi * f))[:, None], n, axis=0)


def test_white_noise_curve_follows_minus_half_slope():
    rate, density = 100.0, 0.01
    y = white_and_walk(100_000, rate, density, 0.0, seed=0)
    tau, adev = allan_deviation(y, rate)
    assert tau[0] == pytest.approx(0.01) and tau[-1] <= 100.0
    ok = tau <= 10.0  # ≥ 100 clusters
    assert np.allclose(adev[ok], density / np.sqrt(tau[ok])[:, None], rtol=0.1)
    res = allan_analysis(y, rate)
    assert np.allclose(res.white, density, rtol=0.03)
    assert np.isnan(res.random_walk).all()  # not in the signal, not reported


def test_white_noise_and_rate_random_walk_within_ten_percent():
    # consumer-MEMS figures (BMI160-like): 0.007 °/s/√Hz, 0.002 °/s/√s; 1 h at 100 Hz
    rate, density, walk = 100.0, 0.007 * DEG, 0.002 * DEG
    y = white_and_walk(360_000, rate, density, walk, seed=1) + 0.01
    res = allan_analysis(y, rate)
    assert np.allclose(res.white, density, rtol=0.03)
    assert np.allclose(res.random_walk, walk, rtol=0.10)


def test_simulator_error_model_noise_terms_are_recovered():
    simulate = pytest.importorskip("motionlab.simulate.errors")
    model = simulate.PRESETS["harsh"].gyr
    rate, n = 50.0, 360_000  # 2 h
    rng = np.random.default_rng(2)
    draw = simulate.draw_channel(model, rng)
    y, _ = simulate.apply_channel(np.zeros((n, 3)), model, draw, rate, rng)
    res = allan_analysis(y, rate)
    assert np.allclose(res.white, model.noise_density, rtol=0.10)
    assert np.allclose(res.random_walk, model.bias_walk, rtol=0.10)


def test_bias_instability_from_the_flat_floor():
    rate, b, density = 50.0, 1e-3, 2e-4
    y = flicker(180_000, rate, b, seed=3) + white_and_walk(180_000, rate, density, 0.0, seed=4)
    res = allan_analysis(y, rate)
    assert res.bias_instability_flat.all()
    assert np.allclose(res.bias_instability, b, rtol=0.10)
    assert np.allclose(res.white, density, rtol=0.10)
    q = res.quality()
    assert q["bias_instability"] == pytest.approx(list(res.bias_instability))
    assert q["rate_random_walk"] == [None, None, None]


@pytest.mark.parametrize(
    "y, message",
    [
        (np.zeros((10, 3)), "only 10 samples"),
        (np.full((1000, 3), 0.5), "constant"),
        (np.where(np.arange(1000)[:, None] == 9, np.nan, np.ones((1000, 3))), "NaN"),
        (np.ones((1000, 2)), "N×3"),
    ],
)
def test_bad_input_raises(y, message):
    with pytest.raises(InputError, match=message):
        allan_analysis(y, 100.0)


def test_bad_rate_raises():
    with pytest.raises(InputError, match="rate"):
        allan_analysis(np.random.default_rng(0).normal(size=(1000, 3)), 0.0)
