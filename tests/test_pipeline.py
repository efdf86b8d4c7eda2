"""motionlab run / run_pipeline: raw files + map + C3D reference → session, report, CSV, summary;
the errors a user meets (missing segments, existing outputs, mixed inputs); motionlab report."""

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from conftest import DATA, SHARED, generic_reader, needs_shared

from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.pipeline import PipelineOptions, PipelineResult, map_form, run_pipeline
from motionlab.session import SensorStream, Session, load_session, save_session
from motionlab.simulate import simulate
from motionlab.simulate.markers import OpticalSystem, write_c3d

PROTOCOL = {
    "name": "knee_small",
    "title": "Right knee, small test protocol",
    "segments": {
        "thigh_r": {"side": "r", "placement": "lateral thigh"},
        "shank_r": {"side": "r", "sensor_axes": ["-z", "y", "x"], "placement": "tibia"},
    },
    "calibration": [
        {
            "name": "standing",
            "kind": "static",
            "pose": "standing",
            "duration_s": 3,
            "vertical_axis": {"thigh_r": "y", "shank_r": "y"},
        },
    ],
    "joints": {"knee_r": {"type": "knee", "proximal": "thigh_r", "distal": "shank_r", "side": "r"}},
    "tasks": [{"name": "gait", "kind": "gait", "duration_s": 20}],
    "normative": {"gait": {"knee_flexion_deg": [0, 65]}},
    "metrics": ["rom", "peaks", "repetitions", "cycles", "varus_thrust"],
}
MAP = {
    "subject": {"id": "T01"},
    "session": {"date": "2024-05-03"},
    "sensors": {
        "THIGH": {"segment": "thigh_r", "side": "r"},
        "SHANK": {"segment": "shank_r", "side": "r"},
    },
    "reader": generic_reader(mag=True),
}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A simulated right-knee recording as two CSV files, a sensor map and a C3D reference."""
    root = tmp_path_factory.mktemp("raw")
    (root / "knee_small.yaml").write_text(yaml.safe_dump(PROTOCOL))
    session, truth = simulate(
        root / "knee_small.yaml",
        32.0,
        3,
        "typical",
        rate_hz=50.0,
        markers=True,
        mounting_max_deg=5.0,
        optical=OpticalSystem(rate_hz=50.0),
    )
    files = []
    for seg, name in (("thigh_r", "THIGH"), ("shank_r", "SHANK")):
        s = session.sensors[seg]
        table = np.column_stack([s.time, s.acc, s.gyr, s.mag])
        cols = ["t", "ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"]
        pd.DataFrame(table, columns=cols).to_csv(root / f"{name}.csv", index=False)
        files.append(root / f"{name}.csv")
    (root / "map.yaml").write_text(yaml.safe_dump(MAP))
    write_c3d(session.markers["optical"], root / "markers.c3d")
    save_session(session, root / "sim.h5")
    return root, files, truth


@pytest.fixture(scope="module")
def result(recorded) -> PipelineResult:
    root, files, _ = recorded
    options = PipelineOptions(
        root / "knee_small.yaml",
        map_path=root / "map.yaml",
        reference=root / "markers.c3d",
        progress=False,
        seed=2,
    )
    return run_pipeline(files, root / "out", options)


def test_outputs_and_metrics_table(result, recorded):
    _, _, truth = recorded
    assert result.session_path.is_file() and result.report_path.is_file()
    names = {p.name for p in result.csv_dir.iterdir()}
    assert {"knee_r_angles.csv", "metrics.csv", "quality.csv", "calibration.csv"} <= names
    m = result.metrics
    assert list(m.columns) == [
        "block",
        "joint",
        "angle",
        "column",
        "metric",
        "value",
        "unit",
        "grade",
        "normal_min_deg",
        "normal_max_deg",
        "vs_normal",
        "note",
    ]
    assert not m["metric"].str.startswith("curve_").any()  # one row per joint metric
    rom = m[(m.joint == "knee_r") & (m.angle == "flexion") & (m.metric == "max_deg")]
    assert len(rom) == 1 and rom.iloc[0]["unit"] == "deg"
    gait = next(s for s in truth.steps if s["name"] == "gait")
    inside = (truth.time > gait["start_s"]) & (truth.time < gait["end_s"])
    true_max = truth.joint_angles["knee_r_flexion_deg"][inside].max()
    assert rom.iloc[0]["value"] == pytest.approx(true_max, abs=5.0)


def test_session_holds_every_stage_and_the_provenance(result, recorded):
    root = recorded[0]
    ses = load_session(result.session_path)
    assert {"fusion", "calibration", "angles", "metrics", "validation"} <= set(ses.results.stages())
    assert ses.metadata["subject"]["id"] == "T01"
    assert ses.markers, "the reference is kept in the session"
    run = ses.provenance[-1]
    assert run["command"].startswith("motionlab run --protocol")
    assert run["parameters"]["seed"] == 2 and len(run["parameters"]["protocol_sha256"]) == 64
    hashed = {k.split("/")[-1] for p in ses.provenance for k in p["inputs"]}
    assert {"THIGH.csv", "SHANK.csv", "map.yaml"} <= hashed
    val = ses.results.validation.angles
    assert val.columns["knee_r_flexion_deg"].rmse_deg < 5.0
    # 6-D fusion and heading alignment: with the (uncalibrated) magnetometers the shank's
    # heading was turned in the walk and the rotation was 7.9° off
    assert all(e.magnetometer is False for e in ses.results.fusion.values())
    assert ses.results.validation.mode == "heading"
    # a knee calibrated from the walk alone has its axis to 5° at best, so its rotation is
    # graded not determined (segments/grades.py): the shank's principal axis lies 7° about its
    # long axis from the truth here (the pelvis's obliquity tilts its swing, as on real walks),
    # 8.8° of offset against the markers; its course follows them
    rotation = val.columns["knee_r_rotation_deg"]
    assert rotation.sd_deg < 3.0 and abs(rotation.bias_deg) < 12.0
    assert ses.results.calibration.grades["knee_r"].grades[2] == "not determined"
    assert str(root) in result.summary or "T01" in result.summary


def test_session_files_get_the_ingest_checks_from_ingest(recorded):
    """A session file without QC gets ingest's own per-stream checks (the same qc tree), and
    the pipeline calls the library's fusion stage, not the fuse command."""
    import ast

    import motionlab.pipeline as pipeline
    from motionlab import timebase
    from motionlab.ingest import check_and_fill

    session = load_session(recorded[0] / "sim.h5")
    stream = session.sensors["shank_r"]
    pipeline.prepare_sensors(session)
    expected = check_and_fill(*timebase.repair_clock(stream), pipeline.DEFAULT_GAP_MAX)
    assert session.sensors["shank_r"].qc == expected.qc
    assert "clock_repaired" in session.sensors["shank_r"].qc["flags"]
    tree = ast.parse(open(pipeline.__file__).read())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not any(m.startswith("motionlab.cli") for m in imported if m)


