"""motionlab.dsp against scipy.signal, whose algorithms it follows (the tests may import it; the
product does not, for its import time)."""

import numpy as np
import pytest
from scipy import signal

from motionlab import dsp


@pytest.mark.parametrize(
    "order, hz, fs, btype",
    [
        (2, 6.0, 100.0, "lowpass"),
        (4, 6.0, 100.0, "lowpass"),
        (4, 40.0, 100.0, "lowpass"),
        (3, 10.0, 120.0, "lowpass"),
        (5, 2.0, 60.0, "highpass"),
        (2, (5.0, 25.0), 100.0, "bandpass"),
        (4, (8.0, 30.0), 200.0, "bandpass"),
    ],
)
def test_butterworth_sections_are_scipys(order, hz, fs, btype):
    ours = dsp.butter(order, hz, fs, btype)
    theirs = signal.butter(order, hz, btype, fs=fs, output="sos")
    np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(dsp.sosfilt_zi(ours), signal.sosfilt_zi(theirs), rtol=1e-9)


def test_a_lowpass_passes_dc_and_stops_above_its_cut_off():
    sos = dsp.butter(4, 5.0, 100.0)
    b, a = sos[:, :3].sum(axis=1), sos[:, 3:].sum(axis=1)
    assert np.prod(b / a) == pytest.approx(1.0, abs=1e-12)  # gain 1 at 0 Hz
    t = np.arange(2000) / 100.0
    y = dsp.sosfiltfilt(sos, np.sin(2 * np.pi * 20.0 * t))
    assert np.abs(y[200:-200]).max() < 1e-3  # 20 Hz: 4 octaves above, two passes


def test_bad_designs_are_refused():
    bad = [(0, 5.0, 100.0), (2, 60.0, 100.0), (2, 0.0, 100.0), (2, 5.0, 100.0, "bandstop"),
           (2, (5.0, 60.0), 100.0, "bandpass")]  # fmt: skip
    for args in bad:
        with pytest.raises(ValueError):
            dsp.butter(*args)


@pytest.mark.parametrize(
    "shape, axis", [((500,), -1), ((400, 3), 0), ((3, 400), 1), ((7, 300), -1)]
)
def test_zero_phase_filtering_is_scipys(shape, axis):
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(size=shape), axis=axis)
    sos = dsp.butter(4, 6.0, 100.0)
    np.testing.assert_allclose(
        dsp.sosfiltfilt(sos, x, axis=axis),
        signal.sosfiltfilt(sos, x, axis=axis),
        rtol=1e-10,
        atol=1e-10,
    )


def test_too_short_a_signal_is_refused_as_scipy_does():
    sos = dsp.butter(2, 6.0, 100.0)
    with pytest.raises(ValueError, match="padlen"):
        dsp.sosfiltfilt(sos, np.zeros(9))
    with pytest.raises(ValueError, match="padlen"):
        signal.sosfiltfilt(sos, np.zeros(9))
    for n_sections in (1, 2, 3):  # the shortest signal each takes, as scipy's
        sos = dsp.butter(2 * n_sections, 6.0, 100.0)
        edge = dsp.padlen(sos)
        assert edge == 3 * (2 * n_sections + 1)
        signal.sosfiltfilt(sos, np.zeros(edge + 1))
        with pytest.raises(ValueError, match="padlen"):
            signal.sosfiltfilt(sos, np.zeros(edge))


def test_peaks_are_scipys():
    rng = np.random.default_rng(4)
    t = np.arange(3000) / 100.0
    x = np.sin(2 * np.pi * 0.9 * t) * (1 + 0.3 * np.sin(0.2 * t)) + 0.2 * rng.normal(size=len(t))
    x[100:110] = x[100:110].max() + 1.0  # a plateau
    x[2000:2004] = 5.0  # a plateau of even length
    conditions = [{}, {"height": 0.5}, {"distance": 40}, {"prominence": 0.8},
                  {"height": 0.2, "distance": 60},
                  {"prominence": 1.0, "distance": 25.5}]  # fmt: skip
    for kwargs in conditions:
        ours, props = dsp.find_peaks(x, **kwargs)
        theirs, expected = signal.find_peaks(x, **kwargs)
        np.testing.assert_array_equal(ours, theirs)
        assert props.keys() == expected.keys()
        for key in props:
            np.testing.assert_allclose(props[key], expected[key])


def test_peaks_of_hand_made_signals():
    x = np.array([0, 2, 2, 2, 1, 3, 0, 1, 1, 0, 0, 4, 4], float)
    peaks, _ = dsp.find_peaks(x)
    np.testing.assert_array_equal(peaks, [2, 5, 7])  # middles of plateaus; the last run never
    peaks, props = dsp.find_peaks(x, prominence=0.5)
    np.testing.assert_allclose(props["prominences"], [1, 3, 1])  # above the higher of both sides
    np.testing.assert_array_equal(props["left_bases"], [0, 0, 6])
    np.testing.assert_array_equal(dsp.find_peaks(x, prominence=1.5)[0], [5])
    np.testing.assert_array_equal(dsp.find_peaks(x, distance=4)[0], [5])  # the higher one stays
    assert len(dsp.find_peaks(np.array([1.0, 2.0]))[0]) == 0


def test_correlation_is_scipys():
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=301), rng.normal(size=301)
    np.testing.assert_allclose(
        dsp.correlate(a, b), signal.correlate(a, b, method="fft"), atol=1e-10
    )
    c = np.zeros(50)
    c[10] = 1.0
    d = np.zeros(50)
    d[3] = 1.0
    assert np.argmax(dsp.correlate(c, d)) - (len(d) - 1) == 7  # c is d delayed by 7 samples
