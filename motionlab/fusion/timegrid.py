"""Time-aware fusion: packet-loss gaps filled for the filters, results taken back to the stamps.

The estimators integrate the gyroscope with a fixed interval ``1/rate``. A recording with lost
packets has intervals far longer than that (ingest fills gaps up to ``--gap-max``, 0.1 s by
default, and leaves longer ones), and a filter that integrates such a gap as one sample misses
the rotation of the whole gap: at 100 Hz a 0.5 s gap during a 200 °/s knee swing loses 100°.

:func:`gap_grid` therefore builds, from the recorded stamps, a sample grid on which every
interval is about ``1/rate``: the recorded instants themselves, plus, inside every interval longer
than ``GAP_FACTOR / rate`` (the gap definition of :mod:`motionlab.timebase`), equally spaced
instants at about ``1/rate``. The inputs are interpolated onto the filled instants, the estimator
runs on the grid, and the results are taken back to the recorded stamps. As every recorded
instant is on the grid, taking back is a selection of rows (what SLERP resampling at the grid's
own instants would return), and recordings without a gap reach the estimator unchanged. Clock
jitter is not resampled: stamps that scatter around a regular sampling would otherwise move real
samples, and the integration errors of jittered intervals cancel from one interval to the next.

Interpolation: a gap up to ``CUBIC_MAX_S`` is bridged by a cubic Hermite curve through the two
samples either side with the slopes of the recorded intervals next to the gap (one-sided
differences), longer gaps linearly. What the filter loses in a gap is the integral of the rate
it does not see, and a straight line misses the curvature of a swinging limb. On a simulated
0.8 Hz, 6 rad/s swing (``tests/test_fusion_timegrid.py``, 6 gap positions) a 6-D smoother was
1.2° RMS off without a gap; with one gap of 0.3 / 0.5 / 0.8 s it was 3.4 / 14.7 / 31° off
bridged linearly and 1.24 / 1.95 / 17° bridged by the cubic. At 1 s the cubic overshoots (63°,
linear 23°): the movement in such a gap is not recoverable, and the straight line invents least.
On a real walk the one-sided slopes are noise (tissue ringing, 300-800 °/s transients at heel
strikes and knocks): over 300 gaps of 0.12-0.5 s cut at random into the walk of the 16-IMU
recording (five lower-body sensors, 100 Hz) the cubic missed a median 72° of rotation (90th
percentile 519°, worst 1816°), the line 27° (104°, 229°), and a 0.14-s gap on the left thigh
bridged by the cubic put 66° into its 6-D heading, which the hip (its heading tied at the stand
only) then carried: hip_l 24° SD off the unbroken recording's. So each gap up to ``CUBIC_MAX_S``
takes the bridge its own test gaps (below) say misses less (:func:`gap_noise` with ``choose``):
on that walk the line every time, on the simulated swings and walks mostly the cubic
(``bench/real_world.py`` walk seeds 0-19: knee and hip flexion RMSE within 0.06° of the
cubic-only means). A gap across a fast turn still loses what the line cannot see, and in 6-D its
turn about the vertical stays in the heading (a hip keeps it; a knee's hinge ties take it out
within seconds).

A repeating movement offers a third bridge, the **pattern** (:func:`with_patterns`): the
recorded stretch within ``PATTERN_SEARCH_S`` (10 s) whose surroundings (``PATTERN_CONTEXT_S``,
0.2 s of rate either side, least squared difference) match the gap's best is copied into the
gap and shifted by a line to meet the samples either side, the idea of waveform-similarity
packet-loss concealment in speech coding. The copied stretch must be recorded with its
surroundings and lie clear of the gap's. It is chosen as the others are, by the gap's own test
gaps (at most ``PATTERN_TESTS`` of them, those whose surroundings were recorded too, so that the
filled samples, however bridged, take no part; each matched away from itself and from the gap).

A walk's strides repeat more closely than any line through one of them: over 200 test gaps of
3, 7 and 14 samples cut into the walking of the real 16-IMU recording (``bench/gap_bridges.py``,
five lower-body sensors, 100 Hz) the bridge the fusion chooses missed a median 1.3-1.5° /
4.2° / 9.1-9.3° of rotation on the thighs where the line missed 3.2 / 10.4-12.7 / 21.1-21.3°
(RMS 3.8-4.1 / 9.0-9.3 / 14.5-15.7° against 7.6-7.7 / 19.0-20.8 / 30.1-31.6°), taking the
pattern for 86-99 % of the leg sensors' gaps; on a rate that does not repeat it takes it never
(``tests/test_fusion_timegrid.py``). Judged with test gaps whose surroundings held the gap's
filled samples, the choice had missed more in the tails (left thigh, 14 samples: RMS 20.6°
against the pattern's own 15.7°).

On the simulated walks, whose sensors lose 0.5 % of their packets in bursts, what the line and
cubic missed had been the largest part of the knees' and hips' flexion error
(``bench/real_world.py --protocols walk --seeds 0-9``): worst knee flexion 1.93 / 2.84° →
1.57 / 1.94° (right / left), hips 1.82 / 2.36° → 1.49 / 1.63°; without any packet lost seed 9's
left knee was 1.74°, with the losses bridged by line and cubic 2.84°, by the pattern 1.81°.
Where the simulated walk's markers are hidden (``bench/marker_fusion.py``, 15 sensors, mean)
the IMU-only orientations gained most: ekf 1.91 → 1.61°, ukf 1.61 → 1.32°, particle 1.62 →
1.47°, liu_gn 3.99 → 3.93°.

Movement that does not repeat takes the pattern less often: ``bench/real_world.py``'s free arm
movement is unchanged to 0.01°, and on test gaps cut into three real seated trunk trials'
``Back`` and ``Chest`` (``bench/gap_bridges.py --trunk``, 50 Hz) it is taken for 0-50 % of them.
There the chosen bridge misses within 0.3° RMS of the better of line and cubic for the 3- and
7-sample gaps; for the 14-sample ones (0.28 s) up to 2° more (Aag/trunkmovement_ls ``Back``: 7.8°
against the line's 5.8°, the pattern taken for 21 %); judged with test gaps nearer the gap (as
the line and cubic are) five of those six had missed 0.1-0.8° less and one 0.7° more.
``bench/real_trunk.py``'s medians stay within 0.1° (rotation from rest 1.63 → 1.62°).

Cost: about 1 ms per gap (the test gaps' searches and the gap's own share one matrix product; a
10-min simulated walk's thigh with 100 gaps fuses in 0.13 s against 0.043 s without the
pattern, a 1-h recording at 100 Hz with 587 gaps in 0.96 s against 0.35 s). Above 100 Hz
every k-th sample of the surroundings is matched (at most ``PATTERN_CONTEXT_SAMPLES`` per side),
so that a 2-kHz recording searches no more numbers per candidate than a 100-Hz one.

What the bridge misses is not known, and a filter that takes the bridged rate as measured
carries the missed rotation on as an inclination error that its weak accelerometer correction
removes only over tens of seconds: a 0.14 s gap in a simulated shank's swing put it 21° off and
raised its inclination error over the walk from 0.9° (no packets lost) to 3.0° (RMS). An estimator
that takes ``gaps`` (the default smoother; ``liu_gn`` for its marker steps) is therefore told,
per gap, how uncertain its bridge is (:func:`gap_noise`): the rotation the same bridge misses on
gaps of the same length cut, as a test, out of the recorded samples within ``NOISE_WINDOW_S``
either side (leave-out cross-validation of the bridge on the movement around the gap; per axis,
the RMS over those test gaps), added to the attitude covariance at the first recorded sample
after the gap. A gap at rest or in a smooth swing gets almost nothing (the bridge is good
there), a gap across a heel strike's ringing gets degrees, and there the accelerometer on either
side decides. Gaps that ingest already filled (``--gap-max``, linearly; ``filled`` spans, as
``SensorStream.qc`` lists them in ``filled_spans_s``) are judged the same way with the linear
bridge. On that walk: 3.03°
→ 1.44° for the shank, 1.57° → 0.99° for the thigh, sensors with only small gaps unchanged.
The test gaps judge the bridge by the movement around the gap: a transient that falls inside
the gap alone (a knock that starts and ends in it) is not seen, and its bridge noise is that of
the quieter movement around it (that 21° gap got 7.4°, which was enough). Nor is a pattern
copied from another movement: where the movement does not repeat, the stretch whose
surroundings match best can hold a turn the gap never had (a simulated seated trunk's pelvis,
0.42 s lost as a quick lean ended: 26° added where the test gaps said 2.8°). Either bridge may
be the true one, so a pattern's noise is at least its distance from the line or cubic it
displaced (:func:`_disagreement`; 21° there, and the lumbar angles `not determined`). On the
simulated walks, where the pattern repeats a stride and is right, that floor raised two hips'
gap turns over the 10° of ``segments.grades.GAP_TURN_DEG`` (`weak`; docs/simulator.md).

Marker reference vectors (:class:`~motionlab.fusion.markers.MarkerReferences`) are measured at the
recorded instants only: the filled instants get none (NaN), so inside a gap the filters run on
the IMU alone, as they do where the markers are hidden.

Conventions: time in s, strictly increasing; arrays have the samples along the first axis.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from motionlab.errors import InputError
from motionlab.timebase import GAP_FACTOR

CUBIC_MAX_S = 0.8  # longest gap bridged by a cubic (s); longer ones linearly
NOISE_WINDOW_S = 0.5  # test gaps for a gap's bridge noise start within this of it (s)
PATTERN_CONTEXT_S = 0.2  # the recorded rate matched on either side of a gap (s)
PATTERN_SEARCH_S = 10.0  # a gap's pattern is sought within this of it (s)
PATTERN_TESTS = 12  # test gaps (at most) that judge a gap's pattern bridge
PATTERN_CONTEXT_SAMPLES = 20  # samples matched at most per side (every k-th at high rates)

if TYPE_CHECKING:
    from motionlab.fusion.markers import MarkerReferences
    from motionlab.fusion.registry import FusionResult


@dataclass(frozen=True)
class GapGrid:
    """A near-uniform sample grid around the recorded stamps.

    Attributes
    ----------
    stamps
        (N,) the recorded times (s).
    time
        (M,) the grid (s), M ≥ N: the stamps plus the instants filled into the gaps.
    index
        (N,) position of every recorded sample on the grid (``time[index] == stamps``).
    spans
        (K, 2) ``[start_s, end_s]`` of every filled gap (the stamps either side of it).
    before
        (M − N,) for every filled instant, the recorded sample before its gap.
    """

    stamps: np.ndarray
    time: np.ndarray
    index: np.ndarray
    spans: np.ndarray
    before: np.ndarray

    @property
    def filled(self) -> int:
        """Number of instants filled into the gaps."""
        return len(self.time) - len(self.stamps)

    def vectors(
        self, arr: np.ndarray | None, linear: np.ndarray | None = None
    ) -> np.ndarray | None:
        """(N, 3) samples at the recorded stamps → (M, 3) on the grid (see the module notes);
        ``linear`` (M,) bool: the filled instants to bridge linearly (default: the gaps over
        ``CUBIC_MAX_S``; :func:`gap_noise` with ``choose`` chooses)."""
        if arr is None:
            return None
        t, i = self.stamps, self.before
        j = i + 1
        out = np.empty((len(self.time), arr.shape[1]))
        out[self.index] = arr
        h = (t[j] - t[i])[:, None]
        chord = (arr[j] - arr[i]) / h
        left = np.where(i[:, None] > 0, _slope(t, arr, i - 1, i), chord)
        right = np.where(j[:, None] < len(t) - 1, _slope(t, arr, j, j + 1), chord)
        s = ((self.time[self._filled] - t[i]) / h[:, 0])[:, None]
        cubic = _hermite(s, h, arr[i], arr[j], left, right)
        line = arr[i] + s * (arr[j] - arr[i])
        flat = h > CUBIC_MAX_S if linear is None else np.asarray(linear)[self._filled][:, None]
        out[self._filled] = np.where(flat, line, cubic)
        return out

    @property
    def _filled(self) -> np.ndarray:
        """Grid positions of the filled instants."""
        mask = np.ones(len(self.time), bool)
        mask[self.index] = False
        return np.flatnonzero(mask)

    def references(self, refs: MarkerReferences) -> MarkerReferences:
        """Marker references on the grid: the recorded rows kept, none (NaN) at filled instants."""
        earth = np.full((len(self.time),) + refs.earth.shape[1:], np.nan)
        earth[self.index] = refs.earth
        return dataclasses.replace(refs, earth=earth)

    def back(self, result: FusionResult) -> FusionResult:
        """``result`` of a run on the grid, at the recorded stamps (every per-sample array, in
        the attributes and in ``extra``), with ``extra["resampled"]`` describing the gaps."""
        m = len(self.time)

        def take(value):
            if isinstance(value, np.ndarray) and value.ndim >= 1 and len(value) == m:
                return np.ascontiguousarray(value[self.index])
            return value

        extra = {key: take(value) for key, value in result.extra.items()}
        extra["resampled"] = {"spans_s": self.spans, "samples_filled": self.filled}
        return dataclasses.replace(
            result,
            quat=take(result.quat),
            gyro_bias=take(result.gyro_bias),
            rest=take(result.rest),
            mag_disturbed=take(result.mag_disturbed),
            extra=extra,
        )


def checked_time(time: np.ndarray, n: int) -> np.ndarray:
    """``time`` as (n,) float64, finite and strictly increasing, else :class:`InputError`."""
    t = np.asarray(time, dtype=float)
    if t.shape != (n,):
        raise InputError(
            f"time has shape {t.shape}, the sensor has {n} samples",
            where="time",
            remedy="give one time stamp (s) per sample",
        )
    if not np.isfinite(t).all():
        k = int(np.argmin(np.isfinite(t)))
        raise InputError(f"time stamp {k} is not finite", where="time", remedy="ingest first")
    steps = np.diff(t)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0)) + 1
        raise InputError(
            f"time does not increase at sample {k} ({t[k - 1]:.6g} s → {t[k]:.6g} s)",
            where="time",
            remedy="repair the clock first (motionlab ingest does)",
        )
    return t


def gap_grid(time: np.ndarray, rate: float) -> GapGrid | None:
    """The grid of ``time`` (s) at ``rate`` (Hz), or ``None`` when no interval is a gap.

    A gap of length ``T`` gets ``round(T · rate) − 1`` equally spaced instants (at least one), so
    its intervals are ``1/rate`` to within half a sample spread over the gap.
    """
    t = np.asarray(time, dtype=float)
    gaps = np.flatnonzero(np.diff(t) > GAP_FACTOR / rate)
    if not len(gaps):
        return None
    span = t[gaps + 1] - t[gaps]
    missing = np.maximum(np.round(span * rate).astype(np.int64) - 1, 1)
    owner = np.repeat(np.arange(len(gaps)), missing)
    step = np.arange(len(owner)) - np.repeat(np.cumsum(missing) - missing, missing) + 1
    filled = t[gaps][owner] + step * (span / (missing + 1))[owner]
    grid = np.sort(np.concatenate([t, filled]))
    index = np.searchsorted(grid, t)
    spans = np.column_stack([t[gaps], t[gaps + 1]])
    return GapGrid(t, grid, index, spans, gaps[owner])


def _hermite(s, h, a, b, left, right) -> np.ndarray:
    """Cubic Hermite interpolation at ``s`` (0 at ``a``, 1 at ``b``) over a span ``h`` (s) with
    the slopes ``left`` and ``right`` at its ends (arrays broadcast together)."""
    return (
        (2 * s**3 - 3 * s**2 + 1) * a
        + (s**3 - 2 * s**2 + s) * h * left
        + (3 * s**2 - 2 * s**3) * b
        + (s**3 - s**2) * h * right
    )


def _slope(t: np.ndarray, arr: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Difference quotients between samples ``a`` and ``b`` (clipped into range)."""
    a, b = np.clip(a, 0, len(t) - 1), np.clip(b, 0, len(t) - 1)
    dt = np.where(b > a, t[b] - t[a], 1.0)
    return (arr[b] - arr[a]) / dt[:, None]


