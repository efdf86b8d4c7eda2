"""x-IMU3 exports (a folder per device): synthetic exports written here, and the real trunk
recordings of ../shared when present."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.ingest import ingest
from motionlab.io import detect_format, read_any
from motionlab.pipeline import check_segments
from motionlab.protocol import load_protocol
from tests import ximu3_export as xe
from tests.conftest import ROOT, SHARED, needs_shared

TRUNK = SHARED / "datasets" / "trunk"
TRUNK_MAP = ROOT / "motionlab" / "protocols" / "examples" / "trunk_map.yaml"


def test_a_trial_folder_is_one_sensor_per_device_in_si_units(tmp_path):
    imu = xe.write(tmp_path, xe.export_files())
    assert detect_format(imu) == "ximu3"
    rec = read_any(imu)
    assert [s.label for s in rec.sensors] == ["Back", "Chest"]
    s = rec.sensors[0]
    assert s.serial == "B4A2-5410-EC7B-D68C"
    assert s.time[0] == pytest.approx(xe.T0_US * 1e-6)
    assert np.allclose(s.gyr[:, 2], np.radians(xe.RATE_DEG_S))
    assert np.allclose(s.acc[:, 2], 9.80665)
    assert s.source_units == {"time": "us", "gyr": "deg/s", "acc": "g", "mag": "a.u.", "quat": "1"}
    # the magnetometer (20 Hz) on the inertial clock (50 Hz): its norm kept, × the assumed 50 µT
    assert s.mag.shape == s.acc.shape
    assert np.allclose(np.linalg.norm(s.mag, axis=1), 50 * np.hypot(0.4, 0.9), rtol=1e-3)
    # the quaternion (100 Hz, NWU) on the inertial clock, in ENU: the device's yaw + 90°
    yaw = np.radians(xe.RATE_DEG_S) * (s.time - s.time[0]) + np.pi / 2
    want = np.column_stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)])
    assert np.degrees(rot.angle(rot.mul(rot.conj(want), s.quat))).max() < 1e-3
    notes = " ".join(s.attrs["notes"])
    assert "HighGAccelerometer.csv" in notes and "Battery.csv" in notes


def test_a_device_folder_or_its_inertial_csv_reads_the_device(tmp_path):
    imu = xe.write(tmp_path, xe.export_files())
    folder = imu / "Chest 37CE-5410-EC7B-D8A2 (UDP)"
    assert [s.label for s in read_any(folder).sensors] == ["Chest"]
    assert detect_format(folder / "Inertial.csv") == "ximu3"
    assert [s.label for s in read_any(folder / "Inertial.csv").sensors] == ["Chest"]


def test_ingest_and_cli_take_the_folder_and_hash_the_files_read(tmp_path):
    imu = xe.write(tmp_path, xe.export_files())
    session = ingest([imu])
    assert sorted(session.sensors) == ["Back", "Chest"]
    hashed = session.provenance[-1]["inputs"]
    assert any(k.endswith("Inertial.csv") for k in hashed) and len(hashed) == 8
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(main, ["ingest", str(imu), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.is_file()


def _refusal(tmp_path, files, *where):
    imu = xe.write(tmp_path, files)
    res = CliRunner().invoke(main, ["ingest", str(imu), "-o", str(tmp_path / "o.h5")])
    assert res.exit_code == 2, res.output
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and line.startswith("error: ")
    for w in where:
        assert w in line
    assert not (tmp_path / "o.h5").exists()
    return line


def test_a_device_folder_without_inertial_csv_is_refused(tmp_path):
    files = xe.export_files()
    del files["imu/Back B4A2-5410-EC7B-D68C (UDP)/Inertial.csv"]
    _refusal(tmp_path, files, "Inertial.csv", "no Inertial.csv", "export the device again")


def test_an_empty_inertial_csv_is_called_empty(tmp_path):
    """An empty channel file (a copy that failed) was 'not an x-IMU3 Inertial file'."""
    files = xe.export_files()
    files["imu/Back B4A2-5410-EC7B-D68C (UDP)/Inertial.csv"] = b""
    _refusal(tmp_path, files, "Inertial.csv in 'Back B4A2-5410-EC7B-D68C (UDP)': file is empty")


def test_a_truncated_magnetometer_csv_is_refused(tmp_path):
    files = xe.export_files()
    key = "imu/Chest 37CE-5410-EC7B-D8A2 (UDP)/Magnetometer.csv"
    files[key] = files[key][: len(files[key]) // 2]
    line = _refusal(tmp_path, files, "Magnetometer.csv", "truncated?")
    assert "move Magnetometer.csv out of the folder" in line


def test_two_devices_of_one_name_are_refused_unless_the_map_relabels_one(tmp_path):
    devices = (("Back", "B4A2-5410-EC7B-D68C"), ("Back", "37CE-5410-EC7B-D8A2"))
    line = _refusal(tmp_path, xe.export_files(devices), "sensor label 'Back'", "sensor map")
    assert "37CE-5410-EC7B-D8A2" in line  # the second device's folder is named
    (tmp_path / "map.yaml").write_text("sensors:\n  37CE-5410-EC7B-D8A2: {label: Back2}\n")
    session = ingest([tmp_path / "imu"], tmp_path / "map.yaml")
    assert sorted(session.sensors) == ["Back", "Back2"]


def test_a_map_key_matching_two_devices_names_both_device_folders(tmp_path):
    """The map keys 'Back', which both devices are called: the line named the trial folder twice."""
    devices = (("Back", "B4A2-5410-EC7B-D68C"), ("Back", "37CE-5410-EC7B-D8A2"))
    imu = xe.write(tmp_path, xe.export_files(devices))
    (tmp_path / "map.yaml").write_text("sensors:\n  Back: {segment: thorax}\n")
    with pytest.raises(InputError) as err:
        ingest([imu], tmp_path / "map.yaml")
    line = str(err.value)
    assert "'Back B4A2-5410-EC7B-D68C (UDP)'" in line and "'Back 37CE-5410-EC7B-D8A2 (UDP)'" in line
    assert "key the sensors by serial" in line


def test_a_study_map_naming_a_device_this_trial_lacks_warns_and_a_required_one_refuses(tmp_path):
    """The shipped trunk map names Back, Chest and Chair; a trial without its (optional) chair
    device is read with a warning, and the protocol runs without it. A typo in the key of a
    required segment ('Bakc') is refused where the protocol needs that segment, naming the key."""
    imu = xe.write(tmp_path, xe.export_files())
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(main, ["ingest", str(imu), "--map", str(TRUNK_MAP), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "warning: sensor map key 'Chair' (line 8, chair) names no sensor" in res.stderr
    info = CliRunner().invoke(main, ["info", str(out)])
    assert "warning: sensor map key 'Chair' (line 8, chair) named no sensor" in info.output
    (tmp_path / "typo.yaml").write_text(
        "sensors:\n  Bakc: {segment: thorax}\n  Chest: {segment: pelvis}\n"
    )
    session = ingest([imu], tmp_path / "typo.yaml")
    with pytest.raises(InputError) as err:
        check_segments(session, load_protocol("lumbar_seated"), [imu])
    assert "none on thorax (the sensor map's 'Bakc' named no sensor)" in err.value.line()


def test_devices_whose_clocks_do_not_overlap_are_refused_naming_them(tmp_path):
    """A device whose clock was an hour off (not synchronised before recording): the trunk
    calibration crashed on an empty shared span ("cannot convert float NaN to integer"). Now one
    line names each segment's sensor and its span, and the remedy."""
    from motionlab import stages

    files = xe.export_files(seconds=4.0)
    key = "imu/Back B4A2-5410-EC7B-D68C (UDP)/Inertial.csv"
    head, *rows = files[key].decode().splitlines()
    shifted = [f"{int(r.split(',')[0]) + 3_600_000_000},{r.split(',', 1)[1]}" for r in rows]
    files[key] = ("\n".join([head, *shifted]) + "\n").encode()
    del files["imu/Back B4A2-5410-EC7B-D68C (UDP)/Magnetometer.csv"]
    del files["imu/Back B4A2-5410-EC7B-D68C (UDP)/Quaternion.csv"]
    imu = xe.write(tmp_path, files)
    (tmp_path / "map.yaml").write_text(
        "sensors:\n  Back: {segment: thorax}\n  Chest: {segment: pelvis}\n"
    )
    session = ingest([imu], tmp_path / "map.yaml")
    stages.fuse(session)
    with pytest.raises(InputError) as err:
        stages.calibrate(session, load_protocol("lumbar_seated"))
    line = err.value.line()
    assert line.startswith("sensor clocks: the sensors share 0.0 s of recording")
    assert "thorax's Back 3600.0–3604.0 s" in line and "pelvis's Chest 0.0–4.0 s" in line
    assert "synchronise the devices' clocks before recording" in line


