"""Study manifest: paths, globs, inheritance, and one clear error per broken manifest."""

from pathlib import Path

import pytest

from motionlab.batch import load_manifest
from motionlab.errors import InputError
from motionlab.protocol import PACKAGED


def _files(root: Path, *names: str) -> None:
    for name in names:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text("0 1\n")


def test_valid_manifest_resolves_paths_globs_and_maps(tmp_path):
    _files(tmp_path, "raw/a/shank.txt", "raw/a/thigh.txt", "raw/b/s.h5", "m.yaml", "m2.yaml",
           "ref.c3d")  # fmt: skip
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\n"
        "map: m.yaml\n"
        "sessions:\n"
        "  - subject: S01\n"
        "    visit: 1\n"
        "    files: raw/a/*.txt\n"
        "  - {subject: S01, visit: week 6, files: [raw/b/s.h5], reference: ref.c3d, map: m2.yaml}\n"
    )
    m = load_manifest(tmp_path / "study.yaml")
    assert m.protocol == PACKAGED / "knee.yaml"
    a, b = m.sessions
    assert (a.subject, a.visit, a.line) == ("S01", "1", 4)
    assert [f.name for f in a.files] == ["shank.txt", "thigh.txt"]  # sorted glob
    assert a.map == tmp_path / "m.yaml" and a.reference is None and not a.problem
    assert b.folder == Path("S01") / "week 6"
    assert b.map == tmp_path / "m2.yaml" and b.reference == tmp_path / "ref.c3d"


def test_the_studys_map_is_for_raw_recordings_not_session_files(tmp_path):
    """README's manifest gives a top-level map and a session made by ``motionlab simulate``:
    every such session failed ("map applies to raw recordings; a session file already names
    its sensors"). The study's map now goes to the raw recordings only."""
    from motionlab.session import Session, save_session

    _files(tmp_path, "raw/a/shank.txt", "m.yaml")
    save_session(Session(sensors={}), tmp_path / "sim.h5")
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nmap: m.yaml\nsessions:\n"
        "  - {subject: S01, visit: v1, files: raw/a/*.txt}\n"
        "  - {subject: S02, visit: v1, files: sim.h5}\n"
    )
    raw, sim = load_manifest(tmp_path / "study.yaml").sessions
    assert raw.map == tmp_path / "m.yaml" and sim.map is None and not sim.problem


def test_a_references_marker_map_is_a_key_for_the_study_or_a_session(tmp_path):
    """``motionlab run --markers`` had no manifest key: ``markers:`` was an unknown key, so a
    study could not validate against a reference whose markers are not named by the default."""
    _files(tmp_path, "x.h5", "mk.yaml", "mk2.yaml", "ref.c3d")
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nmarkers: mk.yaml\nsessions:\n"
        "  - {subject: A, visit: v1, files: x.h5, reference: ref.c3d}\n"
        "  - {subject: B, visit: v1, files: x.h5, reference: ref.c3d, markers: mk2.yaml}\n"
        "  - {subject: C, visit: v1, files: x.h5, reference: ref.c3d, markers: gone.yaml}\n"
    )
    m = load_manifest(tmp_path / "study.yaml")
    a, b, c = m.sessions
    assert m.markers == a.markers == tmp_path / "mk.yaml" and b.markers == tmp_path / "mk2.yaml"
    assert not a.problem and not b.problem
    assert c.problem.startswith("study.yaml line 6, key sessions[2].markers: no such markers")
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nmarkers: gone.yaml\nsessions: [{subject: A, visit: v1, files: x.h5}]\n"
    )
    with pytest.raises(InputError, match="line 2, key markers: no such file 'gone.yaml'"):
        load_manifest(tmp_path / "study.yaml")


def test_run_options_as_keys(tmp_path):
    _files(tmp_path, "x.h5", "cal/ABC.yaml")
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nseed: 2\nclock_sync: false\ncalibration: cal\nsessions:\n"
        "  - {subject: A, visit: v1, files: x.h5, magnetometer: true, filter: madgwick}\n"
        "  - {subject: B, visit: v1, files: x.h5, calibration: nocal, orientation: vendor}\n"
    )
    m = load_manifest(tmp_path / "study.yaml")
    assert m.options == {"seed": 2, "clock_sync": False, "calibration_dir": tmp_path / "cal"}
    a, b = m.sessions
    assert a.options == {"magnetometer": True, "estimator": "madgwick"} and not a.problem
    assert b.problem.startswith("study.yaml line 7, key sessions[1].calibration: no such")
    assert b.options["orientation"] == "vendor"


