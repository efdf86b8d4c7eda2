"""Broken input through ``motionlab ingest``: exit code 2, one stderr line, no file changed."""

import os

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from motionlab.cli import main

XIO_HEADER = (
    "Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
    "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)"
)
XSENS_HEADER = (
    "// Start Time: Unknown\n// Update Rate: 100.0Hz\n// Filter Profile: human (46.1)\n"
    "// Firmware Version: 4.0.2\n"
    "PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\n"
)
GENERIC_MAP = """reader:
  format: generic
  delimiter: ","
  time: t
  sensors:
    - label: shank
      serial: "S1"
      gyr: {{columns: [gx, gy, {gz}], unit: rad/s}}
"""


def xio_rows(n=50, bad=None):
    rows = [f"{k * 0.01:.2f},0.1,0.2,0.3,0.0,0.0,1.0" for k in range(n)]
    for k, text in (bad or {}).items():
        rows[k] = text
    return XIO_HEADER + "\n" + "\n".join(rows) + "\n"


def xsens_rows(n=50):
    return XSENS_HEADER + "".join(
        f"{k:05d}\t{k * 100}\t0.1\t0.2\t9.8\t0.01\t0.02\t0.03\n" for k in range(n)
    )


def generic_rows(delimiter=","):
    rows = [f"{k * 0.01:.2f},0.1,0.2,0.3" for k in range(50)]
    return ("t,gx,gy,gz\n" + "\n".join(rows) + "\n").replace(",", delimiter)


def broad_h5(path, n=100):
    with h5py.File(path, "w") as f:
        f["imu_acc"] = np.tile([0.0, 0.0, 9.81], (n, 1))
        f["imu_gyr"] = np.zeros((n, 3))
        f["imu_mag"] = np.tile([0.0, 20.0, -40.0], (n, 1))
        f["opt_quat"] = np.tile([1.0, 0, 0, 0], (n, 1))
        f["opt_pos"] = np.zeros((n, 3))
        f["movement"] = np.zeros(n, bool)
        f.attrs["sampling_rate"] = 285.7