def test_a_folder_that_is_no_export_is_still_refused(tmp_path):
    (tmp_path / "x").mkdir()
    with pytest.raises(InputError, match="is a folder") as err:
        read_any(tmp_path / "x")
    assert err.value.line().endswith("give the file's path")


def test_a_trial_folder_holding_the_export_names_it_in_the_remedy(tmp_path):
    """A user gave the trial folder (``imu/`` and the optical file beside it): the refusal
    said only "give the file's path"; it names the export folder inside."""
    imu = xe.write(tmp_path / "trial", xe.export_files())
    (tmp_path / "trial" / "optitrack.csv").write_text("Format Version,1.23\n")
    with pytest.raises(InputError) as err:
        read_any(tmp_path / "trial")
    assert err.value.line().endswith(f"give the export folder inside it: {imu}")
    res = CliRunner().invoke(main, ["ingest", str(tmp_path / "trial"), "-o",
                                    str(tmp_path / "o.h5")])  # fmt: skip
    assert res.exit_code == 2 and f"inside it: {imu}" in res.stderr
    assert not (tmp_path / "o.h5").exists()


@needs_shared
def test_real_trunk_export_reads_every_device_with_the_vendor_vertical_agreeing():
    imu = TRUNK / "Aag" / "trunkmovement_ls" / "imu"
    if not imu.is_dir():
        pytest.skip("trunk data set not present")
    rec = read_any(imu)
    assert [s.label for s in rec.sensors] == ["Back", "Chair", "Chest", "L_arm", "R_Arm", "x-IMU3"]
    for s in rec.sensors:
        assert s.attrs["quat_rate_hz"] == pytest.approx(100, rel=0.05)
        assert s.attrs["mag_rate_hz"] == pytest.approx(20, rel=0.05)
        up = rot.rotate(s.quat, s.acc)
        up /= np.linalg.norm(up, axis=1)[:, None]
        assert np.median(up[:, 2]) > 0.98  # the vendor's earth z is up, as ENU's


