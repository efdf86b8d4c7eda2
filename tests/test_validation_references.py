"""References beyond markers: a CSV of segment quaternions and C3D model joint angles (written
with ezc3d here), each on its own clock (0.137 s ahead, 100 ppm fast) and rate, against a
simulated right-knee session whose gyroscopes are interval averages; and the sync's global
fallback and its standard error."""

import json

import ezc3d
import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from test_pipeline import PROTOCOL
from test_validation import calibrate_with_truth

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.protocol import load_protocol
from motionlab.session import load_session, save_session
from motionlab.simulate import simulate
from motionlab.simulate.errors import Preset
from motionlab.validation.model_angles import load_angle_map
from motionlab.validation.optical import resample_quat
from motionlab.validation.segment_csv import read_segment_csv
from motionlab.validation.time_alignment import synchronise
from motionlab.validation.time_offset import gyro_times

OFFSET_S, DRIFT = 0.137, 100e-6
LAB = rot.from_rotvec(np.radians([0.0, 0.0, 70.0]))  # lab → ENU: a turned lab


@pytest.fixture(scope="module")
def knee(tmp_path_factory):
    root = tmp_path_factory.mktemp("refs")
    (root / "knee_small.yaml").write_text(yaml.safe_dump(PROTOCOL))
    protocol = load_protocol(root / "knee_small.yaml")
    session, truth = simulate(protocol, 40.0, 4, Preset("clean"), rate_hz=100.0,
                              mounting_max_deg=10.0, gyr_sampling="interval")  # fmt: skip
    calibrate_with_truth(session, truth, protocol, knots=12)
    session.results.calibration.protocol_path = str(root / "knee_small.yaml")
    path = root / "s.h5"
    save_session(session, path)
    return root, path, truth


def _camera_times(truth, rate):
    """Frames on the reference clock (from 0) and the true times they were taken at."""
    t_cam = np.arange(0.0, OFFSET_S + (1 + DRIFT) * truth.time[-1], 1.0 / rate)
    t_true = (t_cam - OFFSET_S) / (1 + DRIFT)
    keep = (t_true >= truth.time[0]) & (t_true <= truth.time[-1])
    return t_cam[keep] + 3.0, t_true[keep]  # its own origin: frame 0 at 3 s


def _validate(path, reference, *extra):
    res = CliRunner().invoke(main, ["validate", str(path), "--reference", str(reference),
                                    "--json", "--force", *extra])  # fmt: skip
    assert res.exit_code == 0, res.output
    return json.loads(res.output), load_session(path).results.validation


def _error(result, truth, col):
    """The IMU angle minus the truth (deg)."""
    t = result.angles.time_s
    return result.angles.columns[col].imu_deg - np.interp(t, truth.time, truth.joint_angles[col])


def _direct(result, truth, col, centred=False):
    err = _error(result, truth, col)
    if centred:
        err = err - np.nanmean(err)
    return float(np.sqrt(np.nanmean(err**2)))


def test_segment_quaternion_csv_reference(knee):
    root, path, truth = knee
    t_cam, t_true = _camera_times(truth, 60.0)
    rng = np.random.default_rng(1)
    table = {"time": t_cam}
    for seg in ("thigh_r", "shank_r"):
        q = resample_quat(truth.time, truth.segments[seg]["orientation"], t_true)
        q = rot.mul(rot.conj(LAB), q)  # segment → lab
        q = rot.mul(q, rot.from_rotvec(rng.normal(0, np.radians(0.2), (len(q), 3))))
        for i, c in enumerate("wxyz"):
            table[f"{seg}_q{c}"] = q[:, i]
    csv = root / "segments.csv"
    pd.DataFrame(table).to_csv(csv, index=False, float_format="%.9g")
    digest, result = _validate(path, csv)
    assert result.reference.kind == "segments" and result.reference.frames == "anatomical"
    assert abs(digest["time_offset_s"] - (OFFSET_S + 3.0)) <= 0.005
    assert digest["sync"]["grade"] in ("good", "fair") and digest["sync"]["standard_error_ms"] < 2
    assert {result.optical[s].frame for s in ("thigh_r", "shank_r")} == {"segment_frame"}
    for col in truth.joint_angles:  # RMSE agreement as for markers (tests/test_validation.py)
        assert abs(result.angles.columns[col].rmse_deg - _direct(result, truth, col)) < 0.2, col
    assert digest["angles"]["knee_r_flexion_deg"]["r"] > 0.99


