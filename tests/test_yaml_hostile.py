"""Hostile values in the protocol and the sensor map (an audit on copies of the shipped
``lumbar_seated`` protocol and ``trunk_map``): each is refused in one line that names the key
and its line, and the file is left as it was; none crashes or is accepted to be blamed later on
the data."""

import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from motionlab.cli import main
from motionlab.errors import InputError
from motionlab.protocol import (
    PACKAGED,
    THRESHOLD_KEYS,
    TRUNK_ANGLES,
    list_protocols,
    load_protocol,
)
from motionlab.sensor_map import load_sensor_map

BIG = "1" + "0" * 400  # an integer too large for a float
PROTOCOL = PACKAGED / "lumbar_seated.yaml"
TRUNK_MAP = PACKAGED / "examples" / "trunk_map.yaml"
XSENS = Path(__file__).resolve().parent / "data" / "xsens" / "MT46_01-000_00B42D4D.txt"


def _short(value: object) -> str | None:
    """A test id cut short (the values hold numbers of 400 digits, names of 2000 characters)."""
    return value[:24] if isinstance(value, str) else None


def _edited(tmp_path: Path, source: Path, old: str, new: str, name: str = "bad.yaml") -> Path:
    """A copy of ``source`` with ``old`` replaced by ``new`` (once), in ``tmp_path``."""
    text = source.read_text()
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return path


def _line_of(path: Path, text: str) -> int:
    """The 1-based line of ``path`` that holds ``text``."""
    return next(i for i, t in enumerate(path.read_text().splitlines(), 1) if text in t)


def _refused(load, path: Path, key: str, line: int, *expect: str) -> str:
    """``load(path)`` raises an InputError naming ``key`` at ``line`` and holding ``expect``;
    the file is not changed. Returns the message."""
    before = path.read_bytes()
    with pytest.raises(InputError) as err:
        load(path)
    msg = err.value.line()
    assert "\n" not in msg, msg
    assert f"line {line}, key {key}:" in msg, msg
    for text in expect:
        assert text in msg, msg
    assert path.read_bytes() == before
    return msg


def _protocol(tmp_path: Path, old: str, new: str) -> Path:
    return _edited(tmp_path, PROTOCOL, old, new)


def _appended(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "bad.yaml"
    path.write_text(PROTOCOL.read_text() + text)
    return path


def test_shipped_protocols_and_maps_still_load():
    for name in list_protocols():
        load_protocol(name)
    load_protocol(PACKAGED / "examples" / "ring_rig.yaml")
    for path in (PACKAGED / "examples").glob("*_map.yaml"):
        load_sensor_map(path)
    assert {"varus_thrust_deg", "trunk_compensation_deg"} <= set(THRESHOLD_KEYS)
    assert TRUNK_ANGLES == ("flexion", "lateral_bending", "axial_rotation")


# -- 1. numbers too large for a float, not finite ------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "key", "marker"),
    [
        ("duration_s: 20", f"duration_s: {BIG}", "calibration[1].duration_s", BIG),
        ("duration_s: 20", "duration_s: .nan", "calibration[1].duration_s", ".nan"),
        ("duration_s: 20", f"duration_s: 20\n    time_range: [1, {BIG}]",
         "calibration[1].time_range", "time_range"),
        ("duration_s: 20", "duration_s: 20\n    time_range: [1, .inf]",
         "calibration[1].time_range", "time_range"),
        ("duration_s: 20", f"duration_s: 20\n    reference_rho: {{thorax: {BIG}}}",
         "calibration[1].reference_rho.thorax", "reference_rho"),
    ],
    ids=_short,
)  # fmt: skip
def test_a_number_that_is_no_finite_float_is_refused(tmp_path, old, new, key, marker):
    """A 400-digit duration raised OverflowError, a 400-digit time_range end TypeError
    ('ufunc isfinite not supported')."""
    path = _protocol(tmp_path, old, new)
    msg = _refused(load_protocol, path, key, _line_of(path, marker), "is not a finite number")
    assert len(msg) < 400, msg  # the number is shortened


