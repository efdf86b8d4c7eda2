"""The sensor error model's statistics match its parameters (Allan deviation, drops, clocks)."""

import numpy as np
import pytest

from motionlab.simulate import simulate
from motionlab.simulate.errors import (
    PRESETS,
    ChannelModel,
    Clock,
    TimingModel,
    apply_channel,
    draw_channel,
    dropped,
    sample_times,
)

RATE = 100.0


def allan(y: np.ndarray, m: int, rate: float) -> np.ndarray:
    """Overlapping Allan deviation (per column) of rate samples at cluster size ``m``."""
    theta = np.cumsum(y, axis=0) / rate
    d = theta[2 * m :] - 2 * theta[m:-m] + theta[: -2 * m]
    tau = m / rate
    return np.sqrt(np.mean(d**2, axis=0) / (2 * tau**2))


def errors_only(model: ChannelModel, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return apply_channel(np.zeros((n, 3)), model, draw_channel(model, rng), RATE, rng)


def test_white_noise_density_by_allan_deviation():
    density = 0.007 * np.pi / 180  # rad/s/√Hz
    y, _ = errors_only(ChannelModel(noise_density=density), 360_000, 1)
    for tau in (0.1, 1.0, 10.0):
        sigma = allan(y, int(tau * RATE), RATE)
        assert sigma == pytest.approx(density / np.sqrt(tau), rel=0.10)


def test_bias_random_walk_slope_and_level():
    k = 1e-4
    y = np.concatenate([errors_only(ChannelModel(bias_walk=k), 360_000, s)[0] for s in range(4)])
    taus = np.array([30.0, 100.0, 300.0])
    sig = np.array([allan(y.reshape(4, -1, 3)[i], int(t * RATE), RATE) for i in range(4)
                    for t in taus]).reshape(4, 3, 3).mean(axis=(0, 2))  # fmt: skip
    slope = np.polyfit(np.log(taus), np.log(sig), 1)[0]
    assert slope == pytest.approx(0.5, abs=0.1)
    assert sig == pytest.approx(k * np.sqrt(taus / 3), rel=0.15)


def test_constant_bias_scale_saturation_and_quantisation():
    model = ChannelModel(bias_sigma=0.1, scale_sigma=0.01, misalignment_sigma=0.01,
                         full_scale=5.0, lsb=0.01)  # fmt: skip
    rng = np.random.default_rng(3)
    draw = draw_channel(model, rng)
    x = np.column_stack([np.linspace(-8, 8, 1601)] * 3)
    y, bias = apply_channel(x, model, draw, RATE, rng)
    assert np.abs(y).max() == pytest.approx(5.0)
    assert np.allclose(y / 0.01, np.round(y / 0.01), atol=1e-9)
    inside = np.abs(x[:, 0]) < 4
    expected = x[inside] @ draw.matrix.T + bias[inside]
    assert np.abs(y[inside] - expected).max() <= 0.005 + 1e-12
    assert np.allclose(bias, draw.bias0)


@pytest.mark.parametrize("fraction,burst", [(0.005, 3.0), (0.03, 10.0)])
def test_dropped_packet_fraction_and_burst_length(fraction, burst):
    mask = dropped(400_000, TimingModel(drop_fraction=fraction, drop_burst=burst),
                   np.random.default_rng(5))  # fmt: skip
    assert mask.mean() == pytest.approx(fraction, rel=0.10)
    edges = np.diff(mask.astype(int))
    assert mask.sum() / (edges == 1).sum() == pytest.approx(burst, rel=0.10)


def test_clock_offset_drift_and_jitter():
    clock = Clock(offset=0.05, drift=100e-6, jitter_s=1e-3)
    stamps, t_true = sample_times(clock, RATE, 600.0, np.random.default_rng(2))
    assert np.allclose(np.diff(stamps), 1 / RATE)
    resid = stamps - (clock.offset + (1 + clock.drift) * t_true)
    assert np.std(resid) == pytest.approx(1e-3, rel=0.05)
    assert t_true.min() > -0.005 and t_true.max() < 600.005


def test_typical_session_records_gaps_biases_and_clocks():
    from test_simulate import knee_protocol

    session, truth = simulate(knee_protocol(), 45.0, 7, "typical", calibration=False)
    for label, s in session.sensors.items():
        info = truth.sensors[label]
        assert len(s.time) == len(info["sample_time"]) == len(info["gyr_bias"])
        gaps = np.diff(s.time) > 1.5 / RATE
        assert gaps.sum() >= 1 and info["dropped"] > 0
        mapped = info["clock_offset_s"] + (1 + info["clock_drift"]) * info["sample_time"]
        assert np.abs(mapped - s.time).max() < 6 * PRESETS["typical"].timing.jitter_s
        assert np.abs(info["gyr_bias"][0]).max() < 5 * PRESETS["typical"].gyr.bias_sigma
