"""Time-aware fusion across packet-loss gaps (``estimate(..., time=)``, ``fusion.timegrid``).

Signal: 40 s at 100 Hz of a sensor swinging about a fixed tilted axis, angle
``θ(t) = 1.2 sin(2π 0.8 t) + 0.1 t`` rad (peak rate about 6 rad/s, like a shank in gait); the
gyroscope reads ``θ'(t)`` along the axis and the accelerometer gravity in the sensor frame, with
seeded white noise. Packets are dropped in bursts of 0.05–0.3 s, 5 % of the samples, or in one
gap of 0.3 s or 0.5 s. Errors are 6-D: RMS after the best constant heading offset.
"""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion import estimate
from motionlab.fusion.markers import MarkerReferences
from motionlab.fusion.registry import get, make_params
from motionlab.fusion.timegrid import gap_grid, gap_noise
from motionlab.validation.orientation_error import orientation_errors

RATE = 100.0
G = 9.81


def swing(seconds: float = 40.0, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE)) / RATE
    axis = np.array([0.3, 1.0, 0.4]) / np.linalg.norm([0.3, 1.0, 0.4])
    w = 2 * np.pi * 0.8
    theta = 1.2 * np.sin(w * t) + 0.1 * t
    rate = 1.2 * w * np.cos(w * t) + 0.1
    q = rot.mul(rot.from_axis_angle([1.0, 0.0, 0.2], 0.4), rot.from_rotvec(theta[:, None] * axis))
    acc = rot.rotate(rot.conj(q), np.array([0.0, 0.0, G]))
    return {
        "time": t,
        "gyr": rate[:, None] * axis + 0.003 * rng.standard_normal((len(t), 3)),
        "acc": acc + 0.05 * rng.standard_normal((len(t), 3)),
        "quat": rot.make_continuous(q),
    }


def drop_bursts(n: int, fraction: float = 0.05, seed: int = 1) -> np.ndarray:
    """Bool mask of kept samples: bursts of 5–30 samples until ``fraction`` is lost."""
    rng = np.random.default_rng(seed)
    lost = np.zeros(n, bool)
    while lost.mean() < fraction:
        start, length = rng.integers(100, n - 100), rng.integers(5, 31)
        lost[start : start + length] = True
    return ~lost


def six_d_error(q: np.ndarray, truth: np.ndarray) -> float:
    """Total RMS error (deg) after the best constant heading offset, from 5 s on."""
    late = np.arange(len(q)) >= 5 * int(RATE)
    e = rot.mul(truth[late], rot.conj(q[late]))
    yaw = 2.0 * np.arctan2(e[:, 3], e[:, 0])
    off = np.arctan2(np.mean(np.sin(yaw)), np.mean(np.cos(yaw)))
    aligned = rot.mul(rot.from_axis_angle([0.0, 0.0, 1.0], off), q)
    return orientation_errors(aligned, truth, late)["total_rmse_deg"]


@pytest.fixture(scope="module")
def sig():
    return swing()


@pytest.mark.parametrize("name", ["smoother", "madgwick", "mekf"])
def test_dropped_packets_track_as_well_as_without(name, sig):
    keep = drop_bursts(len(sig["time"]))
    assert np.diff(sig["time"][keep]).max() > 0.25
    full = estimate(name, sig["gyr"], sig["acc"], None, RATE, time=sig["time"])
    assert "resampled" not in full.extra
    gappy = estimate(name, sig["gyr"][keep], sig["acc"][keep], None, RATE, time=sig["time"][keep])
    blind = estimate(name, sig["gyr"][keep], sig["acc"][keep], None, RATE)
    e_full = six_d_error(full.quat, sig["quat"])
    e_gappy = six_d_error(gappy.quat, sig["quat"][keep])
    e_blind = six_d_error(blind.quat, sig["quat"][keep])
    assert e_gappy < e_full + 0.3, (e_full, e_gappy)
    assert e_blind > e_gappy + 5.0, (e_blind, e_gappy)  # the gaps do matter
    info = gappy.extra["resampled"]
    assert info["samples_filled"] == (~keep).sum()
    assert gappy.quat.shape == (keep.sum(), 4)
    if gappy.gyro_bias is not None:
        assert gappy.gyro_bias.shape == (keep.sum(), 3)


