"""CAST landmarks: fixed in the cluster frames in a static window or trial, shared labels.

The acceptance case: an elbow session simulated like the knee one of ``test_validation.py``
(1 mm marker noise, occlusions, clock offset and drift, random mountings) whose anatomical
landmarks are seen only during the standing pose, as in the demo. The epicondyles RLHE/RMHE
are recorded as a copy on the upper arm and one on the forearm; in a still window both copies
stay put relative to either cluster, so only the protocol's landmark lists can tell them apart.
"""

import copy
import dataclasses
import json

import numpy as np
import pytest
from click.testing import CliRunner
from test_validation import VALIDATION_PRESET, calibrate_with_truth

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.protocol import load_protocol
from motionlab.results import Results
from motionlab.session import MarkerSet, Session, save_session
from motionlab.simulate import simulate
from motionlab.simulate.markers import write_c3d
from motionlab.validation import validate
from motionlab.validation.cast import (
    assign_landmarks,
    calibrate_landmarks,
    reconstruct,
    static_window,
)
from motionlab.validation.markermap import default_marker_map
from motionlab.validation.reference import optical_segments


def test_shared_labels_follow_the_landmark_lists():
    labels = ["UA1", "LE", "ME", "FA1", "LE", "ME", "RS", "GH"]
    wanted = {"upperarm": ["GH", "LE", "ME"], "forearm": ["RS", "LE", "ME", "US"]}
    got = assign_landmarks(labels, wanted)
    assert got == {"upperarm": {"GH": 7, "LE": 1, "ME": 2}, "forearm": {"RS": 6, "LE": 4, "ME": 5}}
    # one physical marker serves both segments
    once = assign_landmarks(["LE", "ME", "RS"], wanted)
    assert once["upperarm"]["LE"] == once["forearm"]["LE"] == 0
    with pytest.raises(InputError, match="LE occurs 3 times but 2 segment"):
        assign_landmarks(["LE", "LE", "LE"], wanted, "marker set 'x'")


def test_static_window_is_the_longest_still_run_with_landmarks():
    rng = np.random.default_rng(1)
    t = np.arange(0, 20, 0.01)
    turning = np.radians(40) * np.sin(np.pi * t)  # 126°/s peak, 0 at whole seconds
    still = ((t > 2) & (t < 6)) | ((t > 12) & (t < 19))
    angle = np.where(still, 0.0, turning)
    q = rot.from_rotvec(np.column_stack([angle, 0 * t, 0 * t]) + rng.normal(0, 0.003, (len(t), 3)))
    seen = (t > 1) & (t < 7)  # landmarks only in the first still run
    t0, t1 = static_window(t, [q, rot.from_rotvec(np.zeros((len(t), 3)))], seen)
    assert 2.0 <= t0 < 2.6 and 5.4 < t1 <= 6.0, (t0, t1)
    assert static_window(t, [q], seen & (t < 2.5)) is None  # too short


def test_landmarks_fixed_in_the_cluster_frame_are_rebuilt_in_every_frame():
    t = np.linspace(0, 10, 501)
    q = rot.from_rotvec(np.column_stack([0.3 * t, np.sin(t), 0 * t]))
    origin = np.column_stack([t, 2 * t, np.ones_like(t)])
    local = np.array([[0.1, -0.2, 0.03], [0.0, 0.05, -0.1]])
    truth = rot.rotate(q[:, None], local[None]) + origin[:, None]
    seen = truth.copy()
    seen[t > 2] = np.nan  # the landmarks are taken off after 2 s
    fixed, spread = calibrate_landmarks(seen, q, origin, np.ones(len(t), bool))
    np.testing.assert_allclose(fixed, local, atol=1e-12)
    assert np.all(spread < 1e-12)
    np.testing.assert_allclose(reconstruct(q, origin, fixed), truth, atol=1e-12)


@pytest.fixture(scope="module")
def elbow():
    protocol = load_protocol("elbow")
    session, truth = simulate(protocol, 180.0, 3, VALIDATION_PRESET, markers=True)
    full = session.markers["optical"]
    standing = truth.step("standing")
    frame_time = truth.markers["frame_time"]
    off = (frame_time < standing["start_s"]) | (frame_time > standing["end_s"])
    landmark = np.array([kind == "landmark" for kind in truth.markers["kinds"]])
    positions = full.positions.copy()
    positions[np.ix_(off, landmark)] = np.nan
    session.markers["optical"] = dataclasses.replace(full, positions=positions)
    calibrate_with_truth(session, truth, protocol)
    return session, truth, protocol, full


