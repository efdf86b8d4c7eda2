"""The two legs' clocks without a pelvis sensor: linked by the heel strikes when they tie them
well, else every number that compares one leg's events with the other's is withheld.

A simulated walk without a pelvis sensor (its sensors on clocks 22.5 ms apart across the legs)
read 10.9 % step-time asymmetry: no sensor joined the legs, so the left leg was never timed.
"""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from motionlab.clocksync import stage, sync_forest
from motionlab.kinematics import spatiotemporal as sp
from motionlab.protocol import load_protocol
from motionlab.results import NOT_LINKED, ClockFit, ClockSync


def _true_steps(strides: pd.DataFrame, gait: dict) -> pd.DataFrame:
    """The stride table with each step's two contacts (its landing ``start_s`` and the other
    foot's contact ``step_time_s`` before) moved to the nearest true contacts (within 0.1 s:
    the clocks are tens of ms apart, the steps half a second), so that the summary pairs the
    same steps: on a walk whose strides vary, the asymmetry of the product's few paired steps
    and that of every step of the walk differ by as much as the test allows."""

    def true(t: float, side: str) -> float:
        ic = gait[f"ic_{side}"]
        j = int(np.argmin(np.abs(ic - t)))
        assert abs(ic[j] - t) < 0.1
        return float(ic[j])

    steps = strides.dropna(subset=["step_time_s"])
    land = [true(r.start_s, r.side) for r in steps.itertuples()]
    first = [true(r.start_s - r.step_time_s, "l" if r.side == "r" else "r")
             for r in steps.itertuples()]  # fmt: skip
    out = strides.copy()
    out.loc[steps.index, "start_s"] = land
    out.loc[steps.index, "step_time_s"] = np.subtract(land, first)
    return out


@pytest.fixture(scope="module")
def no_pelvis():
    """A 40-s simulated walk (typical errors: each sensor on its own clock) without the pelvis
    sensor; shank_l's clock 22.5 ms from shank_r's."""
    from motionlab.simulate import simulate

    # the strides vary (the default); a dropped-packet span of this seed (shank_l, 33.82-34.00 s)
    # covers a left initial contact, which the event detector took across the gap 0.13 s late
    # (the asymmetry then read 4.3 %), before it knew gaps (gait_events, "Data gaps")
    session, truth = simulate("walk", 40.0, 2, "typical", rate_hz=50.0, gait={})
    del session.sensors["pelvis"]
    return session, truth


def _run(session):
    from motionlab.pipeline import PipelineOptions, analyse

    session = dataclasses.replace(session, sensors=dict(session.sensors))
    analyse(session, PipelineOptions(protocol="walk", progress=False))
    return session


def test_the_heel_strikes_link_the_legs_without_a_pelvis(no_pelvis):
    session, truth = no_pelvis
    offset = {k: v["clock_offset_s"] for k, v in truth.sensors.items()}
    assert abs(offset["shank_l"] - offset["shank_r"]) > 0.02  # else nothing to find
    assert [root for root, _ in sync_forest(session, load_protocol("walk"))] == [
        "thigh_r", "thigh_l"
    ]  # fmt: skip
    done = _run(session)
    fits = done.results.clock_sync.fits
    assert fits["shank_l"].reference == "thigh_r" and fits["shank_l"].status == "applied"
    left = fits["shank_l"].offset_s - fits["shank_r"].offset_s  # shank_l against shank_r
    assert left == pytest.approx(offset["shank_l"] - offset["shank_r"], abs=0.003)
    g = done.results.gait
    summ = g.summary
    true = sp.summary(_true_steps(g.strides.frame(), truth.gait))
    assert summ.step_pairs >= 5 and "step_time_asymmetry_pct" not in summ.withheld
    assert true.step_pairs == summ.step_pairs
    # it read 10.9 % without the link, 4.3 % (true 0.4 %) with the IC taken across the gap
    assert summ.step_time_asymmetry_pct == pytest.approx(true.step_time_asymmetry_pct, abs=1.0)
    assert summ.strides_rejected.get("data gap") == 1  # the left stride over the gap


