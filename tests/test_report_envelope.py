"""The report's long curves drawn through their envelope per column (``report/pdf.py``)."""

import numpy as np
from matplotlib.figure import Figure

from motionlab.report.pdf import envelope, thin_curves


def _walk(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return np.arange(n) / 100.0, np.cumsum(rng.normal(size=n))


def _columns(x, x0, x1, columns):
    return np.floor((x - x0) * (columns / (x1 - x0)))


def test_the_envelope_keeps_each_columns_lowest_highest_first_and_last_sample():
    x, y = _walk(18_000)
    columns = 300
    keep = envelope(x, y, x[0], x[-1], columns)
    assert len(keep) <= 4 * (columns + 1) < len(x)
    assert np.all(np.diff(keep) > 0)  # in the samples' order
    col, kept = _columns(x, x[0], x[-1], columns), _columns(x[keep], x[0], x[-1], columns)
    for c in np.unique(col):
        ours, theirs = y[keep][kept == c], y[col == c]
        assert ours.min() == theirs.min() and ours.max() == theirs.max()
        first, last = np.flatnonzero(col == c)[[0, -1]]
        assert first in keep and last in keep


def test_a_spike_of_one_sample_survives():
    x = np.arange(10_000) / 100.0
    y = np.sin(x)
    y[4321] = 50.0
    y[7000] = -50.0
    keep = envelope(x, y, x[0], x[-1], 100)
    assert 4321 in keep and 7000 in keep
    assert y[keep].max() == 50.0 and y[keep].min() == -50.0


def test_gaps_stay_gaps_and_samples_outside_the_view_keep_their_extremes():
    x, y = _walk(5_000, seed=1)
    y[1000:1003] = np.nan
    keep = envelope(x, y, 10.0, 30.0, 50)  # the view is part of the trace
    assert {1000, 1001, 1002} <= set(keep)
    assert 999 in keep and 1003 in keep  # the runs on both sides end and start where they did
    assert y[keep][np.isfinite(y[keep])].max() == np.nanmax(y)
    assert y[keep][np.isfinite(y[keep])].min() == np.nanmin(y)
    assert 0 in keep and len(y) - 1 in keep


def _axes(fig: Figure):
    ax = fig.add_axes([0.1, 0.1, 0.5, 0.8])  # 3 in wide: 432 columns at 144 per inch
    return ax


def test_thin_curves_thins_long_plain_curves_only():
    fig = Figure(figsize=(6, 4))
    ax = _axes(fig)
    x, y = _walk(18_000, seed=2)
    long = ax.plot(x, y, lw=0.8)[0]
    short = ax.plot(x[:1500], y[:1500])[0]  # 1500 < 4 × 432 points: untouched
    marked = ax.plot(x, y + 1, "x")[0]  # markers are drawn one per point
    dashed = ax.plot(x, y - 1, "--")[0]  # a dash pattern runs along the whole line
    limits = ax.get_xlim(), ax.get_ylim()
    thin_curves(fig)
    assert ax.get_xlim() == limits[0] and ax.get_ylim() == limits[1]
    assert 1000 < len(long.get_xdata()) <= 4 * 433
    assert long.get_ydata().max() == y.max() and long.get_ydata().min() == y.min()
    np.testing.assert_array_equal(short.get_ydata(), y[:1500])
    for line, offset in ((marked, 1), (dashed, -1)):
        np.testing.assert_array_equal(line.get_ydata(), y + offset)


def test_thin_curves_leaves_curves_whose_x_goes_back():
    fig = Figure(figsize=(6, 4))
    ax = _axes(fig)
    t = np.linspace(0, 20 * np.pi, 20_000)
    loop = ax.plot(np.cos(t), np.sin(t))[0]
    thin_curves(fig)
    assert len(loop.get_xdata()) == len(t)
