"""Xsens DOT exports broken on purpose (copies of the fixture in ``tests/data/dot``): each is
read, or refused in one line naming the file, the place and a remedy; never a crash."""

import pytest
from click.testing import CliRunner
from conftest import DATA

from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.io import detect_format, read_any

FIXTURE = DATA / "dot" / "RFemur_20210820_202113_840_excerpt.csv"
LINES = FIXTURE.read_text().splitlines()  # line 6 OutputRate, 12 the table header


def _write(tmp_path, lines):
    p = tmp_path / "dot.csv"
    p.write_text("\n".join(lines) + "\n")
    return p


def _refusal(path):
    """The one line ``motionlab ingest path`` exits 2 with."""
    out = path.parent / "o.h5"
    res = CliRunner().invoke(main, ["ingest", str(path), "-o", str(out)])
    assert res.exit_code == 2, res.output
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and line.startswith("error: "), line
    assert not out.exists()
    return line


@pytest.mark.parametrize("rate", ["6.0.0Hz", "1e309Hz", "9" * 400 + "Hz", "0Hz"])
def test_an_output_rate_that_is_no_rate_is_ignored_with_a_note(tmp_path, rate):
    """'6.0.0Hz' raised ValueError; '1e309Hz' was read as 1 Hz and the stamps' 60 Hz taken for
    a wrong time unit. The header rate is only a check: the stamps give the rate."""
    lines = list(LINES)
    lines[5] = f"OutputRate:,{rate}"
    s = read_any(_write(tmp_path, lines)).sensors[0]
    assert "nominal_rate_hz" not in s.attrs
    assert s.rate_hz == pytest.approx(60.0, abs=0.01)
    note = s.attrs["notes"][0]
    assert note.startswith(f"OutputRate '{rate[:40]}")
    assert note.endswith("' is no rate in Hz: ignored, the rate is the time stamps'")
    lines[5] = "OutputRate:, 30 hz"
    assert read_any(_write(tmp_path, lines)).sensors[0].attrs["nominal_rate_hz"] == 30.0


@pytest.mark.parametrize("tick", ["1e30", "-5", str(2**32)])
def test_a_sample_time_fine_out_of_its_32_bit_range_is_refused(tmp_path, tick):
    """1e30 overflowed int64 (read silently, or 'time stamp -9.22337e+12 s repeats'); -5 was
    'missing or non-integer tick value'."""
    lines = list(LINES)
    fields = lines[20].split(",")
    fields[1] = tick
    lines[20] = ",".join(fields)
    line = _refusal(_write(tmp_path, lines))
    assert line.startswith("error: dot.csv line 21: column 'SampleTimeFine': tick value ")
    assert line.endswith(
        " is out of range (0 to 2^32-1 µs, wrapping) — repair the row, or export the file again"
    )


@pytest.mark.parametrize("length", [70_000, 101])
def test_an_overlong_device_tag_is_refused_naming_its_line(tmp_path, length):
    """A 70 000-character DeviceTag pushed the table header out of the head detection reads:
    'unknown file format'."""
    lines = list(LINES)
    lines[1] = "DeviceTag:," + "x" * length
    p = _write(tmp_path, lines)
    assert detect_format(p) == "dot"
    assert _refusal(p) == (
        f"error: dot.csv line 2: DeviceTag is {length} characters long, at most 100 are read: "
        "damaged header? — export again from the Xsens DOT app, or shorten the tag in that line"
    )
    lines[1] = "DeviceTag:," + "x" * 100
    assert read_any(_write(tmp_path, lines)).sensors[0].serial == "x" * 100


def test_a_dot_preamble_without_its_table_says_so(tmp_path):
    """``sep=,`` and ``DeviceTag:,`` but no table header: a DOT export, not 'unknown format'."""
    with pytest.raises(InputError, match=r"no DOT table header \(PacketCounter,SampleTimeFine"):
        read_any(_write(tmp_path, LINES[:11]))


def test_a_dot_table_without_its_preamble_is_not_blamed_on_the_gyroscope(tmp_path):
    """Without ``sep=,`` and its ``Key:,value`` lines a DOT table is read as an MT Manager
    export (SampleTimeFine in 10 kHz ticks, gyroscope in rad/s) and refused for its gyroscope
    unit; it should be named as a DOT export without its header."""
    rates = DATA / "dot" / "femur_rate_quantities_excerpt.csv"
    line = _refusal(_write(tmp_path, rates.read_text().splitlines()[11:]))
    assert "DOT" in line and "gyroscope" not in line