def test_legs_the_heel_strikes_cannot_link_withhold_what_compares_them(no_pelvis, monkeypatch,
                                                                        tmp_path):  # fmt: skip
    """Without a link (here: one asked tighter than the heel strikes give) the step time, double
    support, lengths, speed and asymmetry are not given, with the reason in the report, the
    console line and the CSV; each leg's own numbers are; each leg is still timed inside."""
    from motionlab.report import load_view, write_report
    from motionlab.report.console import _gait_line
    from motionlab.report.csv import gait_frames

    monkeypatch.setattr(stage, "LINK_MAX_SE_S", 1e-6)
    done = _run(no_pelvis[0])
    fits = done.results.clock_sync.fits
    assert fits["thigh_l"].status.startswith(f"{NOT_LINKED}: no sensor joins it to thigh_r")
    assert fits["shank_l"].reference == "thigh_l"  # the knee still on one clock
    g = done.results.gait
    summ = g.summary
    assert np.isnan(summ.step_time_asymmetry_pct) and np.isnan(summ.walking_speed_m_s)
    why = summ.withheld["step_time_asymmetry_pct"]
    assert why.startswith("not given: the two legs' sensor clocks are not linked (thigh_l:")
    assert all(summ.withheld[c] == why for c in sp.BOTH_LEGS)
    assert np.isnan(g.strides.step_time_s).all() and np.isnan(g.strides.double_support_pct).all()
    assert np.isfinite(summ.sides["l"]["stride_time_s"].mean)
    assert np.isfinite(summ.cadence_steps_per_min)
    view = load_view(done)
    assert f"step-time asymmetry {why}" in _gait_line(view)
    rows = gait_frames(view)["spatiotemporal_summary.csv"].set_index(["parameter", "side"])
    assert rows.loc[("step_time_asymmetry_pct", "both"), "note"] == why
    assert rows.loc[("double_support_pct", "l"), "note"] == why
    assert rows.loc[("stride_time_s", "l"), "note"] == ""
    strides = gait_frames(view)["spatiotemporal.csv"]  # the left stride over the lost packets
    assert strides.loc[strides["reason"] == "data gap", "side"].tolist() == ["l"]
    write_report([view], tmp_path / "r.pdf")
    text = " ".join((tmp_path / "r.txt").read_text().split())
    assert "the two legs' sensor clocks are not linked (thigh_l:" in text
    assert "data gap 1" in text.split("Strides kept:")[1].split(".")[0]
    assert "thigh_l against thigh_r's clock: not linked:" in text


def _fit(sensor: str, reference: str, status: str = "applied") -> ClockFit:
    return ClockFit(reference, sensor, 0.0, 0.0, 0.0, 1e-3, 1e-6, np.nan, 0.0, status, "network")


def test_which_clock_each_sensor_is_on():
    """A sensor's references followed to the root, or to a part's root not linked to it; the
    vendor's synchronised clocks (the data's answer kept, not applied) count as one."""
    linked = ClockSync({"shank_r": _fit("shank_r", "thigh_r"),
                        "thigh_l": _fit("thigh_l", "thigh_r")})  # fmt: skip
    assert linked.clock_of("shank_r") == linked.clock_of("thigh_l") == "thigh_r"
    assert linked.not_linked(["thigh_r", "shank_r", "thigh_l"]) == ""
    apart = ClockSync({"shank_r": _fit("shank_r", "thigh_r"),
                       "thigh_l": _fit("thigh_l", "thigh_r", f"{NOT_LINKED}: no sensor joins it"),
                       "shank_l": _fit("shank_l", "thigh_l")})  # fmt: skip
    assert apart.clock_of("shank_l") == "thigh_l"
    assert apart.not_linked(["shank_r", "shank_l"]) == "thigh_l: no sensor joins it"
    assert apart.not_linked(["thigh_l", "shank_l"]) == ""
    vendor = ClockSync({"thigh_l": _fit("thigh_l", "thigh_r", f"{stage.VENDOR_KEPT} (Synced); "
                                        f"the data's fit said: {NOT_LINKED}: ...")})  # fmt: skip
    assert vendor.not_linked(["thigh_r", "thigh_l"]) == ""
    # a file written before the parts existed: the left leg has no fit, its clock its own
    old = ClockSync({"shank_r": _fit("shank_r", "thigh_r")})
    assert old.not_linked(["shank_r", "shank_l"]) == "shank_l, thigh_r keep their own clocks, " \
                                                     "never compared"  # fmt: skip