def _check_rmse_against_truth(result, truth):
    angles = result.angles
    t = angles.time_s
    for col, true_deg in truth.joint_angles.items():
        entry = angles.columns[col]
        direct = np.sqrt(np.nanmean((entry.imu_deg - np.interp(t, truth.time, true_deg)) ** 2))
        assert abs(entry.rmse_deg - direct) < 0.2, (col, entry.rmse_deg, direct)


def test_elbow_landmarks_in_the_standing_pose_only(elbow):
    session, truth, protocol, _ = elbow
    result = validate(session, protocol=protocol)
    _check_rmse_against_truth(result, truth)
    standing = truth.step("standing")
    for seg, info in result.optical.items():
        assert info.frame == "landmarks", seg
        assert info.static_source == "still window"
        # on the camera clock (0.137 s ahead), inside the standing pose
        start, end = np.array(info.static_s) - 0.137
        assert standing["start_s"] - 0.05 <= start < end <= standing["end_s"] + 0.05
        assert end - start > 3.0
        assert max(info.landmark_spread_mm.values()) < 3.0
        assert info.landmark_rms_mm == {}  # never seen outside the window


def test_shared_epicondyles_are_rebuilt_on_their_own_segment(elbow):
    session, _, protocol, full = elbow
    markers = session.markers["optical"]
    mmap = default_marker_map(markers, protocol, list(session.sensors))
    optical = optical_segments(markers, mmap, protocol)
    copies = [j for j, lab in enumerate(full.labels) if lab == "RLHE"]  # upper arm, forearm
    for seg, j in zip(("upperarm_r", "forearm_r"), copies, strict=True):
        rebuilt = optical[seg].landmark_trajectories()["RLHE"]
        d_own = np.linalg.norm(rebuilt - full.positions[:, j], axis=1)
        other = copies[1] if j == copies[0] else copies[0]
        d_other = np.linalg.norm(rebuilt - full.positions[:, other], axis=1)
        # the hidden copy of its own segment, through the whole session: marker noise only
        assert np.sqrt(np.nanmean(d_own**2)) < 0.0025, seg
        assert np.nanpercentile(d_other, 95) > 0.01, seg  # the other copy moves away


def _static_trial(full: MarkerSet, truth) -> MarkerSet:
    """The standing pose as a separate trial, in another lab frame and on its own clock."""
    standing = truth.step("standing")
    frame_time = truth.markers["frame_time"]
    keep = (frame_time > standing["start_s"] + 0.5) & (frame_time < standing["end_s"] - 0.5)
    turn = rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(70.0))
    moved = rot.rotate(turn, full.positions[keep]) + np.array([2.0, -1.0, 0.0])
    return MarkerSet("static", full.time[keep] - full.time[keep][0], full.labels, moved)


def test_landmarks_from_a_separate_static_trial(elbow, tmp_path):
    session, truth, protocol, full = elbow
    static = _static_trial(full, truth)
    landmark = [kind == "landmark" for kind in truth.markers["kinds"]]
    keep = [j for j, is_lm in enumerate(landmark) if not is_lm]  # clusters only
    movement = dataclasses.replace(
        full, labels=[full.labels[j] for j in keep], positions=full.positions[:, keep]
    )
    result = validate(session, movement, protocol=protocol, static=static)
    _check_rmse_against_truth(result, truth)
    for seg, info in result.optical.items():
        assert info.frame == "landmarks" and info.static_source == "static trial", seg

    ses = Session(sensors=session.sensors, metadata=session.metadata,
                  results=Results(fusion=session.results.fusion,
                                  calibration=copy.copy(session.results.calibration)))  # fmt: skip
    ses.results.calibration.protocol_path = "elbow"
    path, dyn, sta = tmp_path / "s.h5", tmp_path / "move.c3d", tmp_path / "static.c3d"
    save_session(ses, path)
    write_c3d(movement, dyn)
    write_c3d(static, sta)
    args = ["validate", str(path), "--reference", str(dyn), "--static", str(sta), "--json"]
    out = CliRunner().invoke(main, args)
    assert out.exit_code == 0, out.output
    digest = json.loads(out.output)
    for col, entry in digest["angles"].items():
        assert entry["rmse_deg"] == pytest.approx(result.angles.columns[col].rmse_deg, abs=0.05)

    for prefix_landmarks, message in ((False, "cluster marker thorax_C1"), (True, "none of the")):
        renamed = [
            "X" + lab if is_lm == prefix_landmarks else lab
            for lab, is_lm in zip(static.labels, landmark, strict=True)
        ]
        bad = dataclasses.replace(static, labels=renamed)
        with pytest.raises(InputError, match=message):
            validate(session, movement, protocol=protocol, static=bad)