def test_missing_files_make_a_session_problem_not_an_error(tmp_path):
    _files(tmp_path, "x.h5")
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nsessions:\n"
        "  - {subject: A, visit: v1, files: x.h5}\n"
        "  - {subject: B, visit: v1, files: nothere/*.txt}\n"
        "  - subject: C\n    visit: v1\n    files: x.h5\n    reference: gone.c3d\n"
    )
    a, b, c = load_manifest(tmp_path / "study.yaml").sessions
    assert a.problem == ""
    assert b.problem.startswith("study.yaml line 4, key sessions[1].files: no file matches")
    assert c.problem.startswith("study.yaml line 8, key sessions[2].reference: no such reference")


BROKEN = [
    ("protocol: knee\nsessons: []\n", "line 2, key sessons", "unknown key"),
    ("protocol: knee\n", "key sessions", "missing"),
    ("protocol: knee\nsessions: []\n", "line 2, key sessions", "needs a list"),
    ("protocol: nosuch\nsessions: [{subject: A, visit: v, files: x}]\n", "line 1, key protocol",
     "'nosuch': no such protocol"),
    ("protocol: knee\nmap: gone.yaml\nsessions: [{subject: A, visit: v, files: x}]\n",
     "line 2, key map", "no such file"),
    ("protocol: knee\nsessions:\n  - {subject: A/B, visit: v, files: x}\n",
     "line 3, key sessions[0].subject", "cannot name a folder"),
    ("protocol: knee\nsessions:\n  - {subject: ..., visit: v, files: x}\n",
     "sessions[0].subject", "cannot name a folder"),
    ("protocol: knee\nsessions:\n  - {visit: v, files: x}\n", "sessions[0].subject", "expected"),
    ("protocol: knee\nsessions:\n  - {subject: A, visit: v, files: x}\n"
     "  - {subject: A, visit: v, files: y}\n", "line 4, key sessions[1]", "first is on line 3"),
    ("protocol: knee\nsessions:\n  - {subject: A, visit: v, files: m.yaml}\n"
     "  - {subject: A, visit: w, files: m.yaml}\n", "line 4, key sessions[1]",
     "repeats the files and settings of sessions[0] (line 3)"),
    ("protocol: knee\nsessions:\n  - {subject: A, visit: v, files: []}\n",
     "line 3, key sessions[0].files", "needs a file"),
    ("protocol: knee\nsessions:\n  - subject: A\n    visit: v\n    fils: x\n",
     "line 5, key sessions[0].fils", "unknown key"),
    ("protocol: knee\nsessions:\n  - just a string\n", "key sessions[0]", "not a mapping"),
    ("protocol: knee\nsessions:\n  - {subject: A, visit: v\n", "line 4", "not valid YAML"),
    ("- a list\n", "key (top level)", "not a mapping"),
    ("protocol: knee\nseed: x\nsessions: [{subject: A, visit: v, files: x}]\n",
     "line 2, key seed", "expected an integer"),
    ("protocol: knee\nsessions:\n  - {subject: A, visit: v, files: x,\n     angle_lowpass: -3}\n",
     "line 4, key sessions[0].angle_lowpass", "is -3, expected 0 or more"),
    ("protocol: knee\nsessions:\n  - {subject: A, visit: v, files: x,\n     magnetometer: 1}\n",
     "line 4, key sessions[0].magnetometer", "expected true or false"),
    ("protocol: knee\nfilter: nope\nsessions: [{subject: A, visit: v, files: x}]\n",
     "line 2, key filter", "unknown estimator"),
    ("protocol: knee\norientation: own\nsessions: [{subject: A, visit: v, files: x}]\n",
     "line 2, key orientation", "is 'own'"),
    ("protocol: knee\ncalibration: gone/\nsessions: [{subject: A, visit: v, files: x}]\n",
     "line 2, key calibration", "no such calibration folder"),
]  # fmt: skip


@pytest.mark.parametrize(("text", "where", "message"), BROKEN)
def test_broken_manifest_names_key_and_line(tmp_path, text, where, message):
    path = tmp_path / "study.yaml"
    path.write_text(text)
    (tmp_path / "m.yaml").write_text("sensors: {}\n")
    with pytest.raises(InputError) as info:
        load_manifest(path)
    err = info.value
    assert message in err.line()
    if where:
        assert err.path.name == "study.yaml" and where in err.where
    assert "\n" not in err.line() and err.remedy