def test_a_sensor_the_sync_could_not_time_is_named_on_the_way_to_its_clock():
    """A fit neither applied nor consistent with one clock (kept as recorded) leaves its
    sensor, and every sensor timed against it, at an unknown offset from the root; the
    vendor's synchronisation kept counts as timed, a part's root not linked is not untimed."""
    poor = "not reliable: the shared joint centre fits poorly"
    tree = ClockSync({"thigh_r": _fit("thigh_r", "pelvis", poor),
                      "shank_r": _fit("shank_r", "thigh_r"),
                      "thigh_l": _fit("thigh_l", "pelvis", "consistent with one clock"),
                      "shank_l": _fit("shank_l", "thigh_l")})  # fmt: skip
    assert tree.untimed(["thigh_l", "shank_l"]) is None
    assert tree.untimed(["shank_l", "shank_r"]) is tree.fits["thigh_r"]  # the shank's reference
    assert tree.untimed(["thigh_r", "shank_r"]) is None  # the knee: its shank timed on its thigh
    assert tree.untimed(["pelvis", "thigh_r"]) is tree.fits["thigh_r"]  # the hip
    # whose stamps may be off: the shank_r side of the shanks, the thigh's side of the hip
    assert tree.untimed_way(["shank_l", "shank_r"]) == (tree.fits["thigh_r"], ["shank_r"])
    assert tree.untimed_way(["pelvis", "thigh_r"]) == (tree.fits["thigh_r"], ["thigh_r"])
    assert tree.clock_of("shank_r") == "pelvis"  # on the root's clock as recorded
    vendor = ClockSync({"thigh_l": _fit("thigh_l", "thigh_r", f"{stage.VENDOR_KEPT} (Synced)")})
    assert vendor.untimed(["thigh_l"]) is None
    apart = ClockSync({"thigh_l": _fit("thigh_l", "thigh_r", f"{NOT_LINKED}: no sensor joins it")})
    assert apart.untimed(["thigh_l"]) is None  # said by not_linked


def test_a_hip_across_a_part_not_linked_to_the_pelvis_is_untimed():
    """Legs the heel strikes timed against each other and nothing against the pelvis are on
    the first leg sensor's clock, not linked to the pelvis's: a hip's two clocks were never
    compared (both hips were graded as if timed), a knee's were."""
    legs = ClockSync({"thigh_r": _fit("thigh_r", "pelvis", f"{NOT_LINKED}: nothing ties it"),
                      "shank_r": _fit("shank_r", "thigh_r"),
                      "thigh_l": _fit("thigh_l", "thigh_r"),
                      "shank_l": _fit("shank_l", "thigh_l")})  # fmt: skip
    assert legs.untimed_way(["pelvis", "thigh_r"]) == (legs.fits["thigh_r"], ["thigh_r"])
    assert legs.untimed_way(["pelvis", "thigh_l"]) == (legs.fits["thigh_r"], ["thigh_l"])
    assert legs.untimed(["thigh_l", "shank_l"]) is None  # the knees: one clock
    assert legs.untimed(["thigh_r", "shank_r"]) is None
    assert legs.untimed(["shank_l", "shank_r"]) is None


def test_legs_whose_clocks_were_not_timed_withhold_what_compares_them(tmp_path):
    """A harsh simulated walk (clocks up to ~0.1 s apart) whose heel strikes and joint centres
    did not time every leg sensor: the shanks stayed 66 ms apart as recorded and a symmetric
    walker read 24 % step-time asymmetry (±2.4); now what compares the legs is withheld, and
    each leg's own numbers are given; the knees, whose thigh and shank were not timed against
    each other, are weak (they were determined)."""
    from motionlab.pipeline import PipelineOptions, analyse
    from motionlab.simulate import simulate

    session, truth = simulate("walk", 40.0, 7, "harsh", rate_hz=50.0, gait={})
    offset = {k: v["clock_offset_s"] for k, v in truth.sensors.items()}
    assert abs(offset["shank_l"] - offset["shank_r"]) > 0.05  # else nothing to get wrong
    analyse(session, PipelineOptions(protocol="walk", progress=False))
    untimed = session.results.clock_sync.untimed(["thigh_r", "shank_r", "thigh_l", "shank_l"])
    assert untimed is not None and untimed.sensor in {"thigh_r", "shank_r", "thigh_l", "shank_l"}
    summ = session.results.gait.summary
    why = summ.withheld["step_time_asymmetry_pct"]
    assert why.startswith("not given: the two legs' sensor clocks were not all timed (")
    assert "--no-clock-sync" in why and all(summ.withheld[c] == why for c in sp.BOTH_LEGS)
    assert np.isnan(summ.step_time_asymmetry_pct) and np.isnan(summ.walking_speed_m_s)
    assert np.isfinite(summ.cadence_steps_per_min)
    assert all(np.isfinite(summ.sides[k]["stride_time_s"].mean) for k in "rl")
    knees = {k: session.results.calibration.grades[f"knee_{k}"] for k in "rl"}
    for side, knee in knees.items():  # a knee's flexion: weak, the clocks its first reason
        assert knee.grades[0] == "weak", side
        assert knee.reasons[0].startswith(f"the clocks of thigh_{side} and shank_{side} were "
                                          "not timed against each other ("), side  # fmt: skip
    # the run's screen names the sensors left as recorded beside the corrections
    from motionlab.report import ReportOutput, load_view
    from motionlab.report.console import run_summary

    names = {"session_file": "session.h5", "csv_dir": "csv", "results_json": "results.json"}
    out = ReportOutput(tmp_path / "report.pdf", tmp_path / "report.txt")
    text = run_summary(load_view(session), out, {}, 1.0, **names)
    line = next(x for x in text.splitlines() if x.startswith("  clock sync: "))
    kept = [k for k, f in session.results.clock_sync.fits.items() if not f.timed]
    assert "; not timed, as recorded: " + ", ".join(kept) + " (" in line, line


