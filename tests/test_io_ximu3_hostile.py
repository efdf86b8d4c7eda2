"""x-IMU3 exports broken on purpose (synthetic, ``tests/ximu3_export.py``): each is read, or
refused in one line naming the file, the place and a remedy; never a crash."""

from __future__ import annotations

import os

import pytest
from click.testing import CliRunner

from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.io import read_any
from tests import ximu3_export as xe

BACK = "imu/Back B4A2-5410-EC7B-D68C (UDP)"
IN_BACK = "in 'Back B4A2-5410-EC7B-D68C (UDP)'"


def _refusal(imu, *parts):
    """Ingest of the trial folder ``imu`` exits 2 with one line holding each of ``parts``; no
    output left."""
    out = imu.parent / "o.h5"
    res = CliRunner().invoke(main, ["ingest", str(imu), "-o", str(out)])
    assert res.exit_code == 2, res.output
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and line.startswith("error: "), line
    for part in parts:
        assert part in line, line
    assert not out.exists()
    return line


def _restamp(data: bytes, stamp) -> bytes:
    """The CSV ``data`` with each row's time stamp (first field, µs) replaced by
    ``stamp(us)``."""
    head, *rows = data.decode().splitlines()
    rows = [f"{stamp(int(r.split(',', 1)[0]))},{r.split(',', 1)[1]}" for r in rows]
    return ("\n".join([head, *rows]) + "\n").encode()


@pytest.mark.parametrize("text", ["[" * 200_000 + "]" * 200_000, "[" + "1" * 5000 + "]"])
def test_a_command_json_too_deep_or_with_a_huge_number_is_read_as_broken(tmp_path, text):
    """RecursionError and ValueError ('Exceeds the limit (4300 digits)') escaped the reader."""
    files = xe.export_files()
    files[f"{BACK}/Command.json"] = text.encode()
    back = read_any(xe.write(tmp_path, files)).sensors[0]
    assert (back.label, back.serial) == ("Back", "B4A2-5410-EC7B-D68C")
    assert (
        "Command.json is not readable JSON: name and serial from the folder"
        in (back.attrs["notes"])
    )


def test_a_quaternion_csv_of_zero_quaternions_is_refused(tmp_path):
    """Rows 'ts,0,0,0,0' raised IndexError ('boolean index did not match') in _onto."""
    files = xe.export_files()
    head, *rows = files[f"{BACK}/Quaternion.csv"].decode().splitlines()
    rows = [r.split(",")[0] + ",0,0,0,0" for r in rows]
    files[f"{BACK}/Quaternion.csv"] = ("\n".join([head, *rows]) + "\n").encode()
    line = _refusal(xe.write(tmp_path, files), f"Quaternion.csv {IN_BACK} lines 2–301")
    assert line.endswith(
        "no row has a time stamp and a whole orientation sample (values missing, NaN, ±inf or "
        "zero) — export the device again, or move Quaternion.csv out of the folder to read "
        "without the orientation"
    )


def test_a_magnetometer_csv_without_one_whole_row_is_refused(tmp_path):
    """X NaN on even rows, Y on odd ones: no finite row, the same IndexError."""
    files = xe.export_files()
    head, *rows = files[f"{BACK}/Magnetometer.csv"].decode().splitlines()
    for i, row in enumerate(rows):
        f = row.split(",")
        f[1 + i % 2] = "NaN"
        rows[i] = ",".join(f)
    files[f"{BACK}/Magnetometer.csv"] = ("\n".join([head, *rows]) + "\n").encode()
    _refusal(
        xe.write(tmp_path, files),
        f"Magnetometer.csv {IN_BACK} lines 2–61: no row has a time stamp and a whole "
        "magnetometer sample (values missing, NaN or ±inf)",
        "move Magnetometer.csv out of the folder",
    )


