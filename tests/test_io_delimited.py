"""Fast delimited-text parsing (:mod:`motionlab.io.delimited`): values and file lines against a
line-by-line reference, and the exact line named for every kind of damage."""

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.io.delimited import TextFile, parse_table, read_lines

RNG = np.random.default_rng(20)


def _parse(tmp_path, data: bytes, header: int = 0, **kw):
    p = tmp_path / "t.csv"
    p.write_bytes(data)
    return parse_table(p, read_lines(p), header, **kw)


def _reference(lines: list[str], header: int, delimiter: str, decimal: str):
    """Values and 1-based lines of the data rows, one line at a time (the slow, obvious way)."""
    rows, where = [], []
    for i, line in enumerate(lines[header + 1 :], header + 2):
        s = line.strip()
        if not s or s.startswith(("#", "//")):
            continue
        cells = [c.strip() for c in line.split(delimiter)]
        rows.append([float(c.replace(decimal, ".")) if c not in ("", "NaN") else np.nan
                     for c in cells])  # fmt: skip
        where.append(i)
    return np.array(rows), np.array(where)


@pytest.mark.parametrize("seed", range(40))
def test_random_files_match_the_line_by_line_reference(tmp_path, seed):
    rng = np.random.default_rng(seed)
    delimiter = ["\t", ";", ",", " "][seed % 4]
    decimal = "," if delimiter in "\t;" and seed % 3 == 0 else "."
    ncol = int(rng.integers(2, 7))
    lines = ["// exported by a test"] * int(rng.integers(0, 3))
    header = len(lines)
    lines.append(delimiter.join(f"c{k}" for k in range(ncol)))
    for _ in range(int(rng.integers(1, 300))):
        kind = rng.random()
        if kind < 0.03:
            lines.append(["", "   ", "\t"][int(rng.integers(3))])
        elif kind < 0.06:
            lines.append(["# note", "  // note", "#"][int(rng.integers(3))])
        else:
            v = rng.normal(0, 100, ncol).round(int(rng.integers(0, 7)))
            cells = [f"{x:.6f}".replace(".", decimal) for x in v]
            if rng.random() < 0.1:
                cells[int(rng.integers(ncol))] = ["", "NaN"][int(rng.integers(2))]
            lines.append(delimiter.join(cells))
    eol = ["\n", "\r\n"][seed % 2]
    data = (eol.join(lines) + eol * (seed % 5 != 0)).encode()
    if not _reference(lines, header, delimiter, decimal)[0].size:
        return
    table = _parse(tmp_path, data, header, delimiter=delimiter if seed % 2 else None)
    values, where = _reference(lines, header, delimiter, decimal)
    assert table.delimiter == delimiter and table.decimal == decimal
    np.testing.assert_array_equal(table.data, values)
    np.testing.assert_array_equal(table.lines, where)
    assert table.preamble == lines[:header] and table.notes == []


def test_text_file_lines_like_splitlines(tmp_path):
    text = "a,b\r\nüber,2\r\n\r\nlast"
    p = tmp_path / "x.csv"
    p.write_bytes(b"\xef\xbb\xbf" + text.encode())
    lines = read_lines(p)
    assert list(lines) == text.splitlines() and len(lines) == 4 and lines.unended
    assert lines[1] == "über,2" and lines[-1] == "last" and lines[1:3] == ["über,2", ""]
    p.write_bytes("t;x\r1;é\r".encode("latin-1"))  # Latin-1, classic Mac line ends
    lines = read_lines(p)
    assert lines.encoding == "latin-1" and list(lines) == ["t;x", "1;é"]
    assert list(TextFile.from_lines(p, ["a", "b"])) == ["a", "b"]


def test_comment_lines_and_blank_lines_keep_file_line_numbers(tmp_path):
    text = "t,a\n# c\n0,1\n\n  // x\n1,2\n   \n2,3\n"
    t = _parse(tmp_path, text.encode())
    np.testing.assert_array_equal(t.lines, [3, 6, 8])
    np.testing.assert_array_equal(t.data, [[0, 1], [1, 2], [2, 3]])
    t = _parse(tmp_path, b"t;a\n% c\n0;1\n", comments=["%"])
    np.testing.assert_array_equal(t.lines, [3])


def _big(n: int, bad: dict[int, str]) -> bytes:
    """x-io style rows; ``bad`` replaces data row k (file line k + 2)."""
    rows = [f"{k * 0.01:.2f},0.1,0.2,0.3" for k in range(n)]
    for k, text in bad.items():
        rows[k] = text
    return ("t,a,b,c\n" + "\n".join(rows) + "\n").encode()