def test_summary_withholds_what_compares_the_legs():
    """Hand-made events, both legs: with ``not_linked`` the per-side step time, double support
    and lengths and the asymmetry are NaN with the reason; stride, stance and cadence stay."""
    ic_r = np.arange(0.0, 11.0, 1.1)
    ic_l = ic_r[:-1] + 0.55
    sides = {s: _strides(s, ic) for s, ic in (("r", ic_r), ("l", ic_l))}
    events = {s: _events(ic) for s, ic in (("r", ic_r), ("l", ic_l))}
    table = sp.stride_table(sides, events)
    given = sp.summary(table)
    assert given.step_time_asymmetry_pct == pytest.approx(0.0, abs=1e-6)
    summ = sp.summary(table, "not given: clocks")
    assert np.isnan(summ.step_time_asymmetry_pct)
    assert summ.withheld["step_time_asymmetry_pct"] == "not given: clocks"
    assert np.isnan(summ.sides["r"]["step_time_s"].mean)
    assert np.isnan(summ.sides["l"]["double_support_pct"].mean)
    assert summ.sides["r"]["stance_pct"].mean == pytest.approx(given.sides["r"]["stance_pct"].mean)
    assert summ.cadence_steps_per_min == pytest.approx(given.cadence_steps_per_min)


def _strides(side: str, ic: np.ndarray):
    from motionlab.kinematics.gait_events import Strides

    n = len(ic) - 1
    return Strides(side, ic[:-1], ic[:-1] + 0.68, ic[1:], np.ones(n, bool), [""] * n)


def _events(ic: np.ndarray):
    from motionlab.results import GaitEvents

    return GaitEvents(ic, np.ones(len(ic)), ic + 0.68, np.ones(len(ic)))


def test_a_refused_fit_that_measured_the_clocks_far_apart_leaves_the_joint_not_determined():
    """A simulated harsh arm (seed 3): the forearm's clock 116 ms from its upper arm's; the
    joint-centre fit said 120 ± 3 ms but was refused (its residual, soft tissue), so the elbow
    was read on the recorded stamps, flexion 13.9° RMS off, graded weak. At the sensors' speed
    the offset the refused fit measured, less twice its error, moves the angles by more than
    CLOCK_UNDETERMINED_DEG: not determined. An offset it measured near zero keeps weak."""
    from types import SimpleNamespace

    from motionlab.results import JointGrades
    from motionlab.segments import grades

    t = np.arange(0, 20, 0.01)
    gyr = np.column_stack([np.radians(200.0) * np.sin(2 * np.pi * 0.5 * t), 0 * t, 0 * t])
    sensors = {s: SimpleNamespace(gyr=gyr, segment=s, side="") for s in ("upperarm_r", "forearm_r")}
    protocol = SimpleNamespace(joints={"elbow_r": SimpleNamespace(
        proximal="upperarm_r", distal="forearm_r")})  # fmt: skip
    base = {"elbow_r": JointGrades(["determined"] * 3, [""] * 3)}
    poor = "not reliable: the shared joint centre fits poorly (residual 0.12 m/s²)"

    def graded(offset_s: float, se_s: float) -> JointGrades:
        fit = ClockFit("upperarm_r", "forearm_r", offset_s, 0.0, 10.0, se_s, 1e-6, 0.12, 30.0,
                       poor, "joint centre")  # fmt: skip
        session = SimpleNamespace(sensors=sensors, results=SimpleNamespace(
            clock_sync=ClockSync({"forearm_r": fit})))  # fmt: skip
        return grades.clock_graded(base, protocol, session)["elbow_r"]

    far = graded(-0.120, 0.003)
    assert far.grades == ["not determined"] * 3
    assert "the data put them 120 ± 3 ms apart: at least" in far.reasons[0]
    assert graded(-0.010, 0.003).grades == ["weak"] * 3
    assert graded(-0.120, 0.080).grades == ["weak"] * 3  # a fit that measured nothing