def test_manifest_file_missing(tmp_path):
    with pytest.raises(InputError, match="no such manifest"):
        load_manifest(tmp_path / "nope.yaml")


def test_an_x_imu3_export_folder_is_a_session_input(tmp_path):
    """``files: trial/imu`` (an x-IMU3 export, as ``motionlab run trial/imu`` reads it) was
    'no such file' for a folder that exists; its files' contents key the session."""
    from motionlab.batch.state import FileHashes, session_key
    from tests import ximu3_export as xe

    imu = xe.write(tmp_path / "trial", xe.export_files())
    (tmp_path / "study.yaml").write_text(
        "protocol: lumbar_seated\nsessions:\n"
        "  - {subject: A, visit: v1, files: trial/imu}\n"
        "  - {subject: B, visit: v1, files: 'trial/imu/*'}\n"
        "  - {subject: C, visit: v1, files: trial}\n"
    )
    a, b, c = load_manifest(tmp_path / "study.yaml").sessions
    assert list(a.files) == [imu] and not a.problem
    assert [f.name for f in b.files] == sorted(p.name for p in imu.iterdir()) and not b.problem
    assert c.problem.endswith("no such file 'trial' — fix the path; the other sessions still run")
    key = session_key(a.files, PACKAGED / "lumbar_seated.yaml", None, None, FileHashes())
    inertial = next(imu.glob("Back*/Inertial.csv"))
    inertial.write_bytes(inertial.read_bytes().replace(b"0.", b"1.", 1))
    assert key != session_key(a.files, PACKAGED / "lumbar_seated.yaml", None, None, FileHashes())


def test_a_study_of_thousands_of_sessions_loads_and_an_oversized_file_is_refused(tmp_path):
    """A manifest of 8000 sessions was refused as "more than 50000 values" (the bound that stops
    a billion laughs in a protocol), after seconds of pure-Python parsing; a 10-MB one took 41 s
    to say so. Now a study has room for a million values, read by libyaml, and a file over
    4 MiB is refused before it is parsed; aliases that expand without end still are."""
    from motionlab.yamlsafe import MAX_BYTES

    _files(tmp_path, "x.h5")
    rows = "".join(
        f"  - {{subject: S{i}, visit: v1, files: x.h5, seed: {i}}}\n" for i in range(8000)
    )
    (tmp_path / "study.yaml").write_text("protocol: knee\nsessions:\n" + rows)
    sessions = load_manifest(tmp_path / "study.yaml").sessions
    assert len(sessions) == 8000 and not any(s.problem for s in sessions)
    (tmp_path / "big.yaml").write_text("protocol: knee\n#" + "x" * MAX_BYTES + "\n")
    with pytest.raises(InputError, match="too large for a manifest file"):
        load_manifest(tmp_path / "big.yaml")
    laughs = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcde", "bcdef", strict=True)
    )  # 10^6 values once expanded, and more
    (tmp_path / "laughs.yaml").write_text("protocol: knee\n" + laughs.replace("a: &a", "x0: &a"))
    with pytest.raises(InputError, match="holds more than 1000000 values"):
        load_manifest(tmp_path / "laughs.yaml")


def test_one_recording_twice_is_refused_unless_its_settings_differ(tmp_path):
    """The real trunk trial Aag/pivot_hs listed as two visits ran twice and counted twice in the
    study's medians; the same recording with another option (a second estimator, say) is a
    session of its own, and two missing recordings are two session problems."""
    _files(tmp_path, "x.h5")
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nsessions:\n"
        "  - {subject: A, visit: v1, files: x.h5}\n"
        "  - {subject: A, visit: v2, files: x.h5, filter: madgwick}\n"
        "  - {subject: B, visit: v1, files: gone.h5}\n"
        "  - {subject: B, visit: v2, files: gone.h5}\n"
    )
    a, b, c, d = load_manifest(tmp_path / "study.yaml").sessions
    assert not a.problem and not b.problem and c.problem and d.problem
    (tmp_path / "study.yaml").write_text(
        "protocol: knee\nsessions:\n"
        "  - {subject: A, visit: v1, files: x.h5}\n"
        "  - {subject: B, visit: v1, files: [x.h5]}\n"
    )
    with pytest.raises(InputError, match="line 4, key sessions.1.: repeats the files and "
                       "settings of sessions.0. .line 3."):  # fmt: skip
        load_manifest(tmp_path / "study.yaml")