@pytest.mark.parametrize(
    ("stamp", "rate"), [(lambda us: us // 1000, "50000 Hz"), (lambda us: us * 1000, "0.05 Hz")]
)
def test_inertial_time_stamps_not_in_microseconds_are_blamed_on_inertial_csv(tmp_path, stamp, rate):
    """Stamps in ms were read as a 50 kHz, 0.02 s recording and refused later as a truncated
    Magnetometer.csv; stamps in ns were blamed on the gyroscope unit."""
    files = xe.export_files()
    files[f"{BACK}/Inertial.csv"] = _restamp(files[f"{BACK}/Inertial.csv"], stamp)
    line = _refusal(
        xe.write(tmp_path, files),
        f"Inertial.csv {IN_BACK} column 'Timestamp (us)': the time stamps give {rate}, an "
        "x-IMU3 samples at 1–20000 Hz: not in µs?",
    )
    assert line.endswith(
        "— the Timestamp (us) column must be in microseconds: export again from the x-IMU3 GUI, "
        "or convert the column"
    )


def test_negative_or_reversed_inertial_time_stamps_are_blamed_on_inertial_csv(tmp_path):
    files = xe.export_files()
    inertial = files[f"{BACK}/Inertial.csv"]
    files[f"{BACK}/Inertial.csv"] = _restamp(inertial, lambda us: us - xe.T0_US - 40_000)
    _refusal(
        xe.write(tmp_path / "neg", files),
        f"Inertial.csv {IN_BACK} line 2: negative time stamp -40000 µs: the device's clock "
        "counts up from 0",
    )
    head, *rows = inertial.decode().splitlines()
    files[f"{BACK}/Inertial.csv"] = ("\n".join([head, *rows[::-1]]) + "\n").encode()
    _refusal(
        xe.write(tmp_path / "rev", files),
        f"Inertial.csv {IN_BACK} column 'Timestamp (us)': the time stamps run backwards or "
        "stand still (median step -20000 µs)",
        "sort the rows by time",
    )


def _fifo(path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(path)


def _dev_zero(path):
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero here")
    os.symlink("/dev/zero", path)


@pytest.mark.parametrize(
    ("make", "what"),
    [
        (os.mkdir, "is a folder, expected a CSV file"),
        (_fifo, "is a named pipe (FIFO), expected a CSV file; it is not read"),
        (lambda p: os.symlink(p.name, p), "is a link to no file (missing, or a loop)"),
        (_dev_zero, "is a character device, expected a CSV file; it is not read"),
    ],
)
def test_an_inertial_csv_that_is_no_file_says_what_it_is(tmp_path, make, what):
    """A folder, FIFO, link to itself or to /dev/zero named Inertial.csv was reported as 'no
    Inertial.csv in the device folder'."""
    files = xe.export_files()
    del files[f"{BACK}/Inertial.csv"]
    imu = xe.write(tmp_path, files)
    make(imu.parent / BACK / "Inertial.csv")
    with pytest.raises(InputError) as err:
        read_any(imu)
    want = f"Inertial.csv {IN_BACK}: {what} — export the device again from the x-IMU3 GUI"
    assert err.value.line() == want


@pytest.mark.parametrize(
    ("name", "what"), [("Magnetometer.csv", "magnetometer"), ("Quaternion.csv", "orientation")]
)
def test_an_optional_channel_file_that_is_no_file_is_refused_as_an_unusable_one(
    tmp_path, name, what
):
    """A folder or FIFO named Magnetometer.csv or Quaternion.csv was silently left out; it is
    refused with the remedy of a truncated one (move it out to read without that channel)."""
    for make, kind in ((os.mkdir, "is a folder"), (_fifo, "is a named pipe (FIFO)")):
        files = xe.export_files()
        del files[f"{BACK}/{name}"]
        imu = xe.write(tmp_path / kind.split()[-1], files)
        make(imu.parent / BACK / name)
        _refusal(
            imu,
            f"{name} {IN_BACK}: {kind}, expected a CSV file",
            f"move {name} out of the folder to read without the {what}",
        )


def test_channel_files_that_do_not_overlap_the_inertial_data_say_so(tmp_path):
    """Inertial.csv's stamps shifted by 2e19 µs were blamed on Magnetometer.csv ('truncated?'):
    two clocks that never meet name neither file as the one at fault."""
    files = xe.export_files()
    files[f"{BACK}/Inertial.csv"] = _restamp(files[f"{BACK}/Inertial.csv"], lambda us: us + 2e19)
    _refusal(xe.write(tmp_path, files), "do not overlap in time", "Inertial.csv (2e+13")


def test_one_empty_time_stamp_is_named_by_its_line(tmp_path):
    """One empty stamp among 874 rows said 'fewer than two time-stamped rows'."""
    files = xe.export_files()
    head, *rows = files[f"{BACK}/Inertial.csv"].decode().splitlines()
    rows[10] = "," + rows[10].split(",", 1)[1]
    files[f"{BACK}/Inertial.csv"] = ("\n".join([head, *rows]) + "\n").encode()
    _refusal(xe.write(tmp_path, files), "Inertial.csv", "line 12: no time stamp")