@dataclass(frozen=True)
class GapNoise:
    """How uncertain the bridge of each packet-loss gap is, for an estimator's process noise.

    ``after`` (K,) grid positions of the first recorded sample after each gap; ``sigma`` (K,)
    rad, per axis, the rotation the bridge may have missed (:func:`gap_noise`); ``linear`` (M,)
    bool, the filled samples bridged linearly; ``patterns`` (P, 3) int, ``[first, last,
    source]`` of the gaps bridged by a pattern (:func:`with_patterns`): grid positions of the
    gap's first and last filled sample and of the recorded sample the copied stretch follows.
    """

    after: np.ndarray
    sigma: np.ndarray
    linear: np.ndarray
    patterns: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3), np.int64))


def gap_variance(gaps: GapNoise | None, n: int) -> np.ndarray:
    """Per sample of ``n`` (rad², per axis): each gap's bridge variance ``sigma²`` at its
    first recorded sample after (``after``), zero elsewhere and without ``gaps``."""
    out = np.zeros(n)
    if gaps is not None:
        inside = (gaps.after > 0) & (gaps.after < n)
        out[gaps.after[inside].astype(int)] = gaps.sigma[inside] ** 2
    return out


def _bridge(w: np.ndarray, t: np.ndarray, a: np.ndarray, b: np.ndarray, inner: np.ndarray,
            cubic: bool) -> np.ndarray:  # fmt: skip
    """The bridge of :meth:`GapGrid.vectors` (cubic Hermite with one-sided slopes, or linear)
    between samples ``a`` and ``b`` (arrays of test gaps), at the samples ``inner`` (n, m)."""
    h = (t[b] - t[a])[:, None]
    s = (t[inner] - t[a][:, None]) / h
    wa, wb = w[a][:, None], w[b][:, None]
    if not cubic:
        return wa + s[..., None] * (wb - wa)
    left = (w[a] - w[a - 1]) / (t[a] - t[a - 1])[:, None]
    right = (w[b + 1] - w[b]) / (t[b + 1] - t[b])[:, None]
    return _hermite(s[..., None], h[..., None], wa, wb, left[:, None], right[:, None])