def _write_pig(path, t_cam, angles_xyz, rate):
    """A Plug-in-Gait-like C3D: one marker and RKneeAngles (deg) in POINT:ANGLES."""
    n = len(t_cam)
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [rate]
    f["parameters"]["POINT"]["LABELS"]["value"] = ["P01:RKneeAngles"]
    f["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    f.add_parameter("POINT", "ANGLES", ["P01:RKneeAngles"])
    f.add_parameter("POINT", "ANGLE_UNITS", ["deg"])
    points = np.ones((4, 1, n))
    points[:3, 0] = angles_xyz.T
    f["data"]["points"] = points
    f.write(str(path))


def test_c3d_model_angles_reference(knee):
    root, path, truth = knee
    rate = 100.0
    t_cam, t_true = _camera_times(truth, rate)
    start = t_cam[0]
    t_cam = t_cam - start  # a C3D starts at frame 0
    cols = ("knee_r_flexion_deg", "knee_r_adduction_deg", "knee_r_rotation_deg")
    frames_differ = np.array([1.5, 4.0, -6.0])  # another model's frames: constant offsets
    xyz = np.column_stack([np.interp(t_true, truth.time, truth.joint_angles[c]) for c in cols])
    _write_pig(root / "pig.c3d", t_cam, xyz + frames_differ, rate)
    digest, result = _validate(path, root / "pig.c3d")
    assert result.reference.kind == "model_angles"
    assert result.reference.mapping["knee_r_rotation_deg"] == "RKneeAngles.Z"
    assert abs(digest["time_offset_s"] - (OFFSET_S + 3.0 - start)) <= 0.005
    assert any("offsets are expected" in n for n in digest["notes"])
    for i, col in enumerate(cols):
        entry = result.angles.columns[col]
        assert abs(entry.rmse_centred_deg - _direct(result, truth, col, centred=True)) < 0.2
        own_bias = np.nanmean(_error(result, truth, col))
        assert entry.bias_deg - own_bias == pytest.approx(-frames_differ[i], abs=0.2)
    # a sign flipped by an angle map
    (root / "map.yaml").write_text(
        "knee_r_flexion_deg: {label: RKneeAngles, component: x}\n"
        "knee_r_rotation_deg: {label: RKneeAngles, component: z, sign: -1}\n"
    )
    res = CliRunner().invoke(main, ["validate", str(path), "--reference", str(root / "pig.c3d"),
                                    "--force", "--angle-map", str(root / "map.yaml")])  # fmt: skip
    assert res.exit_code == 0, res.output  # the printed summary names the reference's angles
    assert "reference: model joint angles knee_r_flexion_deg = RKneeAngles.X, " in res.output
    flipped = load_session(path).results.validation
    assert flipped.reference.mapping["knee_r_rotation_deg"] == "-RKneeAngles.Z"
    assert "knee_r_adduction_deg" not in flipped.angles.columns
    assert flipped.angles.columns["knee_r_rotation_deg"].r < 0
    # run takes it as its reference, and the report's validation pages take the result
    args = ["run", "--protocol", str(root / "knee_small.yaml"), str(path), "--quiet",
            "--reference", str(root / "pig.c3d"), "-o", str(root / "run"),
            "--no-clock-sync"]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    ran = load_session(root / "run" / "session.h5").results.validation
    assert ran.reference.kind == "model_angles"
    assert ran.angles.columns["knee_r_flexion_deg"].rmse_centred_deg < 3.0
    assert "knee_r_flexion" in (root / "run" / "report.txt").read_text()


def test_segment_csv_errors(tmp_path):
    bad = tmp_path / "a.csv"
    bad.write_text("time,thigh_r_qw,thigh_r_qx,thigh_r_qy\n" + "0,1,0,0\n" * 12)
    with pytest.raises(InputError, match="thigh_r_qz"):
        read_segment_csv(bad)
    bad.write_text("t,thigh_r_qw\n0,1\n")
    with pytest.raises(InputError, match="no time column"):
        read_segment_csv(bad)
    res = CliRunner().invoke(main, ["validate", str(tmp_path / "none.h5"), "--reference", str(bad)])
    assert res.exit_code == 2
    bad.write_text("")  # pandas' delimiter sniffer fails on an empty file (was exit 1)
    with pytest.raises(InputError, match="cannot be read as CSV"):
        read_segment_csv(bad)


LAUGHS = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True)
)