def test_report_text_and_one_screen_summary(result):
    text = result.report_path.with_suffix(".txt").read_text()
    pages = text.split("\f")
    assert len(pages) >= 8
    for word in (
        "Right knee",
        "flexion",
        "sagittal",
        "frontal",
        "transverse",
        "Summary",
        "Data quality",
        "Calibration quality",
        "Expected accuracy",
        "Methods appendix",
        "Validation against optical motion capture",
    ):
        assert word in text, word
    lines = result.summary.splitlines()
    assert len(lines) <= 30 and lines[0].startswith("motionlab run: knee_small")
    assert any("knee_r" in line and "normal 0–65°" in line for line in lines)


def test_existing_outputs_need_force(result, recorded):
    root, files, _ = recorded
    before = result.session_path.stat().st_mtime_ns
    with pytest.raises(InputError, match="output exists"):
        options = PipelineOptions(
            root / "knee_small.yaml", map_path=root / "map.yaml", progress=False
        )
        run_pipeline(files, root / "out", options)
    assert result.session_path.stat().st_mtime_ns == before


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_missing_segments_one_line_exit_2(tmp_path):
    res = run(
        "run",
        "--protocol",
        "knee",
        DATA / "xsens" / "MT_012005D6_031-000_00B421AF_excerpt.txt",
        "-o",
        tmp_path / "out",
    )
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 2 and lines[0] == "[1/7] ingest ..."
    assert "needs sensors on pelvis, thigh_r, thigh_l, shank_r, shank_l" in lines[1]
    assert "--map" in lines[1] and not (tmp_path / "out").exists()
    # the map to write, with the recording's own label
    assert "of the form 'sensors: {00B421AF: {segment: <pelvis, thigh_r, ...>}}'" in lines[1]