def _disagreement(w: np.ndarray, t: np.ndarray, first: int, last: int, source: int, rate: float,
                  cubic: bool) -> float:  # fmt: skip
    """The squared rotation (rad², per axis) between the pattern's bridge of the gap of filled
    samples ``first`` … ``last`` (copied after ``source``) and the line's or cubic's
    (``cubic``): a floor under the pattern's variance, since either bridge may be the true one.
    Test gaps judge the pattern where the movement around the gap repeats; where it does not,
    the stretch whose surroundings match best can hold another movement: on a simulated seated
    trunk (quick leans, 0.4-s losses) a pattern whose test gaps said 2.8° added 26° of turn
    where the cubic missed 6°, while the two bridges' 21° apart said as much."""
    m = last - first + 1
    alt = _bridge(w, t, np.array([first - 1]), np.array([last + 1]),
                  np.arange(first, last + 1)[None, :], cubic)[0]  # fmt: skip
    apart = (_pattern(w, first - 1, m, source) - alt).sum(0) / rate
    return float(np.sum(apart**2) / 3.0)


def _context_samples(rate: float) -> int:
    """Samples of :data:`PATTERN_CONTEXT_S` at ``rate`` (Hz), at least 2."""
    return max(2, int(round(PATTERN_CONTEXT_S * rate)))