def test_angle_map_yaml_is_bounded_and_checked(tmp_path):
    path = tmp_path / "map.yaml"
    path.write_text(LAUGHS)  # a billion laughs: refused, not expanded
    with pytest.raises(InputError, match="alias"):
        load_angle_map(path)
    path.write_text("knee_r_flexion_deg: {label: RKneeAngles, component: [\n")
    with pytest.raises(InputError, match="line"):
        load_angle_map(path)
    path.write_text("knee_r_flexion_deg: {label: RKneeAngles, component: q}\n")
    with pytest.raises(InputError, match="key knee_r_flexion_deg"):
        load_angle_map(path)
    # a column written twice (the later won) and a sign of true (taken as 1) were accepted
    path.write_text(
        "knee_r_flexion_deg: {label: RKneeAngles, component: x}\n"
        "knee_r_flexion_deg: {label: LKneeAngles, component: y, sign: -1}\n"
    )
    with pytest.raises(InputError, match="written twice"):
        load_angle_map(path)
    path.write_text("knee_r_flexion_deg: {label: RKneeAngles, component: x, sign: true}\n")
    with pytest.raises(InputError, match="key knee_r_flexion_deg"):
        load_angle_map(path)


def _turning(seed, duration, rate=100.0):
    """An IMU and an optical body turning with smooth random rates; the gyroscope reports the
    interval averages."""
    rng = np.random.default_rng(seed)
    fine = np.arange(0.0, duration, 1e-3)
    w = np.cumsum(rng.normal(size=(len(fine), 3)), axis=0)
    w = (w - w.mean(axis=0)) / w.std() * 1.5
    q = rot.integrate_gyro(rot.IDENTITY, w, 1e-3)
    t_imu = np.arange(0.01, duration - 0.01, 1.0 / rate)
    q_imu = resample_quat(fine, q, t_imu)
    dq = rot.mul(rot.conj(resample_quat(fine, q, t_imu - 1.0 / rate)), q_imu)
    gyr = rot.to_rotvec(dq) * rate
    t_opt = np.arange(0.0, duration, 1 / 120.0)
    q_opt = resample_quat(fine, q, t_opt)
    return (t_imu, gyr), (t_opt + OFFSET_S, q_opt)


def test_interval_gyro_timing_and_global_fallback():
    (t, gyr), ref = _turning(2, 30.0)
    point = synchronise([(t, gyr)], [ref])
    interval = synchronise([(gyro_times(t), gyr)], [ref])
    assert abs(point.model.offset_s - (OFFSET_S - 0.005)) < 0.001  # half a sample off
    assert abs(interval.model.offset_s - OFFSET_S) < 0.001
    assert interval.grade == "good" and interval.standard_error_s < 0.001
    # 8 s of data: no 10 s window fits, one global offset instead of "0 windows" refused
    short = synchronise([(gyro_times(t[:800]), gyr[:800])], [ref])
    assert short.method == "global cross-correlation" and "0 window" in short.fallback
    assert abs(short.model.offset_s - OFFSET_S) < 0.002
    assert np.isfinite(short.standard_error_s) and short.grade in ("good", "fair")


def test_simulated_interval_gyroscope_is_the_mean_rate(knee):
    _, path, truth = knee
    s = load_session(path).sensors["shank_r"]
    assert s.attrs["gyr_sampling"] == "interval"
    t_true = truth.sensors["shank_r"]["sample_time"]
    q = resample_quat(truth.time, truth.sensors["shank_r"]["orientation"], t_true)
    mean_rate = rot.to_rotvec(rot.mul(rot.conj(q[:-1]), q[1:])) / np.diff(t_true)[:, None]
    inner = slice(100, -100)
    err = np.linalg.norm(s.gyr[1:][inner] - mean_rate[inner], axis=1)
    assert np.max(err) < 1e-6  # point samples are off by 0.27 rad/s (99th percentile) here


def test_marker_map_segment_frame_key(tmp_path):
    from motionlab.validation.markermap import load_marker_map

    path = tmp_path / "map.yaml"
    path.write_text("segments:\n  thigh_r: {rigid_body: femur, segment_frame: true}\n")
    assert load_marker_map(path).segments["thigh_r"].segment_frame
    path.write_text("segments:\n  thigh_r: {cluster: [A, B, C], segment_frame: true}\n")
    with pytest.raises(InputError, match="segment_frame"):
        load_marker_map(path)


