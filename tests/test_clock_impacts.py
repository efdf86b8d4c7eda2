"""The impact lag of motionlab.clocksync: two sensors' heel-strike transients tie their clocks.

A hand-built pulse train with a known shift and drift, a recording without transients (refused),
a simulated walk on own clocks (every pair within a tolerance of the true clock difference,
left and right legs tied directly; the network sync within 1.5 ms), and ``choose`` (the rule of
the sync tree, used without heel strikes).
"""

import dataclasses

import numpy as np
import pytest

from motionlab.clocksync import choose, impact_clock, synchronise
from motionlab.pipeline import prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.results import ClockFit
from motionlab.session import SensorStream
from motionlab.simulate import simulate
from motionlab.simulate.errors import get_preset

RATE = 100.0  # Hz
DURATION = 70.0  # s


def _ringing(t: np.ndarray, strikes: np.ndarray, freq_hz: float, axis: np.ndarray) -> np.ndarray:
    """Gyroscope (N, 3) rad/s of a sensor rocking after every strike as the simulator's wobble
    does: angle 0.01 rad · (x/τ)³ e^{3−x/τ}/27 · sin(2π f x), x the time since the strike."""
    angle = np.zeros(len(t))
    for s in strikes:
        x = t - s
        m = (x > 0) & (x < 1.6)
        u = x[m] / 0.04
        angle[m] += 0.01 * u**3 * np.exp(3 - u) / 27 * np.sin(2 * np.pi * freq_hz * x[m])
    return np.gradient(angle, t)[:, None] * axis


def _stream(label: str, stamps: np.ndarray, gyr: np.ndarray, rng) -> SensorStream:
    # gait-like slow movement (1 Hz, not in the transients' band) and sensor noise
    slow = 2.0 * np.sin(2 * np.pi * 0.9 * stamps)[:, None] * np.array([0.0, 0.0, 1.0])
    gyr = gyr + slow + rng.normal(0.0, 0.002, gyr.shape)
    acc = np.tile([0.0, 0.0, 9.81], (len(stamps), 1)) + rng.normal(0.0, 0.02, gyr.shape)
    return SensorStream(label, stamps, acc=acc, gyr=gyr)


@pytest.fixture(scope="module")
def pulse_pair():
    """Strikes at irregular steps (0.5-0.6 s) with two 5 s pauses; the sensor's clock reads
    ``t + 23.4 ms + 30 ppm (t − 35 s)`` at true time ``t``; carriers 10 and 15 Hz."""
    rng = np.random.default_rng(3)
    steps = rng.uniform(0.5, 0.6, 200)
    strikes = 2.0 + np.cumsum(steps)
    strikes = strikes[strikes < DURATION - 2.0]
    strikes = strikes[(np.abs(strikes - 25.0) > 2.5) & (np.abs(strikes - 50.0) > 2.5)]
    t = np.arange(0.0, DURATION, 1.0 / RATE)  # true sampling instants of both sensors
    a = _stream("a", t, _ringing(t, strikes, 10.0, np.array([1.0, 0.0, 0.0])), rng)
    c = 0.0234 + 30e-6 * (t - 35.0)
    b = _stream("b", t + c, _ringing(t, strikes, 15.0, np.array([0.0, 0.6, 0.8])), rng)
    return a, b


def test_pulse_train_shift_recovered(pulse_pair):
    a, b = pulse_pair
    fit = impact_clock(a, b)
    assert fit.method == "impacts"
    assert fit.status == "applied"
    t = np.linspace(5.0, DURATION - 5.0, 20)
    truth = 0.0234 + 30e-6 * (t - 35.0)
    assert np.max(np.abs(fit.error_s(t) - truth)) < 0.0005
    assert fit.offset_se_s < 0.0005
    # the other way round: the negative offset
    back = impact_clock(b, a)
    assert abs(back.offset_s + fit.offset_s) < 0.0005