def _pattern_sources(
    w: np.ndarray, a: np.ndarray, m: int, recorded_csum: np.ndarray, rate: float
) -> np.ndarray:
    """For gaps of ``m`` samples after samples ``a`` (array), the sample (array, −1 where none)
    after which the stretch of ``w`` elsewhere best matches each gap's surroundings: the least
    squared difference over :data:`PATTERN_CONTEXT_S` of rate either side, among the stretches
    within :data:`PATTERN_SEARCH_S` of the gaps that are recorded with their surroundings
    (``recorded_csum``: the cumulative count of recorded samples, with a leading 0) and do not
    touch the gap's own; above ``PATTERN_CONTEXT_SAMPLES`` samples per side, every k-th sample
    counted from the gap is matched (the memory of the search stays that of 100 Hz). All gaps
    share one search (one matrix product: the squared difference is the stretches' energy less
    twice their correlation with the surroundings, plus the surroundings' own energy)."""
    n, d = w.shape
    a = np.asarray(a, np.int64)
    k = _context_samples(rate)
    step = max(1, k // PATTERN_CONTEXT_SAMPLES)  # at high rates every step-th sample is matched
    reach = int(round(PATTERN_SEARCH_S * rate))
    out = np.full(len(a), -1, np.int64)
    ok = (a - k + 1 >= 0) & (a + m + k < n)
    lo, hi = max(k - 1, int(a.min()) - reach), min(n - m - k - 1, int(a.max()) + reach)
    if not ok.any() or hi < lo:
        return out
    c = np.arange(lo, hi + 1)
    whole = recorded_csum[c + m + k + 1] - recorded_csum[c - k + 1] == m + 2 * k
    view = np.lib.stride_tricks.sliding_window_view(w, k, axis=0)  # (n-k+1, d, k), no copy
    toward, away = view[:, :, k - 1 :: -step], view[:, :, ::step]  # counted from the gap

    def sides(before: slice | np.ndarray, after: slice | np.ndarray) -> np.ndarray:
        """The matched samples of the windows starting at ``before`` (ending where a gap
        begins) and at ``after`` (starting where it ends), one row per stretch."""
        b, f = toward[before], away[after]  # copies the matched samples only
        return np.concatenate([b.reshape(len(b), -1), f.reshape(len(f), -1)], axis=1)

    rows = a[ok]
    stretches = sides(slice(lo - k + 1, hi - k + 2), slice(lo + m + 1, hi + m + 2))
    context = sides(rows - k + 1, rows + m + 1)
    cost = np.sum(stretches**2, axis=1)[:, None] - 2.0 * (stretches @ context.T)
    first, last = rows - k + 1, rows + m + k  # each gap's own stretch with its surroundings
    own = (c[:, None] + m + k >= first) & (c[:, None] - k + 1 <= last)
    cost[~whole[:, None] | own] = np.inf
    best = np.argmin(cost, axis=0)
    found = np.isfinite(cost[best, np.arange(len(rows))])
    out[np.flatnonzero(ok)[found]] = lo + best[found]
    return out


def _pattern(w: np.ndarray, a: int, m: int, c: int) -> np.ndarray:
    """The ``m`` samples after sample ``a`` bridged by those after sample ``c``, shifted by a
    line so that they meet ``w[a]`` and ``w[a + m + 1]`` (:func:`with_patterns`)."""
    d0, d1 = w[a] - w[c], w[a + m + 1] - w[c + m + 1]
    s = (np.arange(1, m + 1) / (m + 1))[:, None]
    return w[c + 1 : c + m + 1] + d0 + s * (d1 - d0)


def with_patterns(arr: np.ndarray | None, noise: GapNoise | None) -> np.ndarray | None:
    """(M, k) samples on a filled grid with every gap of ``noise.patterns`` bridged by its
    pattern: the recorded stretch elsewhere in the recording whose surroundings match the gap's
    best, shifted to meet the samples either side (module notes). Other gaps as they are."""
    if arr is None or noise is None or not len(noise.patterns):
        return arr
    out = np.array(arr, dtype=float)
    for first, last, source in noise.patterns.tolist():
        out[first : last + 1] = _pattern(out, first - 1, last - first + 1, source)
    return out


def _gap_tests(
    time: np.ndarray, gyr: np.ndarray, recorded: np.ndarray, rate: float, patterns: bool
):
    """Per gap of a filled grid (:func:`gap_noise`'s arguments): ``(first, last, span s,
    {bridge: σ² rad² per axis}, pattern source)`` with the test gaps' variance for each bridge
    that has test gaps (``False`` the line, ``True`` the cubic only up to ``CUBIC_MAX_S``,
    ``"pattern"`` the pattern on up to :data:`PATTERN_TESTS` of those whose surroundings were
    recorded as well, only with ``patterns``),
    else the fallback under ``None``; the source of the gap's own pattern (−1: none)."""
    filled = ~np.asarray(recorded, bool)
    n = len(time)
    starts = np.flatnonzero(filled & ~np.r_[False, filled[:-1]])  # first filled of each gap
    ends = np.flatnonzero(filled & ~np.r_[filled[1:], False])  # last filled of each gap
    half = int(round(NOISE_WINDOW_S * rate))
    k = _context_samples(rate)
    csum = np.r_[0, np.cumsum(recorded)]
    for first, last in zip(starts.tolist(), ends.tolist(), strict=True):
        m = last - first + 1
        inside = first >= 1 and last + 1 < n
        span = time[last + 1] - time[first - 1] if inside else (m + 1) / rate
        # test gaps between samples a and a + m + 1, with a - 1 … a + m + 2 recorded (the
        # cubic's slopes need the outer two)
        a = np.arange(max(1, first - 1 - half), min(n - m - 3, last + 1 + half) + 1)
        a = a[csum[a + m + 3] - csum[a - 1] == m + 4]
        var = {}
        source = -1
        if len(a):
            inner = a[:, None] + 1 + np.arange(m)[None, :]
            for cubic in (False, True) if span <= CUBIC_MAX_S else (False,):
                bridge = _bridge(gyr, time, a, a + m + 1, inner, cubic)
                missed = (gyr[inner] - bridge).sum(1) / rate
                var[cubic] = float(np.mean(np.sum(missed**2, axis=1)) / 3.0)
            # the pattern's test gaps: those whose surroundings were recorded too, so that the
            # filled samples (however bridged) take no part in judging it
            clear = a[(a - k + 1 >= 0) & (a + m + k + 1 <= n)]
            clear = clear[csum[clear + m + k + 1] - csum[clear - k + 1] == m + 2 * k]
            if patterns and inside and len(clear):  # their patterns and the gap's, one search
                pick = np.linspace(0, len(clear) - 1, PATTERN_TESTS).round().astype(int)
                tests = clear[np.unique(pick)]
                src = _pattern_sources(gyr, np.r_[tests, first - 1], m, csum, rate)
                if (src[:-1] >= 0).all():
                    missed = np.array([
                        (gyr[t + 1 : t + m + 1] - _pattern(gyr, t, m, c)).sum(0) / rate
                        for t, c in zip(tests.tolist(), src[:-1].tolist(), strict=True)
                    ])  # fmt: skip
                    var["pattern"] = float(np.mean(np.sum(missed**2, axis=1)) / 3.0)
                    source = int(src[-1])
        else:
            near = recorded & (np.abs(np.arange(n) - first) <= half)
            rms = float(np.sqrt(np.mean(np.sum(gyr[near] ** 2, axis=1)))) if near.any() else 0.0
            var[None] = (span * rms) ** 2 / 3.0
        yield first, last, span, var, source


def gap_noise(
    time: np.ndarray,
    gyr: np.ndarray,
    recorded: np.ndarray,
    rate: float,
    linear: np.ndarray | None = None,
    choose: bool = False,
) -> GapNoise | None:
    """Per gap of a filled sample grid, the rotation its bridge may have missed (module notes).

    ``time`` (M,) s and ``gyr`` (M, 3) rad/s are the grid with the gaps bridged, ``recorded``
    (M,) bool the samples that were recorded (the others were filled in), ``linear`` (M,) bool
    the filled samples bridged linearly (default: those of gaps over ``CUBIC_MAX_S``, as
    :meth:`GapGrid.vectors` does). For each gap, test gaps of the same number of samples are
    cut out of fully recorded stretches within ``NOISE_WINDOW_S`` of it, bridged the same way,
    and the rate they miss, summed over the samples at ``1/rate`` (the filter's step), gives
    ``sigma² = mean |missed|² / 3`` (rad², per axis). Where no such stretch exists, the rotation
    the recorded rate around it would make over the gap (``T · RMS |ω| / √3``). ``None`` when
    nothing was filled.

    ``choose``: every gap up to ``CUBIC_MAX_S`` that its test gaps say the straight line bridges
    better than the cubic is bridged linearly too (``GapNoise.linear``; the test gaps use only
    recorded samples, so ``gyr`` may be bridged either way). The cubic's slopes are one-sided
    differences, which on a real walk's gyroscope (tissue ringing, 300-800 °/s transients) are
    noise: on four 0.14-s gaps of the 16-IMU walk's thigh the cubic missed 12-85° of rotation
    per axis, the line 4-30°; on a smooth swing the cubic wins (module notes). With ``choose`` a
    gap whose test gaps miss less with its pattern (:func:`with_patterns`) is listed in
    ``GapNoise.patterns`` and its sigma is the pattern's.
    """
    if np.all(recorded):
        return None
    n = len(time)
    flat = np.zeros(n, bool) if linear is None else np.array(linear, bool)
    after, sigma, patterns = [], [], []
    for first, last, span, var, source in _gap_tests(time, gyr, recorded, rate, choose):
        straight = span > CUBIC_MAX_S if linear is None else bool(linear[first])
        if choose and True in var and var[False] <= var[True]:
            straight = True
        flat[first : last + 1] = straight
        after.append(last + 1)
        chosen = var.get(not straight, var.get(False, var.get(None)))
        if source >= 0 and var["pattern"] < chosen:
            patterns.append((first, last, source))
            chosen = max(var["pattern"], _disagreement(gyr, time, first, last, source, rate,
                                                       not straight))  # fmt: skip
        sigma.append(np.sqrt(chosen))
    keep = np.array(after) < n
    return GapNoise(
        np.array(after)[keep], np.array(sigma)[keep], flat,
        np.array(patterns, np.int64).reshape(-1, 3),
    )  # fmt: skip
