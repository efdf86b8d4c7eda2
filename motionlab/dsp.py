"""The few signal-processing steps the pipeline uses — Butterworth design, zero-phase filtering,
peaks, correlation — computed as :mod:`scipy.signal` computes them, without importing it.

Why not :mod:`scipy.signal` itself: in SciPy 1.17 (measured), importing it loads
:mod:`scipy.stats` and rewrites every function's docstring for its array-API dispatch, 0.6–1.3 s
of every ``motionlab run`` in a new process (``python -X importtime``), for five functions. Each
function here follows scipy's algorithm and order of operations, so the numbers agree to
rounding; the tests compare them with scipy's (``tests/test_dsp.py``). The simulator still uses
:mod:`scipy.signal` (``cont2discrete``, ``lfilter``): it is not on a session's path.

References: scipy.signal ``butter`` (analogue prototype, frequency pre-warping, bilinear
transform), ``zpk2sos`` (nearest pairing), ``sosfilt_zi``, ``sosfiltfilt`` (odd extension),
``find_peaks`` (plateau middles, height, distance, prominence), ``correlate`` (full, FFT).
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.fft

# ------------------------------------------------------------------------------ design


def butter(
    order: int, hz: float | tuple[float, float], fs: float, btype: str = "lowpass"
) -> np.ndarray:
    """Digital Butterworth filter as second-order sections (S, 6), ``b0 b1 b2 1 a1 a2`` per row:
    ``scipy.signal.butter(order, hz, btype, fs=fs, output="sos")``.

    ``hz`` the cut-off (Hz; a pair for ``"bandpass"``), ``fs`` the sampling rate (Hz);
    ``btype`` ``"lowpass"``, ``"highpass"`` or ``"bandpass"``. Raises ValueError for a cut-off
    outside (0, fs/2) or an order below 1.
    """
    if int(order) != order or order < 1:
        raise ValueError(f"filter order must be a positive integer, not {order}")
    wn = 2.0 * np.atleast_1d(np.asarray(hz, float)) / fs  # of the Nyquist frequency
    if btype not in ("lowpass", "highpass", "bandpass") or len(wn) != (
        2 if btype == "bandpass" else 1
    ):
        raise ValueError(f"btype {btype!r} with cut-off {hz}: give one cut-off for low- or "
                         "high-pass, two for band-pass")  # fmt: skip
    if not np.all((wn > 0) & (wn < 1)):
        raise ValueError(f"cut-off {hz} Hz must lie between 0 and half the rate ({fs / 2:g} Hz)")
    n = int(order)
    p = -np.exp(1j * np.pi * np.arange(-n + 1, n, 2) / (2 * n))  # analogue prototype, ω = 1
    z = np.zeros(0, complex)
    k = 1.0
    warped = 4.0 * np.tan(np.pi * wn / 2.0)  # pre-warped for the bilinear transform at fs = 2
    if btype == "lowpass":
        p, k = warped[0] * p, k * warped[0] ** n
    elif btype == "highpass":
        k = k * np.real(1.0 / np.prod(-p))
        p = warped[0] / p
        z = np.zeros(n, complex)
    else:
        bw, wo = warped[1] - warped[0], np.sqrt(warped[0] * warped[1])
        p_lp = p * bw / 2.0
        p = np.concatenate([p_lp + np.sqrt(p_lp**2 - wo**2), p_lp - np.sqrt(p_lp**2 - wo**2)])
        z = np.zeros(n, complex)
        k = k * bw**n
    # bilinear transform (fs = 2): s = 4 (z - 1) / (z + 1)
    degree = len(p) - len(z)
    k = k * np.real(np.prod(4.0 - z) / np.prod(4.0 - p))
    z = np.concatenate([(4.0 + z) / (4.0 - z), -np.ones(degree)])
    p = (4.0 + p) / (4.0 - p)
    return _zpk_to_sos(z, p, k)


def _zpk_to_sos(z: np.ndarray, p: np.ndarray, k: float) -> np.ndarray:
    """Sections from real zeros, conjugate-paired poles and a gain, paired as scipy's
    ``zpk2sos(pairing="nearest")``: the pole nearest the unit circle goes last, each pole (pair)
    with the nearest remaining zeros, the gain in the first section."""
    z = np.real(z)
    if len(p) % 2:
        p, z = np.r_[p, 0.0], np.r_[z, 0.0]
    real = np.abs(p.imag) <= 100 * np.finfo(float).eps * np.abs(p)
    p = np.r_[p[~real & (p.imag > 0)], p[real].real]  # one of each conjugate pair, then reals
    sos = np.zeros((len(z) // 2, 6))
    for si in range(len(sos) - 1, -1, -1):
        i = int(np.argmin(np.abs(1.0 - np.abs(p))))
        p1, p = p[i], np.delete(p, i)
        if np.isreal(p1):
            reals = np.flatnonzero(np.isreal(p))
            j = reals[np.argmin(np.abs(np.abs(p[reals]) - 1.0))]
            p2, p = p[j], np.delete(p, j)
        else:
            p2 = np.conj(p1)
        zeros = []
        for _ in range(2):
            j = int(np.argmin(np.abs(z - p1)))
            zeros.append(z[j])
            z = np.delete(z, j)
        sos[si, :3] = np.poly(zeros)
        sos[si, 3:] = np.real(np.poly([p1, p2]))
    sos[0, :3] *= k
    return sos


def sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    """Each section's steady state (S, 2) for a unit step: ``scipy.signal.sosfilt_zi``."""
    zi = np.empty((len(sos), 2))
    scale = 1.0
    for s, (b0, b1, b2, _, a1, a2) in enumerate(np.asarray(sos, float)):
        # I - companion(a)^T, and b's part the state carries
        zi[s] = scale * np.linalg.solve([[1.0 + a1, -1.0], [a2, 1.0]], [b1 - a1 * b0, b2 - a2 * b0])
        scale *= (b0 + b1 + b2) / (1.0 + a1 + a2)
    return zi


