"""``motionlab export`` (sto, mot, c3d, json) round trips, and ``run`` writing results.json with
``--filter``."""

from __future__ import annotations

import dataclasses
import json

import ezc3d
import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import SHARED, needs_shared
from test_pipeline import PROTOCOL

from motionlab.cli import main
from motionlab.export import json_text, opensim_columns, orientations, results_json
from motionlab.io import read_any
from motionlab.io.opensim import read_mot
from motionlab.session import load_session, save_session
from motionlab.simulate import simulate
from motionlab.simulate.markers import OpticalSystem


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A simulated right-knee session with markers, run with --filter madgwick."""
    root = tmp_path_factory.mktemp("export")
    (root / "knee_small.yaml").write_text(yaml.safe_dump(PROTOCOL))
    session, _ = simulate(
        root / "knee_small.yaml", 32.0, 5, "typical", rate_hz=50.0, markers=True,
        mounting_max_deg=5.0, optical=OpticalSystem(rate_hz=50.0),
    )  # fmt: skip
    save_session(session, root / "sim.h5")
    args = ["run", "--protocol", str(root / "knee_small.yaml"), str(root / "sim.h5"), "-o",
            str(root / "out"), "--filter", "madgwick", "--no-clock-sync", "--quiet", "--json",
            str(root / "run.json")]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    return root / "out"


def _export(run_dir, fmt, name):
    out = run_dir / name
    res = CliRunner().invoke(
        main, ["export", str(run_dir / "session.h5"), "--to", fmt, "-o", str(out), "--force"]
    )
    assert res.exit_code == 0, res.output
    return out


def test_run_filter_and_results_json(run_dir):
    ses = load_session(run_dir / "session.h5")
    assert {e.name for e in ses.results.fusion.values()} == {"madgwick"}
    assert ses.provenance[-1]["parameters"]["estimator"] == "madgwick"
    assert "--filter madgwick" in ses.provenance[-1]["command"]
    written = json.loads((run_dir / "results.json").read_text())
    assert json.loads((run_dir.parent / "run.json").read_text()) == written  # run --json FILE
    again = results_json(ses)
    assert written["angles"]["joints"].keys() == again["angles"]["joints"].keys()
    for joint, entry in written["angles"]["joints"].items():
        for col, values in entry["columns"].items():
            np.testing.assert_allclose(
                np.array(values, dtype=float),
                np.array(again["angles"]["joints"][joint]["columns"][col], dtype=float),
            )
    assert sorted(map(json.dumps, written["metrics"])) == sorted(map(json.dumps, again["metrics"]))


def test_json_export_loads_with_grades_and_metrics(run_dir):
    doc = json.loads(_export(run_dir, "json", "r.json").read_text())  # strict JSON: no NaN
    assert doc["format"] == "motionlab-results"
    knee = doc["angles"]["joints"]["knee_r"]
    assert list(knee["columns"]) == ["knee_r_flexion_deg", "knee_r_adduction_deg",
                                     "knee_r_rotation_deg"]  # fmt: skip
    assert set(knee["grades"].values()) <= {"determined", "weak", "not determined"}
    assert len(knee["columns"]["knee_r_flexion_deg"]) == len(doc["angles"]["time_s"])
    assert doc["angles"]["lowpass_hz"] == 6.0  # the default cut-off, said with the angles
    row = doc["metrics"][0]
    assert {"block", "joint", "angle", "metric", "value", "unit", "grade"} <= set(row)
    assert "validation" in doc and "sync" in doc["validation"]
    # a measured value of an angle not determined is null, as in the CSV tables
    for joint in doc["angles"]["joints"].values():
        for col, grade in joint.get("grades", {}).items():
            assert (joint["columns"][col] is None) == (grade == "not determined")
    for r in doc["metrics"]:
        if r["grade"] == "not determined" and r["unit"] != "1":
            assert r["value"] is None, r
    # the series to the CSVs' 1e-4 deg (a 1-h walk's 17-digit floats made 98 MB)
    flexion = [v for v in knee["columns"]["knee_r_flexion_deg"] if v is not None]
    assert flexion and all(round(v, 4) == v for v in flexion)
    assert any(round(v, 3) != v for v in flexion)  # rounded, not truncated further


def test_json_series_take_under_nine_bytes_a_value(run_dir):
    """The series on one line each (``json_text``): a 10-minute walk's 660 000 values took
    9.9 MB indented a value a line (15 bytes a value), 5.4 MB so (docs/performance.md, "Long
    recordings"); the file reads back as before."""
    path = _export(run_dir, "json", "size.json")
    doc = json.loads(path.read_text())
    angles = doc["angles"]
    columns = [c for j in angles["joints"].values() for c in j["columns"].values() if c]
    values = len(angles["time_s"]) * (1 + len(columns))
    assert values > 3000
    angles["time_s"] = []
    for j in angles["joints"].values():
        j["columns"] = {k: [] if v else v for k, v in j["columns"].items()}
    series_bytes = path.stat().st_size - len(json_text(doc) + "\n")
    assert series_bytes <= 9 * values


def test_json_text_puts_number_lists_on_one_line_and_reads_back_the_same():
    tree = {
        "format": "motionlab-results",
        "series": [0.0, -1.2345, None, 1e-07, 3],
        "rows": [{"a": 1, "b": [True, False], "c": "é\n"}, [], {}, [[1, 2], ["x"]]],
        "empty": [],
        "none": None,
    }
    text = json_text(tree)
    assert json.loads(text) == tree
    assert '"series": [0.0,-1.2345,null,1e-07,3]' in text
    assert '"b": [\n' in text  # booleans are no numbers: as json.dumps indents them
    plain = {k: v for k, v in tree.items() if k != "series"}
    plain["rows"] = plain["rows"][:3]  # without number lists: json.dumps's very bytes
    assert json_text(plain) == json.dumps(plain, indent=1, allow_nan=False)
    with pytest.raises(ValueError):
        json_text({"x": [float("nan")]})  # standard JSON: NaN is null before it gets here


def test_sto_round_trip_through_ingest(run_dir):
    path = _export(run_dir, "sto", "orientations.sto")
    time, quats = orientations(load_session(run_dir / "session.h5"))
    assert sorted(quats) == ["femur_r_imu", "tibia_r_imu"]
    rec = read_any(path)
    assert rec.format == "opensim"
    for s in rec.sensors:
        np.testing.assert_allclose(s.quat, quats[s.label], atol=1e-6)
        np.testing.assert_allclose(s.time, time, atol=1e-9)
    res = CliRunner().invoke(main, ["ingest", str(path), "-o", str(run_dir / "sto.h5"),
                                    "--force"])  # fmt: skip
    assert res.exit_code == 0, res.output
    back = load_session(run_dir / "sto.h5")
    np.testing.assert_allclose(back.sensors["tibia_r_imu"].quat, quats["tibia_r_imu"], atol=1e-6)


@needs_shared
def test_sto_matches_files_opensim_wrote(run_dir):
    ours = run_dir / "orientations_cmp.sto"
    if not ours.exists():
        _export(run_dir, "sto", ours.name)
    theirs = SHARED / "formats" / "opensim" / "myComplexTasksTrial_orientations.sto"

    def head(path):
        lines = path.read_text().splitlines()
        end = lines.index("endheader")
        return {ln.split("=")[0] for ln in lines[:end] if "=" in ln}

    assert head(ours) == head(theirs)
    a, b = read_any(ours).sensors[0], read_any(theirs).sensors[0]
    assert a.attrs["earth_frame"] == b.attrs["earth_frame"]
    assert "Z up" in a.attrs["earth_frame"]


def test_mot_round_trip(run_dir):
    header, table = read_mot(_export(run_dir, "mot", "angles.mot"))
    assert header["inDegrees"] == "yes" and int(header["nRows"]) == len(table)
    angles = load_session(run_dir / "session.h5").results.angles.columns()
    # Rajagopal's coordinate where one maps (knee flexion), motionlab's names elsewhere; the
    # angles not determined left out (this small protocol's knee has a weak or undetermined
    # frame: its grades decide)
    grades = load_session(run_dir / "session.h5").results.calibration.grades["knee_r"].grades
    named = ["knee_angle_r", "knee_r_adduction", "knee_r_rotation"]
    kept = [n for n, g in zip(named, grades, strict=True) if g != "not determined"]
    assert list(table.columns[: 1 + len(kept)]) == ["time", *kept]
    np.testing.assert_array_equal(table["time"], angles["time_s"])
    np.testing.assert_array_equal(table["knee_angle_r"], angles["knee_r_flexion_deg"])


def test_opensim_coordinate_names_and_signs():
    cols = {c: np.array([10.0, -5.0]) for c in ("lumbar_flexion_deg", "lumbar_lateral_bending_deg",
            "hip_l_adduction_deg", "elbow_r_carrying_deg", "elbow_r_pronation_deg")}  # fmt: skip
    out = opensim_columns(cols)
    assert list(out) == ["lumbar_extension", "lumbar_bending", "hip_adduction_l",
                         "elbow_r_carrying_deg", "pro_sup_r"]  # fmt: skip
    np.testing.assert_array_equal(out["lumbar_extension"], [-10.0, 5.0])  # extension = −flexion
    np.testing.assert_array_equal(out["hip_adduction_l"], [10.0, -5.0])


def test_c3d_round_trip(run_dir):
    path = _export(run_dir, "c3d", "angles.c3d")
    ses = load_session(run_dir / "session.h5")
    raw = ezc3d.c3d(str(path))
    point = raw["parameters"]["POINT"]
    assert list(point["ANGLES"]["value"]) == ["knee_r_angles"]
    assert list(point["ANGLE_UNITS"]["value"]) == ["deg"]
    (m,) = read_any(path).markers
    angle = m.model_outputs["knee_r_angles"]
    assert angle.kind == "angles" and angle.unit == "deg"
    flex = ses.results.angles.data["knee_r_flexion_deg"]
    ok = np.isfinite(flex)
    np.testing.assert_allclose(angle.data[ok, 0], flex[ok], atol=1e-3)  # float32 in the file
    optical = next(iter(ses.markers.values()))
    assert m.labels == optical.labels
    assert np.nanmax(np.abs(m.positions)) == pytest.approx(
        np.nanmax(np.abs(optical.positions)), abs=0.05
    )  # metres, not mm


def test_export_errors(run_dir, tmp_path):
    res = CliRunner().invoke(main, ["export", str(run_dir / "session.h5"), "-o",
                                    str(tmp_path / "x.txt")])  # fmt: skip
    assert res.exit_code == 2 and "--to" in res.output
    empty = tmp_path / "empty.h5"
    from motionlab.session import Session

    save_session(Session(), empty)
    res = CliRunner().invoke(main, ["export", str(empty), "-o", str(tmp_path / "a.mot")])
    assert res.exit_code == 2 and "error: empty.h5: no joint angles" in res.output  # named
    assert not (tmp_path / "a.mot").exists()


def test_export_never_replaces_its_session_even_with_force(tmp_path):
    """``export s.h5 --to json -o s.h5 --force`` wrote the JSON over the analysed session."""
    from motionlab.session import Session

    path = tmp_path / "s.h5"
    save_session(Session(), path)
    before = path.read_bytes()
    res = CliRunner().invoke(
        main, ["export", str(path), "--to", "json", "-o", str(path), "--force"]
    )
    assert res.exit_code == 2 and "the output is also an input" in res.output
    assert path.read_bytes() == before


def test_c3d_keeps_gaps_on_its_frame_grid(run_dir, tmp_path):
    """The demo's angle table has 5 gaps (rows left out): written back to back at the rate,
    every later frame sat up to 0.7 s early and validating a session against its own export
    gave 6°. The frames are the grid from the first sample; a gap stays one (residual −1)."""
    from motionlab.results import AngleTable

    ses = load_session(run_dir / "session.h5")
    table = ses.results.angles
    t = np.asarray(table.time)
    keep = (t < 10.0) | (t > 10.5)  # half a second missing
    ses.results.angles = AngleTable(
        t[keep], {c: np.asarray(v)[keep] for c, v in table.data.items()}, table.units,
        table.events, table.method,
    )  # fmt: skip
    save_session(ses, tmp_path / "gap.h5")
    out = tmp_path / "gap.c3d"
    res = CliRunner().invoke(main, ["export", str(tmp_path / "gap.h5"), "--to", "c3d", "-o",
                                    str(out)])  # fmt: skip
    assert res.exit_code == 0, res.output
    raw = ezc3d.c3d(str(out))
    rate = raw["parameters"]["POINT"]["RATE"]["value"][0]
    labels = list(raw["parameters"]["POINT"]["LABELS"]["value"])
    i = labels.index("knee_r_angles")
    frames = raw["data"]["points"].shape[2]
    assert frames == pytest.approx((t[-1] - t[0]) * rate + 1, abs=1)  # the whole span
    residual = raw["data"]["meta_points"]["residuals"][0, i]
    grid = t[0] + np.arange(frames) / rate
    assert (residual[(grid > 10.05) & (grid < 10.45)] == -1).all()
    flex = np.asarray(table.data["knee_r_flexion_deg"])
    later = np.argmin(np.abs(grid - 20.0))  # a frame after the gap: the sample of its time
    assert raw["data"]["points"][0, i, later] == pytest.approx(
        np.interp(grid[later], t, flex), abs=0.05
    )


def test_exports_withhold_angles_not_determined(run_dir, tmp_path):
    """The .mot and the C3D gave numbers for angles the recording did not determine, which
    the CSV and the JSON withhold: the .mot leaves the coordinate out, the C3D writes 0 and
    says so in POINT:DESCRIPTIONS."""
    from motionlab.results import JointGrades

    ses = load_session(run_dir / "session.h5")
    grades = ses.results.calibration.grades["knee_r"]
    ses.results.calibration.grades["knee_r"] = JointGrades(
        ["determined", "not determined", "not determined"], ["", "x", "x"], grades.trunk
    )
    save_session(ses, tmp_path / "nd.h5")
    mot, c3d = tmp_path / "nd.mot", tmp_path / "nd.c3d"
    for fmt, out in (("mot", mot), ("c3d", c3d)):
        res = CliRunner().invoke(main, ["export", str(tmp_path / "nd.h5"), "--to", fmt, "-o",
                                        str(out)])  # fmt: skip
        assert res.exit_code == 0, res.output
    _, table = read_mot(mot)
    assert "knee_angle_r" in table.columns and "knee_r_adduction" not in table.columns
    raw = ezc3d.c3d(str(c3d))
    labels = list(raw["parameters"]["POINT"]["LABELS"]["value"])
    i = labels.index("knee_r_angles")
    assert "not determined" in raw["parameters"]["POINT"]["DESCRIPTIONS"]["value"][i]
    assert (raw["data"]["points"][1:3, i] == 0).all()


def test_sto_leaves_out_rows_in_a_sensors_gap(run_dir, tmp_path):
    """The demo's .sto had NaN rows wherever a sensor was in a gap, and motionlab refused its
    own file ("quat not a number … fusion bridges at most 0.1 s"): those rows are left out."""
    ses = load_session(run_dir / "session.h5")
    label = next(iter(ses.results.fusion))
    entry = ses.results.fusion[label]
    quat = np.array(entry.quat, dtype=float)
    quat[200:230] = np.nan  # 0.6 s at 50 Hz
    ses.results.fusion[label] = dataclasses.replace(entry, quat=quat)
    save_session(ses, tmp_path / "gap.h5")
    out = tmp_path / "gap.sto"
    res = CliRunner().invoke(main, ["export", str(tmp_path / "gap.h5"), "--to", "sto", "-o",
                                    str(out)])  # fmt: skip
    assert res.exit_code == 0 and "rows in a sensor's gap left out" in res.output, res.output
    assert "nan" not in out.read_text().lower()
    (rec,) = [read_any(out)]
    assert all(np.isfinite(s.quat).all() for s in rec.sensors)


def test_an_opensense_imu_name_is_its_segment():
    """motionlab's own .sto (OpenSense's names: tibia_r_imu) needed a hand-written map to be
    run again ("no joint has sensors on both its segments"): the names place the sensors."""
    from motionlab.kinematics.segment_types import opensim_imu_name, segment_of_opensim_imu

    for segment, side in (("shank", "r"), ("thigh", "l"), ("pelvis", ""), ("thorax", ""),
                          ("upperarm", "r"), ("forearm", "l")):  # fmt: skip
        assert segment_of_opensim_imu(opensim_imu_name(segment, side)) == (segment, side)
    assert segment_of_opensim_imu("femur_imu") is None  # a sided body without a side
    assert segment_of_opensim_imu("Back") is None