def test_the_recording_date_is_the_time_the_gui_set_in_command_json(tmp_path):
    """``Command.json``'s ``{"time": "2025-02-13 11:28:59"}`` dates the recording: each device
    keeps it, the session's ``metadata["recorded"]`` is the earliest, and the report prints it
    as the session date when the sensor map gives none."""
    from motionlab.protocol import load_protocol
    from motionlab.report.model import SessionView
    from motionlab.session import Session

    imu = xe.write(tmp_path, xe.export_files())
    assert [s.attrs["recorded"] for s in read_any(imu).sensors] == ["2025-02-13"] * 2
    session = ingest([imu])
    assert session.metadata["recorded"] == "2025-02-13"
    view = SessionView(session, load_protocol("lumbar_seated"), None, {}, None)
    assert view.date == "2025-02-13"
    session.metadata["session"] = {"date": "2025-02-14"}  # the sensor map's word comes first
    assert view.date == "2025-02-14"
    assert SessionView(Session(), load_protocol("lumbar_seated"), None, {}, None).date == (
        "not recorded"
    )


def test_a_device_without_command_json_says_where_its_name_came_from(tmp_path):
    """Without ``Command.json`` the name and serial come from the folder's name, and the notes
    say so (and that the recording has no date)."""
    files = {k: v for k, v in xe.export_files().items() if not k.endswith("Command.json")}
    imu = xe.write(tmp_path, files)
    back = read_any(imu).sensors[0]
    assert (back.label, back.serial) == ("Back", "B4A2-5410-EC7B-D68C")
    assert "recorded" not in back.attrs or not back.attrs["recorded"]
    notes = " ".join(back.attrs["notes"])
    assert "no Command.json" in notes and "B4A2-5410-EC7B-D68C" in notes
    assert "no Command.json" not in " ".join(
        read_any(xe.write(tmp_path / "b", xe.export_files())).sensors[0].attrs["notes"]
    )
    out = tmp_path / "s.h5"
    assert CliRunner().invoke(main, ["ingest", str(imu), "-o", str(out)]).exit_code == 0
    info = CliRunner().invoke(main, ["info", str(out)]).output
    assert "note: no Command.json: device name 'Back'" in info
    assert "note: not read: Battery.csv, HighGAccelerometer.csv" in info