def test_a_task_time_range_and_a_normal_range_too_large_for_a_float_are_refused(tmp_path):
    path = _appended(tmp_path, f"tasks:\n  - {{name: bend, kind: trunk, time_range: [0, {BIG}]}}\n")
    _refused(load_protocol, path, "tasks[0].time_range", _line_of(path, "name: bend"),
             "is not a finite number")  # fmt: skip
    path = _appended(
        tmp_path, f"normative:\n  trunk_movement: {{lumbar_flexion_deg: [0, {BIG}]}}\n"
    )
    _refused(load_protocol, path, "normative.trunk_movement.lumbar_flexion_deg",
             _line_of(path, "lumbar_flexion_deg"), "is not a finite number")  # fmt: skip


def test_a_huge_repetition_count_is_shortened_in_the_message(tmp_path):
    path = _protocol(tmp_path, "duration_s: 20", f"duration_s: 20\n    repetitions: {BIG}")
    msg = _refused(load_protocol, path, "calibration[1].repetitions",
                   _line_of(path, "repetitions"), "give a count between 0 and")  # fmt: skip
    assert len(msg) < 400, msg


@pytest.mark.parametrize(("text", "written"), [("2e1", "2.0e+1"), ("2.0e1", "2.0e+1")])
def test_e_notation_yaml_reads_as_text_says_how_to_write_it(tmp_path, text, written):
    """YAML 1.1 needs a point and a signed exponent: '1.0e3' (the old remedy) is text too."""
    path = _protocol(tmp_path, "duration_s: 20", f"duration_s: {text}")
    _refused(load_protocol, path, "calibration[1].duration_s", _line_of(path, text),
             f"is text '{text}'", f"write {written}")  # fmt: skip
    path = _protocol(tmp_path, "duration_s: 20", f"duration_s: {written}")
    assert load_protocol(path).calibration[1].duration_s == 20.0


# -- 2. the sensor map's reader options ----------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "expect"),
    [
        ("strong", "'strong' is not a number"),
        (BIG, "is not a finite number"),
        ("-50", "is -50 µT"),
        ("0", "is 0 µT"),
        ("1.0e+308", "is 1e+308 µT"),
        (".nan", "nan is not a finite number"),
        ("1.0e308", "is text '1.0e308'"),
    ],
    ids=_short,
)
def test_map_mag_field_ut_is_a_plausible_field(tmp_path, value, expect):
    """'strong' raised ValueError, 10**400 OverflowError; -50 flipped the magnetometer, 1e308 and
    .nan were blamed later on the data."""
    path = tmp_path / "map.yaml"
    path.write_text(TRUNK_MAP.read_text() + f"reader: {{mag_field_ut: {value}}}\n")
    msg = _refused(load_sensor_map, path, "reader.mag_field_ut", _line_of(path, "mag_field_ut"),
                   expect)  # fmt: skip
    assert "1 to 10000 µT" in msg or "write 1.0e+308" in msg, msg


@pytest.mark.parametrize("value", ["40", "48.5", "1", "10000"])
def test_map_mag_field_ut_in_range_is_kept(tmp_path, value):
    path = tmp_path / "map.yaml"
    path.write_text(TRUNK_MAP.read_text() + f"reader: {{mag_field_ut: {value}}}\n")
    assert load_sensor_map(path).reader["mag_field_ut"] == float(value)


@pytest.mark.parametrize(
    ("reader", "key", "expect"),
    [
        ("{rate_hz: .nan}", "reader.rate_hz", "nan is not a finite number"),
        (f"{{rate_hz: {BIG}}}", "reader.rate_hz", "is not a finite number"),
        ("{rate_hz: -100}", "reader.rate_hz", "is -100 Hz"),
        ("{rate_hz: fast}", "reader.rate_hz", "'fast' is not a number"),
        ("{skip_rows: -1}", "reader.skip_rows", "-1 is not a line count"),
        ("{header_rows: 3}", "reader.header_rows", "3 is not a line count"),
        (f"{{time: {{column: t, unit: ticks, tick_hz: {BIG}}}}}", "reader.time.tick_hz",
         "is not a finite number"),
        ("{mag: {columns: [a, b, c], unit: a.u., field_ut: -5}}", "reader.mag.field_ut",
         "is -5 µT"),
        ("{sensors: [{label: a, mag: {columns: [a, b, c], unit: a.u., field_ut: .inf}}]}",
         "reader.sensors[0].mag.field_ut", "inf is not a finite number"),
    ],
    ids=_short,
)  # fmt: skip
def test_map_numeric_reader_options_are_checked(tmp_path, reader, key, expect):
    path = tmp_path / "map.yaml"
    path.write_text(TRUNK_MAP.read_text() + f"reader: {reader}\n")
    _refused(load_sensor_map, path, key, _line_of(path, "reader:"), expect)