@pytest.mark.parametrize("start", [10.0, 13.3, 17.7])
def test_one_long_gap(sig, start):
    """One gap of 0.3 s or 0.5 s stays near the gapless error, far below the gap taken as one
    sample."""
    full = six_d_error(estimate("smoother", sig["gyr"], sig["acc"], None, RATE).quat, sig["quat"])
    for length, margin in ((0.3, 0.1), (0.5, 1.5)):
        keep = np.ones(len(sig["time"]), bool)
        keep[int(start * RATE) : int((start + length) * RATE)] = False
        args = ("smoother", sig["gyr"][keep], sig["acc"][keep], None, RATE)
        err = six_d_error(estimate(*args, time=sig["time"][keep]).quat, sig["quat"][keep])
        blind = six_d_error(estimate(*args).quat, sig["quat"][keep])
        assert err < full + margin, (length, full, err)
        assert blind > err, (length, blind, err)


def test_grid_by_hand():
    t = np.array([0.0, 0.01, 0.02, 0.06, 0.07, 0.095])
    grid = gap_grid(t, 100.0)
    np.testing.assert_allclose(grid.time, [0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.0825,
                                           0.095])  # fmt: skip
    np.testing.assert_array_equal(grid.index, [0, 1, 2, 6, 7, 9])
    np.testing.assert_allclose(grid.spans, [[0.02, 0.06], [0.07, 0.095]])
    values = np.column_stack([t, 2 * t, np.ones_like(t)])
    np.testing.assert_allclose(grid.vectors(values)[:, 1], 2 * grid.time)
    assert gap_grid(t[:3] + 1e-4 * np.array([0, 1, -1]), 100.0) is None  # jitter is no gap


def test_without_gaps_time_changes_nothing(sig):
    a = estimate("smoother", sig["gyr"], sig["acc"], None, RATE)
    b = estimate("smoother", sig["gyr"], sig["acc"], None, RATE, time=sig["time"])
    np.testing.assert_array_equal(a.quat, b.quat)


def test_marker_references_are_absent_at_filled_instants(sig):
    keep = drop_bursts(len(sig["time"]), seed=2)
    body = np.eye(3)[:2]
    earth = rot.rotate(sig["quat"][keep][:, None], body)
    refs = MarkerReferences(body, earth, np.full(2, 0.01))
    grid = gap_grid(sig["time"][keep], RATE)
    on_grid = grid.references(refs)
    filled = np.setdiff1d(np.arange(len(grid.time)), grid.index)
    assert np.isnan(on_grid.earth[filled]).all()
    np.testing.assert_array_equal(on_grid.earth[grid.index], earth)
    res = estimate("liu_gn", sig["gyr"][keep], sig["acc"][keep], None, RATE, references=refs,
                   time=sig["time"][keep])  # fmt: skip
    assert res.quat.shape == (keep.sum(), 4)
    err = orientation_errors(res.quat, sig["quat"][keep], np.ones(keep.sum(), bool))
    assert err["total_rmse_deg"] < 1.0
    for value in res.extra.values():
        if isinstance(value, np.ndarray) and value.ndim:
            assert len(value) == keep.sum()


@pytest.mark.parametrize(
    "time, message",
    [
        (np.arange(10) / RATE, "shape"),
        (np.r_[np.arange(19), 18.0] / RATE, "does not increase"),
        (np.r_[np.arange(19), np.nan] / RATE, "not finite"),
    ],
)
def test_bad_time_is_an_input_error(sig, time, message):
    with pytest.raises(InputError, match=message):
        estimate("madgwick", sig["gyr"][:20], sig["acc"][:20], None, RATE, time=time)