def test_session_reference_kind_as_for_a_file():
    """validate without a reference file and run on inputs holding markers take the session's
    own reference through one function: model angles alone are an angles reference."""
    from motionlab.session import MarkerSet, ModelOutput, Session
    from motionlab.validation.reference_kinds import session_reference

    t = np.arange(5) / 100.0
    angles = ModelOutput("RKneeAngles", "angles", "deg", np.zeros((5, 3)))
    pig = MarkerSet("pig", t, model_outputs={"RKneeAngles": angles})
    assert session_reference(Session(markers={"pig": pig}))[1] == "angles"
    assert session_reference(Session(markers={"pig": pig}), "markers")[1] == "markers"
    markers = MarkerSet("m", t, labels=["A"], positions=np.zeros((5, 1, 3)),
                        model_outputs={"RKneeAngles": angles})  # fmt: skip
    assert session_reference(Session(markers={"m": markers})) == (markers, "markers")
    with pytest.raises(InputError, match="has no optical data"):
        session_reference(Session(), path="s.h5")


def test_an_angle_map_makes_a_pig_c3d_with_markers_an_angle_reference(knee):
    """A real Plug-in Gait C3D holds its markers as well as its POINT:ANGLES: README's
    ``--reference pig.c3d --angle-map angles.yaml`` validated against the markers and dropped
    the map without a word. The map now says the kind; the library refuses a map given with
    a marker reference."""
    root, path, truth = knee
    rate = 100.0
    t_cam, t_true = _camera_times(truth, rate)
    cols = ("knee_r_flexion_deg", "knee_r_adduction_deg", "knee_r_rotation_deg")
    xyz = np.column_stack([np.interp(t_true, truth.time, truth.joint_angles[c]) for c in cols])
    n = len(t_cam)
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [rate]
    f["parameters"]["POINT"]["LABELS"]["value"] = ["P01:RKneeAngles", "P01:RKNE"]
    f["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    f.add_parameter("POINT", "ANGLES", ["P01:RKneeAngles"])
    f.add_parameter("POINT", "ANGLE_UNITS", ["deg"])
    points = np.ones((4, 2, n))
    points[:3, 0] = xyz.T
    points[:3, 1] = 100.0  # a marker standing still
    f["data"]["points"] = points
    f.write(str(root / "pig_markers.c3d"))
    (root / "map2.yaml").write_text("knee_r_flexion_deg: {label: RKneeAngles, component: x}\n")
    args = ["validate", str(path), "--reference", str(root / "pig_markers.c3d"), "--force",
            "--angle-map", str(root / "map2.yaml")]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    assert "reference: model joint angles knee_r_flexion_deg = RKneeAngles.X" in res.output
    from motionlab import stages
    from motionlab.validation.reference_kinds import load_reference

    ref, kind = load_reference(root / "pig_markers.c3d")
    assert kind == "markers"  # without a map: its markers, with a note naming the angles
    with pytest.raises(InputError, match="angle map applies to a reference of model joint"):
        stages.validate(load_session(path), None, ref, reference_kind=kind, force=True,
                        angle_map=load_angle_map(root / "map2.yaml"))  # fmt: skip


def test_a_segment_csv_time_in_ms_or_ns_is_refused(tmp_path):
    """A time column in ms (or ns since the epoch) made the sync allocate a grid over its span
    ("internal error") or hang; a camera's step is 0.1 ms-1 s."""
    q = np.tile([1.0, 0.0, 0.0, 0.0], (20, 1))
    for name, t in (("ms", np.arange(20) * 8.33), ("ns", 1.7e18 + np.arange(20) * 8.33e6)):
        path = tmp_path / f"{name}.csv"
        pd.DataFrame({"time": t, **{f"thigh_r_q{c}": q[:, i] for i, c in enumerate("wxyz")}}
                     ).to_csv(path, index=False)  # fmt: skip
        with pytest.raises(InputError, match="time steps .* per row"):
            read_segment_csv(path)
    path = tmp_path / "s.csv"
    pd.DataFrame({"time": np.arange(20) / 120, **{f"thigh_r_q{c}": q[:, i]
                  for i, c in enumerate("wxyz")}}).to_csv(path, index=False)  # fmt: skip
    assert len(read_segment_csv(path).time) == 20


def test_a_segment_csv_as_excel_saves_it_and_one_with_no_quaternion(tmp_path):
    """Excel's byte-order mark hid the time column ("has no time column"); quaternion columns
    of zeros became a sync on nothing that blamed the session."""
    q = np.tile([1.0, 0.0, 0.0, 0.0], (20, 1))
    frame = pd.DataFrame({"time": np.arange(20) / 120, **{f"thigh_r_q{c}": q[:, i]
                          for i, c in enumerate("wxyz")}})  # fmt: skip
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + frame.to_csv(index=False).encode())
    assert len(read_segment_csv(bom).time) == 20
    zeros = tmp_path / "zeros.csv"
    frame.assign(**{f"thigh_r_q{c}": 0.0 for c in "wxyz"}).to_csv(zeros, index=False)
    with pytest.raises(InputError, match="segment 'thigh_r' has 0 rows with a quaternion"):
        read_segment_csv(zeros)