def test_map_form_names_the_recordings_labels_and_the_segments_to_choose():
    """The remedy's map form: the unmapped sensors' own labels (three at most), the missing
    segments to choose from on the first."""
    session = Session()
    for label in ("Back", "Chair", "Chest", "L_arm"):
        session.sensors[label] = SensorStream(label=label, time=np.arange(3.0))
    assert map_form(session, ["pelvis", "thorax"]) == (
        "{Back: {segment: <pelvis or thorax>}, Chair: {segment: ...}, Chest: {segment: ...}, ...}"
    )
    session.sensors["Back"].segment = "thorax"  # a mapped sensor is not offered again
    del session.sensors["L_arm"]
    assert map_form(session, ["pelvis"]) == "{Chair: {segment: <pelvis>}, Chest: {segment: ...}}"
    assert map_form(Session(), ["pelvis"]) == "{<sensor label>: {segment: <pelvis>}}"


@needs_shared
def test_missing_segments_shared_xsens_recording(tmp_path):
    path = SHARED / "formats" / "xsens" / "MT_012005D6_031-000_00B421AF.txt"
    res = run("run", "--protocol", "knee", path, "-o", tmp_path / "out", "--quiet")
    assert res.exit_code == 2
    assert res.output.count("\n") == 1
    assert res.output.startswith("error: MT_012005D6_031-000_00B421AF.txt: the 'knee' protocol")
    assert "pelvis, thigh_r, thigh_l, shank_r, shank_l" in res.output


def test_missing_one_segment_is_named(recorded, tmp_path):
    ses = load_session(recorded[0] / "sim.h5")
    del ses.sensors["shank_r"]
    save_session(ses, tmp_path / "no_shank.h5")
    res = run(
        "run",
        "--protocol",
        recorded[0] / "knee_small.yaml",
        tmp_path / "no_shank.h5",
        "-o",
        tmp_path / "out",
        "--quiet",
    )
    assert res.exit_code == 2
    assert "needs sensors on shank_r, thigh_r; the input has none on shank_r" in res.output
    assert "(its sensors: thigh_r (thigh_r))" in res.output


def test_missing_segment_of_a_mapped_recording_names_sides_and_what_to_do(recorded, tmp_path):
    """A map that gives segment and side (``thigh`` + ``r``) is listed as the protocol's
    ``thigh_r``, not as a bare ``thigh`` that reads as if the side were lost; and since every
    sensor is mapped the remedy is the recording or the protocol, not a map."""
    ses = load_session(recorded[0] / "sim.h5")
    del ses.sensors["shank_r"]
    ses.sensors["thigh_r"].segment, ses.sensors["thigh_r"].side = "thigh", "r"
    save_session(ses, tmp_path / "no_shank.h5")
    res = run("run", "--protocol", recorded[0] / "knee_small.yaml", tmp_path / "no_shank.h5",
              "-o", tmp_path / "out", "--quiet")  # fmt: skip
    assert res.exit_code == 2 and res.output.count("\n") == 1
    assert "(its sensors: thigh_r (thigh_r))" in res.output
    # its one joint lacks the shank: no copy of the protocol measures it (the shoulder DOT
    # recording was told to set 'required: false', then refused for no joint)
    assert "none of its joints (thigh_r–shank_r) has sensors on both its segments" in res.output
    assert "--map" not in res.output


def test_a_recording_with_one_joint_of_several_is_told_to_make_the_rest_optional():
    from pathlib import Path

    from motionlab.pipeline import check_segments
    from motionlab.protocol import load_protocol

    proto = load_protocol("knee")
    ses, _ = simulate(proto, 30.0, 0, "clean", rate_hz=50.0, calibration=False)
    for seg in ("thigh_l", "shank_l"):
        del ses.sensors[seg]
    with pytest.raises(InputError, match="none on thigh_l, shank_l .*set 'required: false'"):
        check_segments(ses, proto, [Path("walk.h5")])


def test_an_unreadable_reference_is_refused_before_any_work(recorded, tmp_path):
    """An OptiTrack Motive CSV (the shared trunk trials' reference) was refused only at the
    validate stage, after the fusion, and told to give a sensor map's column map."""
    root, files, _ = recorded
    motive = tmp_path / "optitrack.csv"
    motive.write_text("Format Version,1.23,Take Name,t1\n\n,Type,Rigid Body\nFrame,Time\n0,0.0\n")
    res = run("run", "--protocol", root / "knee_small.yaml", "--map", root / "map.yaml", *files,
              "--reference", motive, "-o", tmp_path / "out")  # fmt: skip
    assert res.exit_code == 2
    assert res.output.startswith("error: optitrack.csv: an OptiTrack Motive CSV export"), res.output
    assert "segment quaternions" in res.output and "--map" not in res.output
    assert res.output.count("\n") == 1 and not (tmp_path / "out").exists()


