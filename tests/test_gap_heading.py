"""A packet-loss gap after the stand may hide a turn about the vertical that a 6-D heading keeps:
joints whose heading is tied only where a pose was held (the hips) are graded by it
(``segments.gap_headings``, ``grades.GAP_TURN_DEG``); knees, tied by their hinge every second,
are not."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED, needs_shared

from motionlab.io.clock import mark_shared_clock
from motionlab.pipeline import PipelineOptions, analyse, prepare_sensors
from motionlab.protocol import load_protocol
from motionlab.report.model import SessionView
from motionlab.report.sentences import cause_and_remedy
from motionlab.results import GapTurn, HeadingTie
from motionlab.segments import gap_headings, grades
from motionlab.session import SensorStream, Session, load_session, save_session
from motionlab.simulate import simulate

QMT = SHARED / "datasets" / "human" / "qmt_full_body" / "full_body_example_data.mat"


@pytest.fixture(scope="module")
def walk():
    """A stand and a 20-s walk on one clock, 0.15 s cut out of the left thigh mid-walk."""
    proto = load_protocol("walk")
    session, truth = simulate(proto, 28.0, 2, "typical", soft_tissue="motion")
    for label, s in list(session.sensors.items()):
        session.sensors[label] = dataclasses.replace(s, time=truth.sensors[label]["sample_time"])
    s = session.sensors["thigh_l"]
    keep = ~((s.time > 18.0) & (s.time < 18.15))
    session.sensors["thigh_l"] = dataclasses.replace(
        s, time=s.time[keep], acc=s.acc[keep], gyr=s.gyr[keep], mag=None
    )
    prepare_sensors(session)
    analyse(session, PipelineOptions(proto, progress=False, clock_sync=False))
    return session, proto


def test_the_fusion_stores_what_each_gap_may_have_missed(walk, tmp_path):
    """Every gap's bridge uncertainty (s after the gap, deg) is kept with the fusion and read
    back from the session file; the simulated thigh swings smoothly, so its 0.15-s gap's bridge
    misses little (under GAP_TURN_DEG) and no joint is graded by it."""
    session, _ = walk
    missed = session.results.fusion["thigh_l"].gaps_missed_deg
    near = [deg for t, deg in missed if 18.0 < t < 18.3]
    assert len(near) == 1 and 0.0 < near[0] < grades.GAP_TURN_DEG
    path = tmp_path / "lost.h5"
    save_session(session, path)
    again = load_session(path)
    np.testing.assert_allclose(again.results.fusion["thigh_l"].gaps_missed_deg, missed)
    assert again.results.calibration.gap_turns == session.results.calibration.gap_turns
    assert all(
        v.turn_deg < grades.GAP_TURN_DEG for v in again.results.calibration.gap_turns.values()
    )


def test_no_angle_inside_a_sensors_gap(walk):
    """Inside the left thigh's 0.15-s gap its joints (left hip and knee) have no angles: the
    thigh recorded nothing there (an 8-s gap had given 25-77° wrong knee angles, slerped
    across it); the right leg's stay."""
    session, _ = walk
    table = session.results.angles.columns()
    t = table["time_s"]
    inside = (t > 18.01) & (t < 18.14)
    around = ((t > 17.8) & (t < 17.95)) | ((t > 18.2) & (t < 18.35))
    assert inside.sum() >= 10
    for column in ("knee_l_flexion_deg", "hip_l_flexion_deg"):
        assert np.isnan(table[column][inside]).all() and np.isfinite(table[column][around]).all()
    assert np.isfinite(table["knee_r_flexion_deg"][inside]).all()