# ------------------------------------------------------------------------------ filtering


def sosfiltfilt(sos: np.ndarray, x: np.ndarray, axis: int = -1) -> np.ndarray:
    """Zero-phase filtering of ``x`` along ``axis``: ``scipy.signal.sosfiltfilt(sos, x, axis)``
    (odd extension by 3 × (2 S + 1) samples, less the sections' trailing zero coefficients; the
    cascade forward from its steady state times the first sample, then backward).

    Raises ValueError when ``x`` is not longer than the extension, as scipy does.
    """
    sos = np.ascontiguousarray(sos, float)
    x = np.asarray(x, float)
    edge = padlen(sos)
    n = x.shape[axis]
    if n <= edge:
        raise ValueError(
            f"The length of the input vector x must be greater than padlen, which is {edge}."
        )
    rows = np.ascontiguousarray(np.moveaxis(x, axis, -1).reshape(-1, n))
    out = np.empty_like(rows)
    filtfilt_at(rows, sos, sosfilt_zi(sos), edge, np.arange(n), out)
    return np.moveaxis(out.reshape(np.moveaxis(x, axis, -1).shape), -1, axis)


def padlen(sos: np.ndarray) -> int:
    """Samples :func:`sosfiltfilt` extends each end by (scipy's default): 3 × (2 S + 1), less
    the sections' trailing zero coefficients; a signal must be longer than this."""
    sos = np.asarray(sos, float)
    taps = 2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * taps


def filtfilt_at(
    x: np.ndarray, sos: np.ndarray, zi: np.ndarray, edge: int, use: np.ndarray, out: np.ndarray
) -> None:
    """``sosfiltfilt(sos, x, axis=-1)[:, use]`` (extension ``edge``) into ``out`` (R, K), for
    ``x`` (R, N), by scipy's own steps and in its order of operations, so to the bit (odd
    extension by ``edge`` samples at each end; the cascade run forward from ``zi × first``,
    then backward from ``zi × last``, ``zi`` from :func:`sosfilt_zi`; each section in
    transposed direct form II, as ``scipy.signal.sosfilt``), without padded copies or axis
    moves. One row at a time, or for many rows all rows at each sample (independent lanes the
    compiler vectorises: 14 rows in half the time)."""
    if x.shape[0] > 2:
        _filtfilt_lanes(x, sos, zi, edge, use, out)
    else:
        _filtfilt_rows(x, sos, zi, edge, use, out)


@numba.njit(cache=True, inline="always")
def _section(sos, s, cur, z0, z1):
    """One second-order section (transposed direct form II) at one sample: the output, and
    the new state."""
    new = sos[s, 0] * cur + z0
    return new, sos[s, 1] * cur - sos[s, 4] * new + z1, sos[s, 2] * cur - sos[s, 5] * new


@numba.njit(cache=True)
def _filtfilt_rows(x, sos, zi, edge, use, out):
    n = x.shape[1]
    m = n + 2 * edge
    y = np.empty(m)
    z = np.empty((sos.shape[0], 2))
    for r in range(x.shape[0]):
        first, last = x[r, 0], x[r, n - 1]
        for k in range(edge):
            y[k] = 2 * first - x[r, edge - k]
            y[n + edge + k] = 2 * last - x[r, n - 2 - k]
        for k in range(n):
            y[edge + k] = x[r, k]
        for start, stop, step in ((0, m, 1), (m - 1, -1, -1)):  # forward, then backward
            for s in range(sos.shape[0]):
                z[s, 0], z[s, 1] = zi[s, 0] * y[start], zi[s, 1] * y[start]
            for k in range(start, stop, step):
                cur = y[k]
                for s in range(sos.shape[0]):
                    cur, z[s, 0], z[s, 1] = _section(sos, s, cur, z[s, 0], z[s, 1])
                y[k] = cur
        for j in range(len(use)):
            out[r, j] = y[edge + use[j]]