def test_sensors_on_no_segment_of_an_all_optional_protocol_are_refused_before_fusion(
    recorded, tmp_path
):
    """The walk protocol's segments are all optional: sensors mapped as femur and tibia passed
    the segment check, were fused, then the calibration crashed ('max() arg is an empty
    sequence'), in run and in the calibrate stage alike."""
    from motionlab import stages

    ses = load_session(recorded[0] / "sim.h5")
    for label, seg, name in (("thigh_r", "femur", "THIGH"), ("shank_r", "tibia", "SHANK")):
        stream = ses.sensors.pop(label)
        stream.label, stream.segment, stream.side = name, seg, "r"
        ses.sensors[name] = stream
    save_session(ses, tmp_path / "mapped.h5")
    res = run("run", "--protocol", "walk", tmp_path / "mapped.h5", "-o", tmp_path / "out")
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert lines[0] == "[1/8] ingest ..." and len(lines) == 2  # nothing fused
    assert "no joint of the 'walk' protocol has sensors on both its segments" in lines[1]
    assert "knee_r needs thigh_r and shank_r" in lines[1]
    assert "femur_r, tibia_r are no segments of it" in lines[1]
    assert not (tmp_path / "out").exists()
    with pytest.raises(InputError, match="no joint of the 'walk' protocol"):
        stages.calibrate(ses, "walk", path=tmp_path / "mapped.h5")


def test_session_file_cannot_be_mixed_or_mapped(recorded, tmp_path):
    root, files, _ = recorded
    res = run(
        "run",
        "--protocol",
        root / "knee_small.yaml",
        root / "sim.h5",
        files[0],
        "-o",
        tmp_path / "a",
        "--quiet",
    )
    assert res.exit_code == 2 and "cannot be combined" in res.output
    res = run(
        "run",
        "--protocol",
        root / "knee_small.yaml",
        root / "sim.h5",
        "--map",
        root / "map.yaml",
        "-o",
        tmp_path / "b",
        "--quiet",
    )
    assert res.exit_code == 2 and "--map applies to raw recordings" in res.output


def test_report_command_two_visits_adds_progress_page(result, tmp_path):
    ses = load_session(result.session_path)
    paths = []
    for i, date in enumerate(("2024-05-03", "2024-06-14")):
        ses.metadata["session"] = {"date": date, "visit": f"visit {i + 1}"}
        paths.append(tmp_path / f"v{i + 1}.h5")
        save_session(ses, paths[-1])
    res = run("report", *paths, "-o", tmp_path / "p.pdf", "--csv", tmp_path / "tables")
    assert res.exit_code == 0, res.output
    text = (tmp_path / "p.txt").read_text()
    assert "Progress over 2 visits (knee_small)" in text
    assert "visit 1" in text and "visit 2" in text
    assert (tmp_path / "tables" / "02_v2" / "metrics.csv").is_file()
    res = run("report", paths[0], "-o", tmp_path / "p.pdf")
    assert res.exit_code == 2 and "use --force" in res.output


def test_run_refuses_an_accelerometer_in_g(recorded, tmp_path):
    """A thigh file whose accelerometer is in g (read as m/s²) went through to the report
    without a word, later with a warning; gravity cannot be 1 m/s²: refused, as the ingest
    refuses it, before any output."""
    root, files, _ = recorded
    table = pd.read_csv(files[0])
    table[["ax", "ay", "az"]] /= 9.80665
    table.to_csv(tmp_path / "THIGH.csv", index=False)
    options = PipelineOptions(root / "knee_small.yaml", map_path=root / "map.yaml", seed=2)
    with pytest.raises(InputError, match=r"THIGH.csv sensor THIGH: \|a\| at rest is 1.00 m/s²"):
        run_pipeline([tmp_path / "THIGH.csv", files[1]], tmp_path / "out", options)
    assert not (tmp_path / "out").exists()


def test_the_metric_rows_carry_their_angles_grade(result):
    """batch's study tables and report read each session's grades from these rows."""
    m = result.metrics
    assert set(m["grade"]) <= {"determined", "weak", "not determined", ""}
    flexion = m[(m["joint"] == "knee_r") & (m["angle"] == "flexion")]
    assert len(flexion) and (flexion["grade"] != "").all()