def test_a_gap_that_may_hide_a_turn_grades_the_hip_not_the_knee(walk):
    """The same walk with the gap's bridge said to miss 35° (as on a real walk's thigh): the
    left hip, tied at the stand only (its 20-s walk lies within 30 s of it: no walk ties), is not
    determined and says why; the knees (hinge ties) and the right hip keep their grades; 15°
    leaves the hip weak. Tied by a walk's anchors every second around the gap, it would not
    be graded by it (they take the turn out)."""
    session, proto = walk
    cal = session.results.calibration
    assert cal.headings.joints["hip_l"].source == "steps"
    every_second = HeadingTie("walk", np.arange(5.0, 28.0), np.zeros(23))
    by_walk = dataclasses.replace(
        cal.headings, joints={**cal.headings.joints, "hip_l": every_second}
    )
    for turn, expected in ((35.0, "not determined"), (15.0, "weak")):
        s = copy.deepcopy(session)
        entry = s.results.fusion["thigh_l"]
        s.results.fusion["thigh_l"] = dataclasses.replace(entry, gaps_missed_deg=[[18.151, turn]])
        walked = gap_headings(s, proto, by_walk).get("hip_l")
        assert walked is None or walked.time_s != 18.151  # tied again within a second
        found = gap_headings(s, proto, cal.headings)
        # the walk's other gaps (a simulated thigh swings smoothly: their bridges miss under a
        # degree) add to it as independent errors
        assert found["hip_l"].turn_deg == pytest.approx(turn, abs=0.01)
        assert (found["hip_l"].sensor, found["hip_l"].time_s) == ("thigh_l", 18.151)
        graded = grades.gap_graded(cal.grades, found)
        assert set(graded["hip_l"].grades) == {expected}
        said = f"{found['hip_l'].gaps} packet-loss gaps (the largest in thigh_l at 18.2 s) may"
        assert all(f"{said} together have hidden a turn of" in r for r in graded["hip_l"].reasons)
        for joint in ("knee_r", "knee_l", "hip_r"):
            assert graded[joint].grades == cal.grades[joint].grades
        if expected == "not determined":  # the gap decides: its reason first, for the summary
            assert all(r.startswith(f"{found['hip_l'].gaps} packet-loss gaps")
                       for r in graded["hip_l"].reasons)  # fmt: skip
            view = SessionView(Session(), proto, None, {}, None)
            cause, remedy = cause_and_remedy(view, "hip_l", graded["hip_l"].reasons[0])
            assert cause == "lost packets may have turned a sensor's heading"
            assert "fewer packets are lost" in remedy


def test_a_hips_flexion_is_graded_by_what_the_hidden_turn_moves_in_it(walk):
    """The turn a gap may hide is about the vertical: a hip's flexion, about a horizontal axis,
    moves by at most the thigh's tilt times (1 - cos turn). With the thigh tilting 30°: 15°
    moves it by 1.0° (determined, the other angles weak), 30° by 4.0° (weak, the others not
    determined), 45° by 8.8° (not determined, as they are); without a determined knee fit to
    give the tilt, flexion is graded as the other angles."""
    session, proto = walk
    cal = session.results.calibration
    tilted = dataclasses.replace(
        cal, hinges={**cal.hinges, "knee_l": dataclasses.replace(
            cal.hinges["knee_l"], proximal_tilt_deg=30.0, verdict="determined")},
    )  # fmt: skip
    assert cal.grades["hip_l"].grades[0] == "determined"
    cases = ((15.0, "determined", "weak", None), (30.0, "weak", "not determined", "4.0"),
             (45.0, "not determined", "not determined", "8.8"))  # fmt: skip
    for turn, flexion, others, moved in cases:
        gap = {"hip_l": GapTurn(turn, "thigh_l", 18.151, gaps=3)}
        graded = grades.gap_graded(cal.grades, gap, proto, tilted)["hip_l"]
        assert graded.grades == [flexion, others, others]
        if moved is None:
            assert graded.reasons[0] == cal.grades["hip_l"].reasons[0]
        else:
            assert graded.reasons[0].startswith("3 packet-loss gaps")
            assert f"up to {moved}° of flexion where thigh_l tilts 30°" in graded.reasons[0]
        assert "of flexion" not in graded.reasons[1]
        unfitted = dataclasses.replace(
            tilted, hinges={**tilted.hinges, "knee_l": dataclasses.replace(
                tilted.hinges["knee_l"], verdict="weak")},
        )  # fmt: skip
        g_all = "weak" if turn <= 2 * grades.GAP_TURN_DEG else "not determined"
        assert grades.gap_graded(cal.grades, gap, proto, unfitted)["hip_l"].grades == [g_all] * 3