def alternating(c: float = 0.7, n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """Time (s) and a rate (rad/s) alternating ±``c`` about x from one sample to the next."""
    gyr = np.zeros((n, 3))
    gyr[:, 0] = c * (-1.0) ** np.arange(n)
    return np.arange(n) / RATE, gyr


def test_gap_noise_by_hand():
    """A rate alternating ±c each sample, one sample filled: every test gap's bridge misses
    the inner sample by 2c (linear: both ends equal the inner's opposite) or 3c (cubic: ends
    +c, one-sided slopes ∓2c/dt, midpoint 2c), so sigma (per axis) is that over rate, /√3."""
    c, n = 0.7, 300
    t, gyr = alternating(c, n)
    recorded = np.ones(n, bool)
    recorded[150] = False
    cubic = gap_noise(t, gyr, recorded, RATE)
    np.testing.assert_array_equal(cubic.after, [151])
    np.testing.assert_allclose(cubic.sigma, [3 * c / RATE / np.sqrt(3)], rtol=1e-12)
    linear = gap_noise(t, gyr, recorded, RATE, linear=~recorded)
    np.testing.assert_allclose(linear.sigma, [2 * c / RATE / np.sqrt(3)], rtol=1e-12)
    smooth = gyr.copy()
    smooth[:, 0] = 0.3 + 2.0 * t  # a straight line: either bridge is exact
    assert gap_noise(t, smooth, recorded, RATE).sigma[0] < 1e-12
    assert gap_noise(t, gyr, np.ones(n, bool), RATE) is None


def linear_gaps(time: np.ndarray, gyr: np.ndarray, recorded: np.ndarray) -> np.ndarray:
    """The filled samples ``gap_noise(..., choose=True)`` bridges linearly."""
    return gap_noise(time, gyr, recorded, RATE, choose=True).linear


def test_each_gap_takes_the_bridge_its_neighbourhood_misses_less_with(sig):
    """On the smooth swing every short gap keeps the cubic (its test gaps miss less with it);
    the alternating rate of test_gap_noise_by_hand (the line misses 2c, the cubic 3c) and a
    gap longer than CUBIC_MAX_S are bridged linearly; recorded samples are never flagged."""
    keep = drop_bursts(len(sig["time"]))
    t = sig["time"][keep]
    grid = gap_grid(t, RATE)
    recorded = np.zeros(len(grid.time), bool)
    recorded[grid.index] = True
    assert not linear_gaps(grid.time, grid.vectors(sig["gyr"][keep]), recorded).any()
    tt, gyr = alternating()
    one = np.ones(len(tt), bool)
    one[150] = False
    np.testing.assert_array_equal(linear_gaps(tt, gyr, one), ~one)
    long = np.ones(len(tt), bool)
    long[100:190] = False  # 0.91 s between the recorded samples either side
    ramp = np.repeat(0.3 + 2.0 * tt[:, None], 3, axis=1)
    np.testing.assert_array_equal(linear_gaps(tt, ramp, long), ~long)


def test_a_gap_in_a_ringing_signal_is_bridged_by_the_line(sig):
    """The swing with 15-Hz tissue ringing of 2 rad/s on top (a real walk's gyroscope between
    heel strikes): the one-sided slopes at a gap's edges are the ringing's, and a cubic through
    them overshoots. Each 0.14-s gap is bridged linearly, and the rotation it misses over the
    gap is smaller than the cubic's (on the real 16-IMU walk: median 27° against 72°)."""
    t = sig["time"]
    gyr = sig["gyr"] + 2.0 * np.sin(2 * np.pi * 15.0 * t)[:, None] * np.array([0.6, 0.0, 0.8])
    missed = {"cubic": [], "chosen": []}
    for start in (10.03, 17.41, 25.27, 31.66):
        keep = ~((t > start) & (t < start + 0.14))
        grid = gap_grid(t[keep], RATE)
        recorded = np.zeros(len(grid.time), bool)
        recorded[grid.index] = True
        flags = linear_gaps(grid.time, grid.vectors(gyr[keep]), recorded)
        assert flags[~recorded].all()
        true = gyr[~keep].sum(axis=0) / RATE
        for kind, linear in (("cubic", np.zeros(len(grid.time), bool)), ("chosen", flags)):
            bridged = grid.vectors(gyr[keep], linear)[~recorded].sum(axis=0) / RATE
            missed[kind].append(np.linalg.norm(bridged - true))
    assert np.mean(missed["chosen"]) < 0.5 * np.mean(missed["cubic"])


def test_gap_across_ringing_is_left_to_the_accelerometer(sig):
    """A 0.15 s gap in a 1.5 s burst of 10 Hz ringing about the swing's axis (a strap ringing
    after an impact) that the bridge cannot follow: taken as measured, its miss stays as an
    inclination error the accelerometer takes tens of seconds to remove; the test gaps around
    it ring too, so its bridge noise is large, the smoother lets the accelerometer on either
    side decide, and the error over the 10 s after the gap falls by more than half."""
    t = sig["time"]
    fine = np.arange(len(t) * 10) / (10 * RATE)
    burst = (fine > 19.3) & (fine < 20.8)
    ring_fine = np.where(burst, 6.0 * np.sin(2 * np.pi * 10 * (fine - 19.3)), 0.0)  # rad/s
    extra = (np.cumsum(ring_fine) / (10 * RATE))[::10]  # its angle (rad)
    axis = np.array([0.3, 1.0, 0.4]) / np.linalg.norm([0.3, 1.0, 0.4])  # the swing's
    theta = 1.2 * np.sin(2 * np.pi * 0.8 * t) + 0.1 * t + extra
    q = rot.mul(rot.from_axis_angle([1.0, 0.0, 0.2], 0.4), rot.from_rotvec(theta[:, None] * axis))
    gyr = sig["gyr"] + ring_fine[::10, None] * axis
    acc = sig["acc"] - sig_gravity(sig["quat"]) + sig_gravity(q)
    keep = np.ones(len(t), bool)
    keep[int(20.02 * RATE) : int(20.17 * RATE)] = False
    grid = gap_grid(t[keep], RATE)
    p = make_params(get("smoother"), {})
    blind = get("smoother").run(grid.vectors(gyr[keep]), grid.vectors(acc[keep]), None, RATE, p)
    told = estimate("smoother", gyr[keep], acc[keep], None, RATE, time=t[keep])
    after = (t[keep] > 20.3) & (t[keep] < 30.0)

    def incl(quat):
        up, ref = sig_gravity(quat) / G, sig_gravity(q[keep]) / G
        return np.degrees(np.sqrt(np.mean(np.sum((up - ref)[after] ** 2, axis=1))))

    e_blind, e_told = incl(blind.quat[grid.index]), incl(told.quat)
    assert e_blind > 4.0, e_blind  # the gap matters (6.3°)
    assert e_told < min(1.5, 0.5 * e_blind), (e_blind, e_told)  # 1.05°


def sig_gravity(q: np.ndarray) -> np.ndarray:
    """Gravity's specific force (m/s²) in the sensor frame of orientations ``q``."""
    return rot.rotate(rot.conj(q), np.array([0.0, 0.0, G]))


def test_filled_spans_follow_the_clock_sync():
    """Ingest lists its filled gaps on the recorded clock; the fusion reads them on the
    stream's time, which the clock sync moved (offset 0.05 s, drift 100 ppm about 10 s)."""
    from dataclasses import asdict

    from motionlab.fusion.stage import filled_spans
    from motionlab.results import ClockFit
    from motionlab.session import SensorStream

    fit = ClockFit("a", "b", 0.05, 1e-4, 10.0, 0.0, 0.0, 0.0, 1.0, "applied")
    spans = [[2.0, 2.05], [30.0, 30.04]]
    s = SensorStream("b", np.arange(5.0), qc={"filled_spans_s": spans})
    np.testing.assert_array_equal(filled_spans(s), spans)
    s.attrs["clock_sync"] = asdict(fit)
    expected = (np.array(spans) - 0.05 + 1e-4 * 10.0) / (1 + 1e-4)
    np.testing.assert_allclose(filled_spans(s), expected, rtol=0, atol=1e-12)
    assert filled_spans(SensorStream("c", np.arange(5.0))) is None


@pytest.mark.parametrize("bad", [[1.0, 2.0, 3.0], [[1.0, float("nan")]], [[3.0, 2.0]], ["a"]])
def test_a_damaged_list_of_filled_gaps_is_one_line(bad):
    """A session file whose ``filled_spans_s`` is not finite ``[start, end]`` pairs."""
    from motionlab.errors import InputError
    from motionlab.fusion.stage import filled_spans
    from motionlab.session import SensorStream

    s = SensorStream("thigh", np.arange(5.0), qc={"filled_spans_s": bad})
    with pytest.raises(InputError) as err:
        filled_spans(s, "s.h5")
    line = err.value.line()
    assert "s.h5" in line and "sensor thigh" in line and "ingest the recording again" in line


def test_bridged_flags_are_the_span_by_span_comparison():
    """registry._bridged finds the samples inside each filled span by bisection (linear in the
    recording): the same flags as comparing every sample with every span, on a clock with
    packet-loss gaps (spans at, between and beyond the samples; one past the end)."""
    from motionlab.fusion.registry import _bridged
    from motionlab.fusion.timegrid import CUBIC_MAX_S

    rng = np.random.default_rng(4)
    t = np.arange(3000) / RATE
    t = t[rng.uniform(size=len(t)) > 0.05]  # dropped packets: the grid fills them
    starts = np.concatenate([rng.uniform(-1.0, 31.0, 40), t[[5, 500]]])
    spans = np.column_stack([starts, starts + rng.uniform(0.0, 0.5, len(starts))])
    grid = gap_grid(t, RATE)
    recorded = np.ones(len(t), bool)
    for start, end in spans:
        recorded[(t > start) & (t < end)] = False
    filled = np.setdiff1d(np.arange(len(grid.time)), grid.index)
    on_grid, linear = _bridged(t, spans, grid)
    assert not recorded.all() and len(filled)  # both paths are used
    np.testing.assert_array_equal(on_grid[grid.index], recorded)
    assert not on_grid[filled].any()
    np.testing.assert_array_equal(linear[grid.index], ~recorded)
    gap = grid.stamps[grid.before + 1] - grid.stamps[grid.before]
    np.testing.assert_array_equal(linear[filled], gap > CUBIC_MAX_S)
    np.testing.assert_array_equal(_bridged(t, spans, None)[0], recorded)


def stepping(
    seconds: float = 40.0, seed: int = 2, rate: float = RATE
) -> tuple[np.ndarray, np.ndarray]:
    """A thigh-like rate (rad/s, (N, 3)) at RATE: strides of 1.1 s ± 3 % (seeded), each the
    same shape of three harmonics with a heel-strike transient, plus 15-Hz ringing after each
    strike and white noise: a repeating movement that no line or cubic follows through 0.1 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate)) / rate
    periods = 1.1 * (1.0 + 0.03 * rng.standard_normal(int(seconds / 0.9)))
    starts = np.r_[0.0, np.cumsum(periods)]
    k = np.searchsorted(starts, t, side="right") - 1
    phase = (t - starts[k]) / periods[k]  # 0..1 within each stride
    shape = 3.0 * np.sin(2 * np.pi * phase) + 1.2 * np.sin(4 * np.pi * phase + 0.7)
    shape += 0.6 * np.sin(6 * np.pi * phase + 1.9)
    since = (phase - 0.62) * periods[k]  # the heel strike at 62 % of each stride
    ring = np.where(since > 0, 2.5 * np.exp(-since / 0.06) * np.sin(2 * np.pi * 15 * since), 0.0)
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    gyr = (shape + ring)[:, None] * axis + np.array([0.1, 0.0, -0.2]) * np.cos(2 * np.pi * phase)[
        :, None
    ]
    return t, gyr + 0.02 * rng.standard_normal(gyr.shape)


def pattern_noise(t: np.ndarray, gyr: np.ndarray, keep: np.ndarray, rate: float = RATE):
    """The gap grid of the samples ``keep``, which of its samples were recorded, and their
    bridges' noise with patterns chosen (:func:`gap_noise`, ``choose=True``)."""
    grid = gap_grid(t[keep], rate)
    recorded = np.zeros(len(grid.time), bool)
    recorded[grid.index] = True
    noise = gap_noise(grid.time, grid.vectors(gyr[keep]), recorded, rate, choose=True)
    return grid, recorded, noise


def missed_deg(
    t: np.ndarray, gyr: np.ndarray, keep: np.ndarray, patterns: bool, rate: float = RATE
) -> float:
    """The rotation (deg) the bridge of the single gap ``~keep`` misses, with or without the
    pattern bridge (the line or cubic its test gaps choose otherwise)."""
    from motionlab.fusion.timegrid import with_patterns

    grid, recorded, noise = pattern_noise(t, gyr, keep, rate)
    bridged = grid.vectors(gyr[keep], noise.linear)
    if patterns:
        bridged = with_patterns(bridged, noise)
    return float(np.degrees(np.linalg.norm((bridged[~recorded] - gyr[~keep]).sum(0) / rate)))


@pytest.mark.parametrize("length", [0.05, 0.09, 0.14])
def test_a_gap_in_a_repeating_movement_is_bridged_by_its_pattern(length):
    """Gaps in a walk-like rate are bridged by the stretch of another stride whose
    surroundings match best: at eight gap positions the rotation missed falls to under a
    third of the line's or cubic's (on the real 16-IMU walk's thighs, 7-sample test gaps: RMS
    14-17° → 6-7°), and the gap's bridge noise says so."""
    t, gyr = stepping()
    plain, chosen = [], []
    for start in np.linspace(8.0, 32.0, 8):
        keep = ~((t > start) & (t < start + length))
        plain.append(missed_deg(t, gyr, keep, False))
        chosen.append(missed_deg(t, gyr, keep, True))
        assert len(pattern_noise(t, gyr, keep)[2].patterns) == 1, start
    rms = lambda v: np.sqrt(np.mean(np.square(v)))  # noqa: E731
    assert rms(chosen) < rms(plain) / 3, (rms(plain), rms(chosen))


def test_a_patterns_uncertainty_is_at_least_its_distance_from_the_line_or_cubic():
    """Either bridge may be the true one, so a gap bridged by a pattern is at least as
    uncertain as the pattern lies from the line or cubic it displaced (a stretch copied from
    another movement adds a turn its test gaps did not see: tests/test_trunk_seated.py): per
    axis, sigma ≥ |∫ (pattern − other) dt| / √3 for every pattern-bridged gap of the walk-like
    rate, and the floor decides where the two are far apart."""
    from motionlab.fusion.timegrid import with_patterns

    t, gyr = stepping()
    keep = np.ones(len(t), bool)
    for start in np.linspace(8.0, 32.0, 8):
        keep[int(start * RATE) : int(start * RATE) + 12] = False
    grid, _, noise = pattern_noise(t, gyr, keep)
    assert len(noise.patterns) == 8
    other = grid.vectors(gyr[keep], noise.linear)
    pattern = with_patterns(other, noise)
    floors = []
    for first, last, _ in noise.patterns:
        apart = (pattern[first : last + 1] - other[first : last + 1]).sum(0) / RATE
        k = int(np.flatnonzero(noise.after == last + 1)[0])
        floors.append(np.linalg.norm(apart) / np.sqrt(3.0))
        assert noise.sigma[k] >= floors[-1] - 1e-12
    assert max(floors) > 0.0


def test_a_pattern_is_copied_only_from_recorded_samples_and_meets_the_gap_ends():
    """Three gaps close together in the repeating rate: each pattern's source stretch, with
    its matched surroundings, lies on recorded samples away from its own gap, and the bridge
    meets the recorded samples either side (the copied stretch shifted by a line)."""
    from motionlab.fusion.timegrid import PATTERN_CONTEXT_S, with_patterns

    t, gyr = stepping()
    keep = np.ones(len(t), bool)
    for start in (20.0, 20.4, 21.5):
        keep[int(start * RATE) : int(start * RATE) + 9] = False
    grid, recorded, noise = pattern_noise(t, gyr, keep)
    assert len(noise.patterns) == 3
    k = int(round(PATTERN_CONTEXT_S * RATE))
    bridged = with_patterns(grid.vectors(gyr[keep], noise.linear), noise)
    for first, last, source in noise.patterns:
        m = last - first + 1
        assert recorded[source - k + 1 : source + m + k + 1].all()
        assert source + m + k < first - k or source - k > last + k
        offsets = bridged[first : last + 1] - bridged[source + 1 : source + m + 1]
        # the shift is a line from the difference before to the difference after the gap
        np.testing.assert_allclose(np.diff(offsets, 2, axis=0), 0.0, atol=1e-12)


def test_a_movement_that_does_not_repeat_keeps_the_line_or_cubic():
    """A rate that wanders without repeating (a random walk): the test gaps find that copying
    the best-matching stretch from elsewhere misses more than the neighbourhood's own line or
    cubic, so no gap is bridged by a pattern and every bridge is as before."""
    rng = np.random.default_rng(7)
    t = np.arange(4000) / RATE
    gyr = np.cumsum(rng.standard_normal((len(t), 3)), axis=0) * 0.05
    keep = drop_bursts(len(t), fraction=0.02, seed=3)
    grid = gap_grid(t[keep], RATE)
    recorded = np.zeros(len(grid.time), bool)
    recorded[grid.index] = True
    on_grid = grid.vectors(gyr[keep])
    noise = gap_noise(grid.time, on_grid, recorded, RATE, choose=True)
    assert len(noise.after) == 5 and not len(noise.patterns)
    plain = gap_noise(grid.time, on_grid, recorded, RATE, linear=noise.linear)
    np.testing.assert_array_equal(noise.sigma, plain.sigma)


def test_at_a_high_rate_the_pattern_matches_every_kth_sample():
    """At 1000 Hz the 0.2 s either side of a gap are 200 samples; every 10th is matched
    (PATTERN_CONTEXT_SAMPLES), and the pattern still misses under a third of the line's or
    cubic's rotation over four 0.1-s gaps in the repeating rate."""
    rate = 1000.0
    t, gyr = stepping(seconds=20.0, rate=rate)
    plain, chosen = [], []
    for start in (6.03, 9.41, 12.77, 15.2):
        keep = ~((t > start) & (t < start + 0.1))
        plain.append(missed_deg(t, gyr, keep, False, rate))
        chosen.append(missed_deg(t, gyr, keep, True, rate))
    assert np.sqrt(np.mean(np.square(chosen))) < np.sqrt(np.mean(np.square(plain))) / 3, (
        plain, chosen)  # fmt: skip