def test_no_transients_refused(pulse_pair):
    """Smooth movement and noise only (no heel strikes): no impact lag."""
    a, b = pulse_pair
    rng = np.random.default_rng(4)
    quiet = [_stream(s.label, s.time, np.zeros_like(s.gyr), rng) for s in (a, b)]
    fit = impact_clock(*quiet)
    assert fit.status.startswith("not reliable")
    assert not np.isfinite(fit.offset_se_s)


def _true_difference(truth, stamps, ref: str, label: str, t: float) -> float:
    """The sensor's stamp minus the reference's stamp of one true instant ``t`` (s)."""
    return float(np.interp(t, truth.sensors[label]["sample_time"], stamps[label])
                 - np.interp(t, truth.sensors[ref]["sample_time"], stamps[ref]))  # fmt: skip


@pytest.fixture(scope="module")
def walk():
    protocol = load_protocol("walk")
    session, truth = simulate(protocol, 60.0, 0, get_preset("typical"))
    stamps = {k: s.time.copy() for k, s in session.sensors.items()}
    prepare_sensors(session)  # as ingest leaves a recording: short gaps filled
    return protocol, session, truth, stamps


def test_simulated_walk_every_pair(walk):
    """Own clocks (offset σ 10 ms, drift 20 ppm): the impact lag of every pair of the five
    sensors, shank_r-shank_l included, within 2 ms of the true clock difference (measured:
    ≤ 1.8 ms on this seed, ≤ 2.1 ms on seeds 0-4; the joint-centre fit was 7-68 ms off on
    pelvis-thigh)."""
    _, session, truth, stamps = walk
    labels = ["pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l"]
    tm = float(truth.time[len(truth.time) // 2])
    for i, ref in enumerate(labels):
        for label in labels[i + 1 :]:
            fit = impact_clock(session.sensors[ref], session.sensors[label])
            true = _true_difference(truth, stamps, ref, label, tm)
            assert fit.status in ("applied", "consistent with one clock"), (ref, label)
            assert abs(fit.error_s(np.array([tm]))[0] - true) < 0.002, (ref, label)


def test_synchronise_ties_left_and_right(walk):
    """After ``synchronise`` one true instant has one session time on both legs (to 1.5 ms),
    and the fits say what timed each sensor."""
    protocol, session, truth, stamps = walk
    session = dataclasses.replace(session, sensors=dict(session.sensors))
    fits = synchronise(session, protocol)
    assert {f.method for f in fits} == {"network"}  # all at once (motionlab.clocknet)
    assert all("heel strikes with" in f.other for f in fits)  # what timed each is recorded
    t = np.linspace(15.0, 45.0, 7)
    times = {}
    for label, s in session.sensors.items():
        st = np.interp(t, truth.sensors[label]["sample_time"], stamps[label])
        cs = s.attrs.get("clock_sync")
        times[label] = ClockFit(**cs).corrected_time(st) if cs else st
    for label in ("thigh_r", "thigh_l", "shank_r", "shank_l"):
        assert np.max(np.abs(times[label] - times["pelvis"])) < 0.0025, label
    assert np.max(np.abs(times["shank_r"] - times["shank_l"])) < 0.0015


def _fit(offset_s: float, se_s: float, status: str, method: str) -> ClockFit:
    return ClockFit("a", "b", offset_s, 0.0, 10.0, se_s, 1e-6, 0.01, 30.0, status, method)


def test_choice_between_methods():
    centre = _fit(0.020, 1e-4, "applied", "joint centre")
    # agreeing within the impact lag's allowance: the joint centre (more precise)
    near = choose(centre, _fit(0.0215, 3e-4, "applied", "impacts"))
    assert near.method == "joint centre" and near.offset_s == 0.020
    assert near.other.startswith("heel strikes: +21.5")
    # 30 ms apart: the impact lag, with the joint centre's answer kept
    far = choose(centre, _fit(-0.010, 3e-4, "applied", "impacts"))
    assert far.method == "impacts" and far.offset_s == -0.010 and "30.0 ms away" in far.other
    # no transients (an arm task): the joint centre as before
    none = choose(centre, _fit(0.0, np.inf, "not reliable: too few heel strikes", "impacts"))
    assert none.method == "joint centre" and none.offset_s == 0.020
    assert none.other == "heel strikes: not reliable: too few heel strikes"
    # a recording too short for the heel strikes (a seated trunk's 12 s): not named at all
    short = choose(centre, _fit(0.0, np.inf, "not enough shared recording (24 s needed)",
                                "impacts"))  # fmt: skip
    assert short.offset_s == 0.020 and short.other == ""
    # the joint centre refused, the impact lag reliable: the impact lag
    refused = dataclasses.replace(centre, status="not reliable: the joint centre fits poorly")
    assert choose(refused, _fit(0.012, 3e-4, "applied", "impacts")).offset_s == 0.012


def test_two_fits_refused_alone_are_taken_together_when_they_agree():
    """A joint-centre fit refused for its residual and a heel-strike lag refused for regular
    steps (a simulated 1-h walk's knee: 122.7 and 120.5 ms) are taken when their clocks agree
    within ``TOGETHER_S`` over the recording; the heel strikes are compared on the reference's
    corrected clock (the thigh moved by -46.2 ms before its shank was fitted)."""
    from motionlab.clocksync.impacts import REGULAR_STEPS
    from motionlab.clocksync.joint_centre import POOR_FIT
    from motionlab.clocksync.stage import TOGETHER_S

    poor = _fit(0.0765, 1e-5, f"{POOR_FIT} (residual 0.06 m/s²)", "joint centre")
    regular = _fit(0.1205, 4e-5, f"{REGULAR_STEPS} (correlation 0.973)", "impacts")
    thigh = _fit(-0.0462, 1e-5, "applied", "joint centre")
    taken = choose(poor, regular, thigh)
    assert (
        taken.status == "applied" and taken.offset_s == 0.0765 and "taken together" in taken.other
    )
    assert choose(poor, regular).status == poor.status  # on the thigh's raw clock: 44 ms apart
    # apart by more than TOGETHER_S, or refused for another reason: not taken
    apart = dataclasses.replace(regular, offset_s=0.1205 + 2 * TOGETHER_S)
    assert choose(poor, apart, thigh).status == poor.status
    few = dataclasses.replace(regular, status="not reliable: too few heel strikes")
    assert choose(poor, few, thigh).status == poor.status
    # agreeing on no difference: one clock
    one = choose(dataclasses.replace(poor, offset_s=0.0),
                 dataclasses.replace(regular, offset_s=0.0004))  # fmt: skip
    assert one.status == "consistent with one clock"


def test_a_long_drifting_pulse_train_is_followed_block_by_block():
    """Over 20 min at 300 ppm (as over an hour at 100 ppm) the lag moves by 360 ms: the whole
    lag is searched on the middle two minutes and each block about the line through the blocks
    timed so far. The correlation at one lag over the whole recording was 0.36, refused as
    "the transients correlate poorly"; a simulated 1-h walk's knee read 0.64."""
    rng = np.random.default_rng(5)
    duration = 1200.0
    strikes = 2.0 + np.cumsum(rng.uniform(0.5, 0.6, 2400))
    strikes = strikes[strikes < duration - 2.0]
    t = np.arange(0.0, duration, 1.0 / RATE)
    a = _stream("a", t, _ringing(t, strikes, 10.0, np.array([1.0, 0.0, 0.0])), rng)
    c = 0.010 + 300e-6 * (t - 600.0)
    b = _stream("b", t + c, _ringing(t, strikes, 15.0, np.array([0.0, 0.6, 0.8])), rng)
    fit = impact_clock(a, b)
    assert fit.status == "applied" and fit.residual < 0.05  # 1 − the middle's correlation
    ends = np.array([10.0, 600.0, duration - 10.0])
    assert np.max(np.abs(fit.error_s(ends) - (0.010 + 300e-6 * (ends - 600.0)))) < 0.001


def test_old_fit_reads_as_joint_centre():
    tree = dataclasses.asdict(_fit(0.01, 1e-4, "applied", "joint centre"))
    del tree["method"], tree["other"]
    assert ClockFit.from_tree(tree).method == "joint centre"