def test_a_long_gap_between_walk_anchors_is_taken_out_by_them(walk):
    """An 8-s gap with the walk's anchors up to its first lost sample and from its end: they
    tie the heading on both sides, so the turn it hid is not kept (the bracket is measured from
    the gap's start, not from the sample after it, which an 8-s gap puts 8 s later)."""
    from motionlab.timebase import take

    session, proto = walk
    s = copy.deepcopy(session)
    stream = s.sensors["thigh_l"]
    s.sensors["thigh_l"] = take(
        stream, np.flatnonzero((stream.time < 10.0) | (stream.time > 18.15))
    )
    s.results.fusion["thigh_l"] = dataclasses.replace(
        s.results.fusion["thigh_l"], gaps_missed_deg=[[18.151, 400.0]]
    )
    cal = session.results.calibration

    def tied(anchors: np.ndarray) -> dict:
        tie = HeadingTie("walk", anchors, np.zeros(len(anchors)))
        return gap_headings(s, proto, dataclasses.replace(
            cal.headings, joints={**cal.headings.joints, "hip_l": tie}))  # fmt: skip

    walked = tied(np.r_[np.arange(5.0, 10.0), np.arange(19.0, 28.0)]).get("hip_l")
    assert walked is None or walked.time_s != 18.151
    far = tied(np.r_[np.arange(2.0, 4.0), np.arange(19.0, 28.0)])  # none in the 5 s before it
    assert far["hip_l"].turn_deg == pytest.approx(400.0, abs=0.01)
    graded = grades.gap_graded(cal.grades, {"hip_l": GapTurn(400.0, "thigh_l", 18.151)})
    assert "a turn of any size (over 180°)" in graded["hip_l"].reasons[0]


@needs_shared
@pytest.mark.skipif(not QMT.is_file(), reason="the qmt full-body recording is not in ../shared")
def test_a_real_walk_with_lost_packets_does_not_call_its_hips_determined():
    """The real 16-IMU walk with 15 bursts of 2-14 lost packets per sensor: its thighs' gaps may
    together have hidden turns of 104° and 69° (the hips then 2.4-35° RMS off the unbroken
    recording's; the largest gap alone, 11° on the right, had left the right hip weak with its
    rotation 35° off); the hips are not determined, flexion too (the thighs tilt 81-82° in the
    sitting: up to 52° of flexion), and the knees still are."""
    import scipy.io as sio

    m = sio.loadmat(QMT, squeeze_me=True, struct_as_record=False)
    t = np.asarray(m["t"], float) - float(m["t"][0])
    rng = np.random.default_rng(3)
    names = {"hip": "pelvis", "upper_leg_right": "thigh_r", "lower_leg_right": "shank_r",
             "upper_leg_left": "thigh_l", "lower_leg_left": "shank_l"}  # fmt: skip
    session = Session()
    for name, seg in names.items():
        keep = np.ones(len(t), bool)
        for start in rng.integers(0, len(t) - 20, 15):
            keep[start : start + rng.integers(2, 15)] = False
        session.sensors[seg] = SensorStream(
            label=seg, time=t[keep], acc=np.asarray(m[name].acc, float)[keep],
            gyr=np.asarray(m[name].gyr, float)[keep], segment=seg, vendor="Xsens",
            source_units={"acc": "m/s^2", "gyr": "rad/s"},
        )  # fmt: skip
    mark_shared_clock(list(session.sensors.values()), "one time vector t in the .mat file")
    prepare_sensors(session)
    analyse(session, PipelineOptions("walk", progress=False))
    g = session.results.calibration.grades
    assert g["knee_r"].grades[0] == g["knee_l"].grades[0] == "determined"
    assert g["hip_r"].grades == g["hip_l"].grades == ["not determined"] * 3


TRUNK = SHARED / "datasets" / "trunk" / "Danique" / "pivot_hs" / "imu"