def test_map_mag_field_ut_through_the_cli_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    (tmp_path / "map.yaml").write_text("reader: {format: xsens, mag_field_ut: -50}\n")
    result = CliRunner().invoke(
        main, ["ingest", str(tmp_path / "in.txt"), "--map", str(tmp_path / "map.yaml"),
               "-o", str(tmp_path / "out.h5")]
    )  # fmt: skip
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "line 1, key reader.mag_field_ut: is -50 µT" in lines[0], lines
    assert not (tmp_path / "out.h5").exists()


# -- 3. thresholds -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "key", "expect"),
    [
        ("thresholds: {nonsense_deg: 3}\n", "thresholds.nonsense_deg",
         "unknown key — use one of varus_thrust_deg, out_of_plane_offset_deg"),
        ("thresholds: {varus_thrust: 3}\n", "thresholds.varus_thrust",
         "did you mean 'varus_thrust_deg'"),
        ("thresholds: {varus_thrust_deg: -3}\n", "thresholds.varus_thrust_deg",
         "is -3: a limit is a size in degrees"),
        ("thresholds: {out_of_plane_offset_deg: 500}\n", "thresholds.out_of_plane_offset_deg",
         "give 0 to 180"),
        (f"thresholds: {{varus_thrust_deg: {BIG}}}\n", "thresholds.varus_thrust_deg",
         "is not a finite number"),
        ("thresholds: {varus_thrust_deg: [3]}\n", "thresholds.varus_thrust_deg",
         "is not a number"),
        ("thresholds: {trunk_compensation_deg: 10}\n", "thresholds.trunk_compensation_deg",
         "expected a limit per trunk angle"),
        ("thresholds: {trunk_compensation_deg: {flexion: 10, lateral: 8}}\n",
         "thresholds.trunk_compensation_deg.lateral", "did you mean 'lateral_bending'"),
        ("thresholds: {trunk_compensation_deg: {flexion: -10}}\n",
         "thresholds.trunk_compensation_deg.flexion", "is -10"),
    ],
    ids=_short,
)  # fmt: skip
def test_thresholds_are_known_keys_and_magnitudes(tmp_path, text, key, expect):
    """'nonsense_deg: 3' and 'varus_thrust_deg: -3' were accepted (every stride flagged)."""
    path = _appended(tmp_path, text)
    _refused(load_protocol, path, key, _line_of(path, "thresholds:"), expect)


def test_thresholds_as_shipped_are_kept(tmp_path):
    path = _appended(
        tmp_path,
        "thresholds:\n  varus_thrust_deg: 3\n  trunk_compensation_deg: {flexion: 10.0}\n"
        "  cross_talk_reference_pct: {forearm: [-45.0, -70.0]}\n",
    )
    th = load_protocol(path).thresholds
    assert th == {"varus_thrust_deg": 3.0, "trunk_compensation_deg": {"flexion": 10.0},
                  "cross_talk_reference_pct": {"forearm": [-45.0, -70.0]}}  # fmt: skip


# -- 4. the protocol's name, title and texts -----------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "key", "expect"),
    [
        ("name: lumbar_seated", "name: ''", "name", "is empty"),
        ("name: lumbar_seated", "name: '   '", "name", "is empty"),
        ("name: lumbar_seated", 'name: "lumbar\\0seated"', "name", "control character '\\x00'"),
        ("name: lumbar_seated", 'name: "lumbar\\eseated"', "name", "control character '\\x1b'"),
        ("name: lumbar_seated", "name: " + "x" * 81, "name", "is 81 characters long, at most 80"),
        ("title: Lumbar spine", "title: " + "t" * 201 + " Lumbar spine", "title",
         "at most 200"),
        ("placement: \"lower back", "placement: \"\\0lower back", "segments.pelvis.placement",
         "control character '\\x00'"),
        ("instructions: \"sit", "instructions: \"\\x1bsit", "calibration[0].instructions",
         "control character '\\x1b'"),
        ("pose: seated or standing", "pose: " + "p " * 1001, "calibration[0].pose",
         "at most 2000"),
    ],
    ids=_short,
)  # fmt: skip
def test_protocol_texts_are_printable_and_bounded(tmp_path, old, new, key, expect):
    """An empty name gave the title 'motionlab report · ', a NUL or ESC leaked matplotlib warnings
    later."""
    path = _protocol(tmp_path, old, new)
    _refused(load_protocol, path, key, _line_of(path, new.strip()[:12]), expect)


