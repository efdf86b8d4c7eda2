"""Files cut short (a copy stopped, a full disk) are refused or repaired with a message that
says so: Xsens text, HDF5 and C3D, at the start, inside the header, and half-way."""

from pathlib import Path

import ezc3d
import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import DATA, SHARED, needs_shared

from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.io import detect_format, read_any

XSENS = DATA / "xsens" / "MT_012005D6_031-000_00B421AF_excerpt.txt"
BROAD = DATA / "broad" / "broad_10_excerpt.hdf5"


def _cut(tmp_path: Path, source: Path | bytes, n: int, name: str | None = None) -> Path:
    data = source if isinstance(source, bytes) else source.read_bytes()
    path = tmp_path / (name or (source.name if isinstance(source, Path) else "cut.bin"))
    path.write_bytes(data[:n])
    return path


# ---------------------------------------------------------------------------------- Xsens text


def test_xsens_cut_inside_the_first_data_row_says_truncated(tmp_path):
    data = XSENS.read_bytes()
    first_row = data.index(b"\n", data.index(b"PacketCounter")) + 1
    for n in (first_row + 3, first_row + 40, first_row + 100):
        with pytest.raises(InputError) as err:
            read_any(_cut(tmp_path, XSENS, n))
        assert err.value.where == "line 7"  # 5 comment lines, the header, then the cut row
        assert err.value.message.startswith("truncated: the only data row has")
        assert "fewer than the header" in err.value.message


def test_xsens_cut_inside_the_header_or_a_value(tmp_path):
    data = XSENS.read_bytes()
    with pytest.raises(InputError, match="truncated: the file ends inside its header"):
        read_any(_cut(tmp_path, XSENS, data.index(b"PacketCounter") + 6), {"format": "xsens"})
    with pytest.raises(InputError, match="header, which has no line end: truncated?"):
        read_any(_cut(tmp_path, XSENS, data.index(b"PacketCounter") + 40))
    text = "// Update Rate: 100.0Hz\nPacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n"
    text += "00001\t0.1\t0.2\t-9.8\n00002\t0.1\t0.2\t-"  # stops after a minus sign
    (s,) = read_any(_cut(tmp_path, text.encode(), len(text), "MT_cut.txt")).sensors
    assert s.n_samples == 1 and s.attrs["notes"] == ["line 4: truncated last line ('-') dropped"]


@pytest.mark.parametrize("fraction", [0.5, 0.9])
def test_xsens_cut_half_way_drops_the_partial_row_with_a_note(tmp_path, fraction):
    data = XSENS.read_bytes()
    n = int(len(data) * fraction)
    whole = data[:n].count(b"\n") - 6  # complete data rows before the cut
    (s,) = read_any(_cut(tmp_path, XSENS, n)).sensors
    assert s.n_samples == whole
    assert s.attrs["notes"][0].startswith(f"line {whole + 7}: truncated last line")


def test_truncated_xsens_through_the_cli_is_one_clear_line(tmp_path):
    data = XSENS.read_bytes()
    _cut(tmp_path, XSENS, data.index(b"\n", data.index(b"PacketCounter")) + 30, "in.txt")
    r = CliRunner().invoke(main, ["ingest", str(tmp_path / "in.txt"), "-o", str(tmp_path / "s")])
    assert r.exit_code == 2 and r.stderr.count("\n") == 1
    assert "in.txt line 7: truncated: the only data row has" in r.stderr


# ---------------------------------------------------------------------------------------- HDF5


@pytest.mark.parametrize("fraction", [0.05, 0.5, 0.9])
def test_truncated_hdf5_is_damaged_not_unknown(tmp_path, fraction):
    data = BROAD.read_bytes()
    path = _cut(tmp_path, BROAD, int(len(data) * fraction))
    with pytest.raises(InputError) as err:
        detect_format(path)
    assert err.value.message == "HDF5 file is damaged or truncated (h5py cannot open it)"
    assert err.value.path == path