@needs_shared
@pytest.mark.skipif(not TRUNK.is_dir(), reason="the trunk data set is not in ../shared")
def test_a_seated_trunk_with_lost_packets_is_graded_by_them():
    """A real seated trial (x-IMU3, 50 Hz; the wheelchair pivots) with 8 bursts of 2-9 lost
    packets per sensor: the lumbar heading is tied at the trunk's rest, and the gaps after it
    (33, the largest in the Back sensor during a pivot) may together have hidden a 16° turn
    (axial rotation 4.3° off the unbroken trial's on average, 5.7° RMS): the lumbar angles are
    weak, not determined as before, and say why."""
    from motionlab.ingest import ingest
    from motionlab.timebase import take

    session = ingest([TRUNK], Path(__file__).parents[1] / "protocols/examples/trunk_map.yaml")
    rng = np.random.default_rng(0)
    for label, s in list(session.sensors.items()):
        keep = np.ones(s.n_samples, bool)
        for start in rng.integers(0, s.n_samples - 20, 8):
            keep[start : start + rng.integers(2, 10)] = False
        session.sensors[label] = take(s, np.flatnonzero(keep))
    prepare_sensors(session)
    analyse(session, PipelineOptions("lumbar_seated", progress=False))
    cal = session.results.calibration
    assert cal.gap_turns["lumbar"].sensor == "Back" and cal.gap_turns["lumbar"].turn_deg > 10
    assert cal.grades["lumbar"].grades == ["weak"] * 3
    assert all(
        "packet-loss gaps (the largest in Back at" in r for r in cal.grades["lumbar"].reasons
    )


@pytest.mark.parametrize("stored", ["[[1.0, 2.0, 3.0]]", "[[18.0, NaN]]", '"hello"'])
def test_a_damaged_list_of_missed_turns_is_one_line(walk, tmp_path, stored):
    """A session file whose fusion entry's gaps_missed_deg is not finite [s, deg] pairs:
    calibrate names the file and the entry in one line, exits 2 and leaves the file as it was."""
    import h5py
    from click.testing import CliRunner

    from motionlab.cli import main

    session, _ = walk
    path = tmp_path / "lost.h5"
    save_session(session, path)
    with h5py.File(path, "a") as f:
        f["results/fusion/thigh_l"].attrs["gaps_missed_deg"] = stored
    before = path.read_bytes()
    res = CliRunner().invoke(main, ["calibrate", str(path), "--protocol", "walk", "--force"])
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [
        f"error: {path.name} results/fusion/thigh_l/gaps_missed_deg: is not a list of finite "
        "[time s, turn deg] pairs — fuse again with --force"
    ]
    assert path.read_bytes() == before


def test_a_hip_far_from_every_pose_is_graded_by_the_time_its_heading_is_not_held(walk):
    """A 30-min simulated walk with its stand the only pose read the right hip's rotation 28° RMS
    off in its first 5 min and 89-154° later, graded weak as the 28-s walk's. Farther than
    HEADING_HOLD_S from every pose a hip's adduction and rotation are not determined and its
    flexion weak; farther than three times it, all not determined; knees (hinge ties) keep
    theirs."""
    from motionlab.segments import unheld_headings

    session, proto = walk
    cal = session.results.calibration
    reach = unheld_headings(session, proto, cal.headings)
    assert set(reach) == {"hip_r", "hip_l"} and max(reach.values()) < grades.HEADING_HOLD_S
    assert grades.hold_graded(cal.grades, reach) == cal.grades  # a short walk: unchanged
    for seconds, expected in ((300.0, ["weak", "not determined", "not determined"]),
                              (900.0, ["not determined"] * 3)):  # fmt: skip
        graded = grades.hold_graded(cal.grades, {"hip_r": seconds})
        assert graded["hip_r"].grades == expected
        assert "the recording reaches" in graded["hip_r"].reasons[1]
        assert graded["hip_l"] == cal.grades["hip_l"] and graded["knee_r"] == cal.grades["knee_r"]
    view = SessionView(Session(), proto, None, {}, None)
    cause, remedy = cause_and_remedy(view, "hip_r", graded["hip_r"].reasons[0])
    assert cause == "the sensors' headings drift between poses" and "every 2 minutes" in remedy