@numba.njit(cache=True)
def _filtfilt_lanes(x, sos, zi, edge, use, out):
    lanes, n = x.shape
    m = n + 2 * edge
    y = np.empty((m, lanes))
    for r in range(lanes):
        first, last = x[r, 0], x[r, n - 1]
        for k in range(edge):
            y[k, r] = 2 * first - x[r, edge - k]
            y[n + edge + k, r] = 2 * last - x[r, n - 2 - k]
        for k in range(n):
            y[edge + k, r] = x[r, k]
    z0 = np.empty((sos.shape[0], lanes))
    z1 = np.empty((sos.shape[0], lanes))
    for start, stop, step in ((0, m, 1), (m - 1, -1, -1)):  # forward, then backward
        for s in range(sos.shape[0]):
            for r in range(lanes):
                z0[s, r], z1[s, r] = zi[s, 0] * y[start, r], zi[s, 1] * y[start, r]
        for k in range(start, stop, step):
            for s in range(sos.shape[0]):
                for r in range(lanes):
                    y[k, r], z0[s, r], z1[s, r] = _section(sos, s, y[k, r], z0[s, r], z1[s, r])
    for j in range(len(use)):
        for r in range(lanes):
            out[r, j] = y[edge + use[j], r]


# ------------------------------------------------------------------------------ peaks


def find_peaks(
    x: np.ndarray,
    height: float | None = None,
    distance: float | None = None,
    prominence: float | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Indices of the local maxima of ``x`` (1-D) and their properties:
    ``scipy.signal.find_peaks(x, height=, distance=, prominence=)`` with lower bounds only.

    A flat peak counts once, at its middle (the left one of two). The conditions apply in
    scipy's order: ``height`` (at least), ``distance`` (samples; the higher peak of two closer
    ones stays), ``prominence`` (at least; the peak above the higher of the lowest points on
    each side before a higher sample). The properties are ``peak_heights`` and ``prominences``,
    ``left_bases``, ``right_bases`` for the conditions given.
    """
    x = np.asarray(x, float)
    peaks = _local_maxima(x)
    props: dict[str, np.ndarray] = {}
    if height is not None:
        keep = x[peaks] >= height
        peaks, props["peak_heights"] = peaks[keep], x[peaks][keep]
    if distance is not None:
        if distance < 1:
            raise ValueError("`distance` must be greater or equal to 1")
        order = np.argsort(x[peaks])  # numpy's sort, as scipy's, for the order of equal heights
        keep = _select_by_distance(peaks, order, int(np.ceil(distance)))
        peaks, props = peaks[keep], {k: v[keep] for k, v in props.items()}
    if prominence is not None:
        prom, left, right = _prominences(x, peaks)
        keep = prom >= prominence
        props.update(prominences=prom, left_bases=left, right_bases=right)
        peaks, props = peaks[keep], {k: v[keep] for k, v in props.items()}
    return peaks, props


def _local_maxima(x: np.ndarray) -> np.ndarray:
    """The samples higher than both neighbours, a run of equal samples counted as one sample
    at its middle (rounded down), the first and last run never."""
    if len(x) < 3:
        return np.zeros(0, dtype=np.intp)
    starts = np.r_[0, np.flatnonzero(x[1:] != x[:-1]) + 1]  # of the runs of equal values
    ends = np.r_[starts[1:] - 1, len(x) - 1]
    v = x[starts]
    top = np.flatnonzero((v[1:-1] > v[:-2]) & (v[1:-1] > v[2:])) + 1
    return ((starts[top] + ends[top]) // 2).astype(np.intp)


@numba.njit(cache=True)
def _select_by_distance(peaks, order, distance):
    keep = np.ones(len(peaks), dtype=np.bool_)
    for i in range(len(peaks) - 1, -1, -1):
        j = order[i]
        if not keep[j]:
            continue
        k = j - 1
        while k >= 0 and peaks[j] - peaks[k] < distance:
            keep[k] = False
            k -= 1
        k = j + 1
        while k < len(peaks) and peaks[k] - peaks[j] < distance:
            keep[k] = False
            k += 1
    return keep


@numba.njit(cache=True)
def _prominences(x, peaks):
    prom = np.empty(len(peaks))
    left = np.empty(len(peaks), dtype=np.intp)
    right = np.empty(len(peaks), dtype=np.intp)
    for n in range(len(peaks)):
        peak = peaks[n]
        i, left[n], left_min = peak, peak, x[peak]
        while i >= 0 and x[i] <= x[peak]:
            if x[i] < left_min:
                left_min, left[n] = x[i], i
            i -= 1
        i, right[n], right_min = peak, peak, x[peak]
        while i < len(x) and x[i] <= x[peak]:
            if x[i] < right_min:
                right_min, right[n] = x[i], i
            i += 1
        prom[n] = x[peak] - max(left_min, right_min)
    return prom, left, right


# ------------------------------------------------------------------------------ correlation


def correlate(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Full cross-correlation of two real 1-D arrays, ``c[k] = Σ a[n + k − (len(b) − 1)] b[n]``
    (length ``len(a) + len(b) − 1``), by FFT: ``scipy.signal.correlate(a, b, method="fft")``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = len(a) + len(b) - 1
    size = scipy.fft.next_fast_len(n, real=True)
    c = scipy.fft.irfft(scipy.fft.rfft(a, size) * scipy.fft.rfft(b[::-1], size), size)
    return c[:n]