def test_hdf5_of_another_layout_is_named_as_such(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f["x"] = np.zeros(3)
    with pytest.raises(InputError, match="HDF5 without the datasets of a BROAD or APDM file"):
        read_any(path)


# ----------------------------------------------------------------------------------------- C3D


def _c3d(path: Path, frames: int = 40, markers: int = 3) -> bytes:
    rng = np.random.default_rng(3)
    f = ezc3d.c3d()
    f["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    f["parameters"]["POINT"]["LABELS"]["value"] = [f"m{k}" for k in range(markers)]
    f["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    points = np.ones((4, markers, frames))
    points[:3] = rng.uniform(-1000, 1000, (3, markers, frames))
    f["data"]["points"] = points
    f.write(str(path))
    return path.read_bytes()


def _refusal(path: Path) -> str:
    with pytest.raises(InputError) as err:
        read_any(path)
    return err.value.line()


def test_c3d_cut_anywhere_is_refused_as_truncated(tmp_path):
    data = _c3d(tmp_path / "full.c3d")  # header 512 B, parameters blocks 2-3, data from 1536
    frame = 3 * 4 * 4  # 3 markers, x y z residual, float32
    half = (1536 + len(data)) // 2  # half-way through the 40 frames
    cases = {
        100: "truncated: the file ends inside its 512-byte header (100 bytes)",
        512: "truncated: the file ends before its parameter section",
        513: "truncated: the file ends before its parameter section",
        1000: "truncated: the file ends inside its parameter section",
        1536: "frame 1: truncated: the file ends before its first frame (the header announces 40)",
        1536 + 10: "frame 1: truncated: the file ends inside its first frame",
        half: "frame 22: truncated: the header announces 40 frames, the file holds 21",
        1536 + 36 * frame: "frame 37: truncated: the header announces 40 frames, the file holds 36",
    }
    for n, message in cases.items():
        path = _cut(tmp_path, data, n, "cut.c3d")
        assert detect_format(path) == "c3d"
        assert message in _refusal(path), n
    assert read_any(_cut(tmp_path, data, 1536 + 40 * frame, "cut.c3d")).markers[0].time.size == 40


@needs_shared
@pytest.mark.parametrize(
    "name",
    [
        "vicon_nexus_walking2.c3d",
        "optitrack_dec_int_walking.c3d",
        "optitrack_motive_sprintbasket.c3d",
    ],
)
def test_real_c3d_cut_at_half_nine_tenths_and_past_the_header(tmp_path, name):
    source = SHARED / "formats" / "c3d" / name
    size = source.stat().st_size
    for n in (size // 2, int(size * 0.9), 513):
        assert "truncated: the " in _refusal(_cut(tmp_path, source, n)), n


# ---------------------------------------------------------------------------------- TRC


TRC = DATA / "c3d" / "markers_20frames.trc"


@pytest.mark.parametrize("keep", [2, 6, 40, -3])
def test_trc_cut_inside_its_last_row_drops_that_row_with_a_note(tmp_path, keep):
    """A TRC copy stopped inside a row was read as a frame: cut in its time ("20,0." of
    "20,0.19") it was refused as 'frame times are not strictly increasing', cut later it kept a
    frame of cut-off markers. The cut row is dropped with a note, as the other readers do."""
    data = TRC.read_bytes()
    start = data.rstrip(b"\n").rindex(b"\n") + 1
    row = data[start:].rstrip(b"\n")
    path = _cut(tmp_path, data, start + (keep if keep > 0 else len(row) + keep))
    whole = read_any(TRC).markers[0]
    cut = read_any(path).markers[0]
    assert cut.positions.shape[0] == whole.positions.shape[0] - 1
    assert np.array_equal(cut.time, whole.time[:-1])
    assert any("truncated last line" in w for w in cut.attrs["warnings"])


def test_trc_whole_last_row_without_a_line_end_is_kept(tmp_path):
    data = TRC.read_bytes()
    cut = read_any(_cut(tmp_path, data, len(data.rstrip(b"\n")))).markers[0]
    assert cut.positions.shape[0] == read_any(TRC).markers[0].positions.shape[0]