@pytest.mark.parametrize(
    ("bad", "message", "line"),
    [
        ("1,2,3,4,5", "5 columns, expected 4", 150_002),  # pandas fails: too many fields
        ("1,2,3", "3 columns, expected 4", 150_002),  # pandas pads: found from the NaN
        ("1;2;3;4", "1 columns, expected 4", 150_002),
        ("1,2,x3,4", "'x3' in numeric column 'b'", 150_002),
        ('1,"2,3,4', "a quote left open", 150_002),
    ],
)
def test_first_bad_line_of_a_large_file_is_named_exactly(tmp_path, bad, message, line):
    with pytest.raises(InputError) as err:
        _parse(tmp_path, _big(200_000, {150_000: bad, 190_000: bad}))
    assert message in err.value.message and err.value.where == f"line {line}"


def test_earliest_text_cell_is_named_whatever_its_column(tmp_path):
    with pytest.raises(InputError) as err:
        _parse(tmp_path, _big(50, {30: "1,abc,2,3", 10: "1,2,3,n.a."}))
    assert err.value.where == "line 12" and "'n.a.' in numeric column 'c'" in err.value.message


def test_truncated_files(tmp_path):
    t = _parse(tmp_path, _big(100, {})[:-5])  # cut inside the last row
    assert len(t.data) == 99 and t.notes == [
        "line 101: truncated last line (3 of 4 columns) dropped"
    ]
    with pytest.raises(InputError) as err:  # cut inside the only row: the delimiter is still known
        _parse(tmp_path, b"t\ta\tb\n0\t1")
    assert err.value.where == "line 2" and err.value.message.startswith(
        "truncated: the only data row has 2 of 3 fields (fewer than the header)"
    )
    with pytest.raises(InputError, match="no data rows"):
        _parse(tmp_path, b"t,a,b,c\n")
    with pytest.raises(InputError, match="no data rows after the header, which has no line end"):
        _parse(tmp_path, b"t,a,b,c")


def test_whitespace_delimiter_and_short_rows(tmp_path):
    t = _parse(tmp_path, b"  1   2\t3\n 4 5 6\n", header=0, header_rows=0, delimiter="whitespace")
    np.testing.assert_array_equal(t.data, [[1, 2, 3], [4, 5, 6]])
    with pytest.raises(InputError) as err:
        _parse(tmp_path, b"1 2 3\n4  5\n7 8 9\n", header_rows=0, delimiter="whitespace")
    assert err.value.where == "line 2" and "2 columns, expected 3" in err.value.message


def test_ragged_rows_and_end(tmp_path):
    with pytest.raises(InputError) as err:
        _parse(tmp_path, b"a,b\n1,2\n3,4,5\n", ragged=True, delimiter=",")
    assert err.value.where == "line 3" and "3 columns, expected 2" in err.value.message
    t = _parse(tmp_path, b"a,b\n1,2\n3\n4,5,,\r\n6,7\n", ragged=True, delimiter=",")
    np.testing.assert_array_equal(t.data, [[1, 2], [3, np.nan], [4, 5], [6, 7]])
    t = _parse(tmp_path, b"a,b\n1,2\n3,4\n,\n,\n", delimiter=",", end=3)
    np.testing.assert_array_equal(t.data, [[1, 2], [3, 4]])


def test_decimal_mark_equal_to_the_delimiter_is_refused(tmp_path):
    with pytest.raises(InputError, match="decimal mark and the delimiter are both ','"):
        _parse(tmp_path, b"a,b\n1,2\n", delimiter=",", decimal=",")


def test_plain_list_of_lines_still_works(tmp_path):
    t = parse_table(tmp_path / "x.csv", ["a;b", "1,5;2", "# c", "3;4"], 0)
    np.testing.assert_array_equal(t.data, [[1.5, 2], [3, 4]])
    np.testing.assert_array_equal(t.lines, [2, 4])


def test_utf16_text_is_named(tmp_path):
    """A UTF-16 export (x-IMU3's Inertial.csv re-saved as Excel 'Unicode text') was 'binary
    file, not delimited text'; it is named, with the encoding to use."""
    p = tmp_path / "Inertial.csv"
    p.write_bytes("Timestamp (us),Gyroscope X (deg/s)\n1,2\n".encode("utf-16"))
    with pytest.raises(InputError, match="text in UTF-16.* — save or export it as UTF-8"):
        read_lines(p)


def test_a_file_cut_inside_a_number_loses_its_last_line_with_a_note(tmp_path):
    """The hostile-input audit cut an x-IMU3 Inertial.csv after '0.' of '0.556448': the last
    row still read as numbers and the sensor ended 6 s early without a word. A file that ends
    without a line end and whose last number has fewer decimals than the line before loses
    that line, with a note; one that ends whole without a line end (the DOT app's) keeps it."""
    whole = "t,a,b\n0.000000,1.250000,0.556448\n0.020000,1.260000,0.556812"
    table = _parse(tmp_path, whole.encode(), 0)
    assert len(table.data) == 2 and table.notes == []
    table = _parse(tmp_path, (whole[:-6]).encode(), 0)
    assert len(table.data) == 1
    assert table.notes == ["line 3: truncated last line ('0.' at the end of the file) dropped"]
    table = _parse(tmp_path, (whole[:-6] + "\n").encode(), 0)  # a line end: written so
    assert len(table.data) == 2 and table.notes == []