def test_a_title_with_an_escape_is_refused(tmp_path):
    path = _protocol(tmp_path, "title: Lumbar spine kinematics", 'title: "\\e[31mLumbar spine"')
    path.write_text(
        path.read_text()
        .replace('Lumbar spine" from', "Lumbar spine from", 1)
        .replace("(seated or standing)\npurpose", '(seated or standing)"\npurpose')
    )
    _refused(load_protocol, path, "title", 5, "control character '\\x1b'", "one line")


def test_purpose_and_source_are_bounded(tmp_path):
    for key in ("purpose", "source"):
        path = _protocol(tmp_path, f"{key}: >\n", f"{key}: >\n  {'w ' * 1001}\n")
        _refused(load_protocol, path, key, _line_of(path, f"{key}:"), "at most 2000")


def test_a_name_of_100000_characters_is_refused_at_once(tmp_path):
    """It made 'motionlab run' hang for minutes in the report's text wrapping."""
    path = _protocol(tmp_path, "name: lumbar_seated", "name: " + "n" * 100_000)
    (tmp_path / "in.txt").write_bytes(XSENS.read_bytes())
    start = time.monotonic()
    result = CliRunner().invoke(
        main, ["run", str(tmp_path / "in.txt"), "--protocol", str(path),
               "-o", str(tmp_path / "res"), "--quiet"]
    )  # fmt: skip
    assert time.monotonic() - start < 30
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "line 4, key name: is 100000 characters long" in lines[0], lines
    assert not (tmp_path / "res").exists()


def test_a_segment_name_longer_than_a_file_name_is_refused(tmp_path):
    path = _protocol(tmp_path, "  chair:\n", "  " + "c" * 101 + ":\n")
    _refused(load_protocol, path, "segments." + "c" * 101, _line_of(path, "c" * 101),
             "is 101 characters long, at most 100")  # fmt: skip


# -- 5. the sensor map's names -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "key", "expect"),
    [
        ("  Back: {segment: thorax}", '  "Ba\\eck": {segment: thorax}', "sensors.Ba\\x1bck",
         "key 'Ba\\x1bck' holds the control character '\\x1b'"),
        ("  Back: {segment: thorax}", "  " + "B" * 101 + ": {segment: thorax}",
         "sensors." + "B" * 79 + "…", "is 101 characters long, at most 100"),
        ("  Back: {segment: thorax}", "  Back: {segment: " + "t" * 101 + "}",
         "sensors.Back.segment", "is 101 characters long, at most 100"),
        ("  Back: {segment: thorax}", '  Back: {segment: "tho\\x85rax"}', "sensors.Back.segment",
         "control character '\\x85'"),
        ("  Back: {segment: thorax}", "  Back: {segment: thorax, label: " + "l" * 101 + "}",
         "sensors.Back.label", "is 101 characters long, at most 100"),
        ("  Back: {segment: thorax}", '  Back: {segment: thorax, side: "r\\0"}',
         "sensors.Back.side", "is not left or right"),
    ],
    ids=_short,
)  # fmt: skip
def test_map_names_are_printable_and_bounded(tmp_path, old, new, key, expect):
    path = _edited(tmp_path, TRUNK_MAP, old, new, "map.yaml")
    _refused(load_sensor_map, path, key, _line_of(path, new.strip()[:6]), expect)


def test_map_subject_id_shown_in_the_report_is_bounded(tmp_path):
    path = tmp_path / "map.yaml"
    path.write_text(TRUNK_MAP.read_text() + "subject: {id: " + "P" * 101 + "}\n")
    _refused(load_sensor_map, path, "subject.id", _line_of(path, "subject:"), "at most 100")
    path.write_text(TRUNK_MAP.read_text() + 'subject: {id: "P\\e017"}\n')
    _refused(load_sensor_map, path, "subject.id", _line_of(path, "subject:"), "'\\x1b'")