def test_a_renamed_column_names_the_header_line_and_a_remedy(tmp_path):
    """'Gyroscope X (°/s)' in an Inertial.csv header (a copy through an editor in Latin-1)
    was 'no column ...' with the column list where the remedy goes and no line."""
    files = xe.export_files()
    key = "imu/Back B4A2-5410-EC7B-D68C (UDP)/Inertial.csv"
    files[key] = files[key].replace(b"Gyroscope X (deg/s)", b"Gyroscope X (\xb0/s)", 1)
    line = _refusal(tmp_path, files, "Inertial.csv in 'Back B4A2-5410-EC7B-D68C (UDP)' line 1:")
    assert "no column 'Gyroscope X (deg/s)' (the header has Timestamp (us), Gyroscope X (°/s)" in (
        line
    )
    assert line.endswith("— export the file again with the vendor's column names, or correct "
                         "the header")  # fmt: skip


def test_a_map_forcing_another_format_on_an_export_folder_is_refused(tmp_path):
    """A map's ``reader: {format: generic, delimiter: 5, sensors: "x"}`` was silently ignored
    for an x-IMU3 folder (its values were never checked): the folder names the clash."""
    imu = xe.write(tmp_path, xe.export_files())
    with pytest.raises(InputError, match="is a ximu3 export folder, but the map's reader says "
                       "format 'generic'"):  # fmt: skip
        read_any(imu, {"format": "generic", "delimiter": 5})
    assert len(read_any(imu, {"format": "ximu3"}).sensors) == 2


def test_a_jump_of_the_inertial_clock_names_inertial_csv(tmp_path):
    """An Inertial.csv whose stamps jump by 10⁶ s was refused as 'Magnetometer.csv covers
    0.02-11.68 s of the inertial data's 0-1000011.71 s: truncated?', whose remedy (move the
    magnetometer out) threw good data away. The inertial file is named, at the line."""
    files = xe.export_files()
    key = next(k for k in files if k.endswith("Back B4A2-5410-EC7B-D68C (UDP)/Inertial.csv"))
    lines = files[key].decode().splitlines()
    stamp, rest = lines[51].split(",", 1)
    lines[51] = f"{int(stamp) + 10**12},{rest}"
    files[key] = ("\n".join(lines) + "\n").encode()
    imu = xe.write(tmp_path, files)
    jump = r"Inertial.csv.* line 52: the time stamps jump by 1e\+06 s"
    with pytest.raises(InputError, match=jump):
        read_any(imu)