def test_an_angle_map_naming_a_label_the_file_lacks_is_refused(knee):
    """``knee_l_flexion_deg: {label: NoSuchAngles}`` beside a valid entry was accepted, with
    only a note "no reference for knee_l_flexion_deg": the typo was never named."""
    root, path, truth = knee
    rate = 100.0
    t_cam, t_true = _camera_times(truth, rate)
    cols = ("knee_r_flexion_deg", "knee_r_adduction_deg", "knee_r_rotation_deg")
    xyz = np.column_stack([np.interp(t_true, truth.time, truth.joint_angles[c]) for c in cols])
    _write_pig(root / "pig_typo.c3d", t_cam - t_cam[0], xyz, rate)
    (root / "typo.yaml").write_text(
        "knee_r_flexion_deg: {label: RKneeAngles, component: x}\n"
        "knee_r_rotation_deg: {label: NoSuchAngles, component: z}\n"
    )
    args = ["validate", str(path), "--reference", str(root / "pig_typo.c3d"), "--force",
            "--angle-map", str(root / "typo.yaml")]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2
    assert "the angle map names NoSuchAngles, which the file does not hold" in res.output


def test_a_segment_csv_column_given_twice_is_refused(tmp_path):
    """A repeated ``thigh_r_qw`` (or ``time``) column was resolved silently to its first copy."""
    q = np.tile([1.0, 0.0, 0.0, 0.0], (20, 1))
    rows = ["time,thigh_r_qw,thigh_r_qx,thigh_r_qy,thigh_r_qz,thigh_r_qw"]
    rows += [f"{k / 120},{','.join(map(str, q[k]))},0.0" for k in range(20)]
    path = tmp_path / "twice.csv"
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError, match="column thigh_r_qw appears more than once"):
        read_segment_csv(path)


def test_a_segment_csv_cell_of_text_is_refused_and_an_empty_one_is_a_gap(tmp_path):
    """A cell reading ``zero`` in a quaternion column was taken as a lost frame, silently; an
    empty cell is one (Motive leaves a lost body's cells empty)."""
    rows = ["time,thigh_r_qw,thigh_r_qx,thigh_r_qy,thigh_r_qz"]
    rows += [f"{k / 120},1,0,0,0" for k in range(20)]
    rows[8] = f"{7 / 120},,,,"
    path = tmp_path / "gap.csv"
    path.write_text("\n".join(rows) + "\n")
    q = read_segment_csv(path).rigid_bodies["thigh_r"]
    assert np.isnan(q[7]).all() and np.isfinite(np.delete(q, 7, axis=0)).all()
    rows[6] = f"{5 / 120},1,zero,0,0"
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"data row 6, column thigh_r_qx: 'zero' is not a number"):
        read_segment_csv(path)


def test_the_reference_is_low_passed_as_the_imu_angles_are(knee, tmp_path):
    """Angles low-passed at 6 Hz (``motionlab angles``' default) against a reference that
    carries a 15-Hz, 4° wobble: the validation low-passes the reference's angles alike, so the
    wobble (2.8° RMS) is not counted as the IMU's error; with the angles as computed (0) it is
    compared as it comes."""
    root, path, truth = knee
    rate = 100.0
    t_cam, t_true = _camera_times(truth, rate)
    t_cam = t_cam - t_cam[0]
    cols = ("knee_r_flexion_deg", "knee_r_adduction_deg", "knee_r_rotation_deg")
    xyz = np.column_stack([np.interp(t_true, truth.time, truth.joint_angles[c]) for c in cols])
    wobble = 4.0 * np.sin(2 * np.pi * 15.0 * t_cam)
    _write_pig(tmp_path / "pig.c3d", t_cam, xyz + wobble[:, None], rate)
    rmse = {}
    for cutoff in ("6", "0"):
        copy = tmp_path / f"s{cutoff}.h5"
        copy.write_bytes(path.read_bytes())
        res = CliRunner().invoke(main, ["angles", str(copy), "--angle-lowpass", cutoff])
        assert res.exit_code == 0, res.output
        _, result = _validate(copy, tmp_path / "pig.c3d")
        rmse[cutoff] = result.angles.columns["knee_r_flexion_deg"].rmse_centred_deg
    assert rmse["6"] < 1.0  # the wobble filtered out of the reference as out of the IMU's
    assert rmse["0"] > 2.5  # compared as it comes: the wobble is in the difference