def _truncated_h5(d):
    broad_h5(d / "full.hdf5")
    data = (d / "full.hdf5").read_bytes()
    (d / "full.hdf5").unlink()
    (d / "in.hdf5").write_bytes(data[: len(data) // 2])
    return ["in.hdf5"]


def _write(name, text):
    def make(d):
        (d / name).write_text(text)
        return [name]

    return make


def _with_map(data, map_text, data_name="in.csv"):
    def make(d):
        (d / data_name).write_text(data)
        (d / "map.yaml").write_text(map_text)
        return [data_name, "--map", "map.yaml"]

    return make


CASES = {
    "truncated text file": (_write("in.txt", xsens_rows(3)[: len(XSENS_HEADER) + 9]), "line"),
    "truncated HDF5 file": (_truncated_h5, "in.hdf5"),
    "wrong delimiter": (
        _with_map(generic_rows(";"), GENERIC_MAP.format(gz="gz")),
        "delimiter ';'",
    ),
    "text in numeric column": (
        _write("in.csv", xio_rows(bad={20: "0.20,0.1,abc,0.3,0.0,0.0,1.0"})),
        "line 22",
    ),
    "empty file": (_write("in.csv", ""), "empty"),
    "only a header": (_write("in.csv", XIO_HEADER + "\n"), "no data rows"),
    "unknown format": (
        _write("in.dat", "hello\nthis is no recording\n"),
        "unknown file format — give a column map, 'reader:' in --map (docs/ingest.md, 'The map')",
    ),
    # random bytes were told to give a column map, as if they were text
    "binary, no format": (_write("in.csv", "\x00\x17\x9c garbage \x00\x01"), "binary file of no"),
    # a MATLAB file (the shared full-body recording is one) was "binary of no format"
    "MATLAB .mat": (
        lambda d: (
            (d / "in.mat").write_bytes(
                b"MATLAB 5.0 MAT-file, Platform: posix" + bytes(92) + b"\x00\x01IM"
            ),
            ["in.mat"],
        )[1],
        "in.mat: a MATLAB .mat file",
    ),
    # a header line of megabytes (a file joined into one line) was "unknown file format"
    "one endless line": (_write("in.csv", "Time," + "x" * 200_000 + "\n1,2\n"), "past 64 kB"),
    "utf-16": (
        lambda d: ((d / "in.csv").write_bytes(XIO_HEADER.encode("utf-16")), ["in.csv"])[1],
        "in.csv: text in UTF-16",
    ),
    "non-monotonic time": (
        _write(
            "in.csv",
            xio_rows(
                bad={
                    10: "0.20,0.1,0.2,0.3,0.0,0.0,1.0",
                    20: "0.10,0.1,0.2,0.3,0.0,0.0,1.0",
                    30: "0.40,0.1,0.2,0.3,0.0,0.0,1.0",
                    40: "0.30,0.1,0.2,0.3,0.0,0.0,1.0",
                }
            ),
        ),
        "time goes backwards",
    ),
    # every row the same (one row repeated): the clock does not advance; was "rate nan Hz"
    "one repeated row": (
        _write("in.csv", XIO_HEADER + "\n" + "0.00,0.1,0.2,0.3,0.0,0.0,1.0\n" * 40),
        "1 distinct time stamp: the time does not advance",
    ),
    "missing required column": (
        _with_map(generic_rows(), GENERIC_MAP.format(gz="gw")),
        "gw",
    ),
    "NaN-only channel (x-io)": (
        _write("in.csv", xio_rows().replace("0.0,0.0,1.0", "NaN,NaN,NaN")),
        "Accelerometer X",
    ),
    "NaN-only channel (generic)": (
        _with_map(
            "t,gx,gy,gz\n" + "".join(f"{k / 100},NaN,NaN,NaN\n" for k in range(50)),
            GENERIC_MAP.format(gz="gz"),
        ),
        "gyr",
    ),
    "map names no sensor of the input": (  # one key of several absent: a warning (test_ingest)
        _with_map(
            xio_rows(),
            "sensors:\n  00B4FFFE: {segment: shank, side: r}\n  00B4FFFF: {segment: foot}\n",
        ),
        "key sensors.00B4FFFE",
    ),
}


def snapshot(d):
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(d.iterdir())}


def run(d, args):
    cwd = os.getcwd()
    os.chdir(d)
    try:
        return CliRunner().invoke(main, ["ingest", *args])
    finally:
        os.chdir(cwd)


def assert_clean_error(result, expect=None):
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert "Traceback" not in result.output
    if expect:
        assert expect in lines[0], lines[0]


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_bad_input(tmp_path, case):
    make, expect = CASES[case]
    args = make(tmp_path)
    before = snapshot(tmp_path)
    result = run(tmp_path, [*args, "-o", "session.h5"])
    assert_clean_error(result, expect)
    assert snapshot(tmp_path) == before  # inputs untouched, no output, no temporary file


def test_the_good_files_of_the_cases_do_ingest(tmp_path):
    (tmp_path / "a.csv").write_text(xio_rows())
    (tmp_path / "b.txt").write_text(xsens_rows())
    (tmp_path / "c.csv").write_text(generic_rows())
    (tmp_path / "map.yaml").write_text(GENERIC_MAP.format(gz="gz"))
    r = run(tmp_path, ["a.csv", "b.txt", "-o", "s.h5"])
    assert r.exit_code == 0, r.output
    r = run(tmp_path, ["c.csv", "--map", "map.yaml", "-o", "t.h5"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["info", str(tmp_path / "s.h5")])
    assert r.exit_code == 0 and "a " in r.output


def test_existing_output_without_force(tmp_path):
    (tmp_path / "in.csv").write_text(xio_rows())
    (tmp_path / "session.h5").write_bytes(b"precious")
    before = snapshot(tmp_path)
    assert_clean_error(run(tmp_path, ["in.csv", "-o", "session.h5"]), "--force")
    assert snapshot(tmp_path) == before
    assert run(tmp_path, ["in.csv", "-o", "session.h5", "--force"]).exit_code == 0
    assert (tmp_path / "session.h5").read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"


def test_unwritable_output_folder_is_a_file(tmp_path):
    (tmp_path / "in.csv").write_text(xio_rows())
    (tmp_path / "notadir").write_text("x")
    before = snapshot(tmp_path)
    assert_clean_error(run(tmp_path, ["in.csv", "-o", "notadir/session.h5"]), "session.h5")
    assert snapshot(tmp_path) == before


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root may write anyway")
def test_unwritable_output_read_only_folder(tmp_path):
    (tmp_path / "in.csv").write_text(xio_rows())
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        before = snapshot(tmp_path)
        assert_clean_error(run(tmp_path, ["in.csv", "-o", "ro/session.h5"]), "not writable")
        assert snapshot(tmp_path) == before and list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def test_a_reader_that_stops_reading_is_no_internal_error():
    """``motionlab angles s.h5 | head -1`` printed "internal error (BrokenPipeError)" and exited
    1 once head had its line: a reader that stops is no bug; the command stops quietly with
    the shell's SIGPIPE status."""
    import subprocess
    import sys

    from motionlab.cli import EXIT_BROKEN_PIPE

    code = (
        "import sys, click\n"
        "from motionlab.cli import main\n"
        "import motionlab.cli.info as info\n"
        "def stop(*a, **k):\n"
        "    raise BrokenPipeError(32, 'Broken pipe')\n"
        "info.command.callback = stop\n"
        "main(['info', 'x.h5'])\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == EXIT_BROKEN_PIPE
    assert "internal error" not in res.stderr and "Traceback" not in res.stderr


def test_a_usage_error_is_one_line_with_exit_2(tmp_path):
    """click's usage errors were three lines (Usage, Try, Error); every other refusal is one."""
    args = ["export", str(tmp_path / "s.h5"), "-o", str(tmp_path / "s.xyz")]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2
    lines = [x for x in res.output.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and " export --help'" in lines[0]


def test_a_task_that_ends_before_it_starts_says_so():
    from motionlab.cli.metrics import _parse_tasks
    from motionlab.errors import InputError

    with pytest.raises(InputError, match="starts at or after its end"):
        _parse_tasks(("gait=150:95",))
    with pytest.raises(InputError, match="is not NAME=START:END"):
        _parse_tasks(("gait=a:95",))


def test_a_full_disk_is_one_line_not_an_internal_error(tmp_path):
    """``info s.h5 > /dev/full`` ended in "internal error (OSError: No space left on device)"."""
    import subprocess
    import sys

    code = (
        "import errno\n"
        "from motionlab.cli import main\n"
        "import motionlab.cli.info as info\n"
        "def full(*a, **k):\n"
        "    raise OSError(errno.ENOSPC, 'No space left on device')\n"
        "info.command.callback = full\n"
        "main(['info', 'x.h5'])\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 2 and "internal error" not in res.stderr
    assert "cannot write (No space left on device)" in res.stderr
