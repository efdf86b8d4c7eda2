"""A session file never holds results that contradict each other, and no process loses another's
work (issue 26): stale results refused, one writer at a time, inputs that are not regular files
refused at once, errors before warnings."""

from __future__ import annotations

import os
import shlex
import shutil
import socket
import sys
import time
from pathlib import Path

import h5py
import pytest
from click.testing import CliRunner

sys.path.insert(0, str(Path(__file__).resolve().parent))
from integrity_helpers import fork_cli, make_sessions, one_error_line, sha, wait  # noqa: E402

from motionlab.cli import main  # noqa: E402
from motionlab.session import load_session, save_session  # noqa: E402


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    return make_sessions(tmp_path_factory.mktemp("sessions"))


@pytest.fixture
def analysed(sessions, tmp_path):
    path = tmp_path / "session.h5"
    shutil.copy(sessions[1], path)
    return path


def cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def stale(path):
    ses = load_session(path)
    return ses.lineage.stale(ses.results)


# ------------------------------------------------------------------------- stale results


def test_replacing_the_fusion_makes_everything_after_it_stale(analysed, tmp_path):
    assert stale(analysed) == {}
    assert cli("fuse", analysed, "--filter", "madgwick", "--force").exit_code == 0
    assert list(stale(analysed)) == ["calibration", "angles", "metrics"]
    info = cli("info", analysed)
    assert "stale: calibration (computed before fuse was redone)" in info.output
    # runnable as printed: the session file and the protocol named (they said "motionlab
    # calibrate --force", which click refused for its missing --protocol)
    todo = next(x for x in info.output.splitlines() if "to bring them up to date: " in x)
    commands = todo.split("to bring them up to date: ")[1].split(", then ")
    calibrate = f"motionlab calibrate {shlex.quote(str(analysed))} --protocol walk --force"
    assert commands[0] == calibrate and len(commands) == 3, commands
    report = cli("report", analysed, "-o", tmp_path / "r.pdf")
    assert report.exit_code == 2 and one_error_line(report.output), report.output
    assert "calibration result is stale" in report.output and calibrate in report.output
    assert not (tmp_path / "r.pdf").exists()
    angles = cli("angles", analysed, "--force")  # would use the old calibration: refused
    assert angles.exit_code == 2 and one_error_line(angles.output), angles.output
    assert f"re-run {calibrate} first" in angles.output
    for command in commands:
        res = cli(*shlex.split(command)[1:])
        assert res.exit_code == 0, res.output
    assert stale(analysed) == {}


def test_a_clock_sync_after_fusion_makes_the_fusion_stale(analysed):
    assert cli("sync", analysed, "--protocol", "walk").exit_code == 0
    assert list(stale(analysed)) == ["fusion", "calibration", "angles", "metrics"]
    res = cli("calibrate", analysed, "--protocol", "walk", "--force")
    assert res.exit_code == 2 and f"re-run motionlab fuse {analysed} --force first" in res.output
    labels = list(load_session(analysed).sensors)
    part = cli("fuse", analysed, "--force", "--sensor", labels[0])  # the others stay stale
    assert part.exit_code == 2 and "stale too" in part.output, part.output
    assert cli("fuse", analysed, "--force").exit_code == 0
    assert "fusion" not in stale(analysed)


def test_an_edited_protocol_file_refuses_the_stages_that_read_it(sessions, tmp_path):
    from motionlab.protocol import PACKAGED

    protocol = tmp_path / "walk.yaml"
    shutil.copy(PACKAGED / "walk.yaml", protocol)
    path = tmp_path / "s.h5"
    shutil.copy(sessions[1], path)
    assert cli("calibrate", path, "--protocol", protocol, "--force").exit_code == 0
    assert cli("angles", path, "--force").exit_code == 0
    protocol.write_text(protocol.read_text() + "\n# edited\n")
    res = cli("metrics", path, "--force")
    assert res.exit_code == 2 and "protocol file has changed" in res.output, res.output


def test_a_schema_2_file_loads_with_its_results_taken_as_consistent(analysed):
    with h5py.File(analysed, "r+") as f:
        del f.attrs["lineage"]
        f.attrs["schema_version"] = 2
    ses = load_session(analysed)
    assert ses.schema_version == 2 and ses.lineage.stale(ses.results) == {}
    assert all(s.assumed for s in ses.lineage.stamps.values())
    assert cli("fuse", analysed, "--force").exit_code == 0  # written back as schema 3
    assert "calibration" in stale(analysed)


# ----------------------------------------------------------------------- one writer at a time


def test_two_writers_on_one_session_both_keep_their_work(analysed, tmp_path):
    """The issue's case: a long stage command and a second one 0.3 s later. Before the lock
    both said they wrote and the file held the last writer's copy only."""
    before = len(load_session(analysed).provenance)
    first = fork_cli(["metrics", analysed, "--force"], tmp_path / "a.log")
    time.sleep(0.3)
    second = fork_cli(["angles", analysed, "--force"], tmp_path / "b.log")
    codes = wait(first), wait(second)
    assert codes == (0, 0), [(tmp_path / n).read_text() for n in ("a.log", "b.log")]
    ses = load_session(analysed)
    stages = [p["parameters"].get("stage") for p in ses.provenance[before:]]
    assert stages == ["metrics", "angles"]  # neither lost; the second ran on the first's file
    assert list(ses.lineage.stale(ses.results)) == ["metrics"]  # and says what it made stale


def test_a_second_writer_waits_then_names_the_first(analysed, tmp_path):
    from motionlab.lock import session_lock

    read, write = os.pipe()
    holder = os.fork()
    if holder == 0:  # holds the lock for 5 s
        os.close(read)
        with session_lock(analysed):
            os.write(write, b"x")
            time.sleep(5)
        os._exit(0)
    os.close(write)
    os.read(read, 1)
    old = sha(analysed)
    t0 = time.monotonic()
    child = fork_cli(["metrics", analysed, "--force"], tmp_path / "m.log",
                     env={"MOTIONLAB_LOCK_WAIT": "0.5"})  # fmt: skip
    code = wait(child)
    waited = time.monotonic() - t0
    out = (tmp_path / "m.log").read_text()
    os.waitpid(holder, 0)
    assert code == 2 and one_error_line(out), out
    assert f"pid {holder}" in out and "being written by another motionlab" in out
    assert 0.5 <= waited < 4.5
    assert sha(analysed) == old


def test_the_lock_of_a_killed_writer_is_free_and_its_temporary_file_swept(analysed, tmp_path):
    from motionlab.lock import session_lock

    child = os.fork()
    if child == 0:
        with session_lock(analysed):
            (tmp_path / ".session.h5.dead.tmp").write_bytes(b"half")
            time.sleep(30)
        os._exit(0)
    time.sleep(0.5)
    os.kill(child, 9)
    os.waitpid(child, 0)
    res = cli("angles", analysed, "--force")
    assert res.exit_code == 0, res.output
    assert not list(tmp_path.glob(".*.tmp")) and not list(tmp_path.glob(".*.lock"))


# ----------------------------------------------------- inputs that are not regular files


def _special(kind: str, folder: Path) -> Path:
    path = folder / kind
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
    else:
        return Path("/dev/null")
    return path


@pytest.mark.parametrize("kind", ["fifo", "socket", "device"])
@pytest.mark.parametrize(
    "args",
    [
        ["ingest", "{x}", "-o", "{t}/s.h5"],
        ["info", "{x}"],
        ["fuse", "{x}"],
        ["calibrate", "{s}", "--protocol", "{x}"],
        ["ingest", "{r}", "--map", "{x}", "-o", "{t}/s.h5"],
        ["run", "--protocol", "walk", "{x}", "-o", "{t}/out"],
        ["batch", "{x}", "-o", "{t}/out"],
        ["validate", "{s}", "--reference", "{x}"],
        ["validate", "{s}", "--markers", "{x}"],
    ],
    ids=["ingest", "info", "fuse", "protocol", "map", "run", "batch", "reference", "markers"],
)
def test_a_special_file_is_refused_at_once(sessions, tmp_path, kind, args):
    x = _special(kind, tmp_path)
    fill = {"{x}": str(x), "{t}": str(tmp_path), "{s}": str(sessions[1]), "{r}": str(sessions[0])}
    argv = [a if a not in fill else fill[a] for a in args]
    argv = [a.replace("{t}", str(tmp_path)) for a in argv]
    before = sha(sessions[1])
    child = fork_cli(argv, tmp_path / "out.log")
    code = wait(child, timeout=20)  # today: ingest of a FIFO waits for a writer forever
    out = (tmp_path / "out.log").read_text()
    assert code == 2 and one_error_line(out), (code, out)
    assert "not a regular file" in out, out
    assert sha(sessions[1]) == before


def test_fuse_says_the_real_error_before_the_sync_warning(sessions, tmp_path):
    ses = load_session(sessions[0])
    label = next(iter(ses.sensors))
    ses.sensors[label].acc[:] = float("nan")  # damaged: no finite accelerometer at all
    path = tmp_path / "broken.h5"
    save_session(ses, path)
    res = CliRunner().invoke(main, ["fuse", str(path)])
    assert res.exit_code == 2, res.output
    first = res.output.strip().splitlines()[0]
    assert first.startswith("error:") and "warning" not in res.output, res.output


def test_stamps_follow_what_each_stage_read():
    import json

    import numpy as np

    from motionlab.lineage import Lineage
    from motionlab.results import AngleTable, ClockSync, FusionEntry, Results, SegmentCalibration

    res, lin = Results(), Lineage()
    res.fusion = {"a": FusionEntry("x", np.zeros((2, 4)))}
    lin.record(res, "fusion")
    res.calibration = SegmentCalibration("p")
    lin.record(res, "calibration")
    res.angles = AngleTable.from_columns({"time_s": np.arange(2.0)})
    lin.record(res, "angles", inputs=("fusion",))  # without the calibration
    assert lin.stale(res) == {}
    lin.record(res, "calibration")  # redone: the uncalibrated angles did not read it
    assert lin.stale(res) == {}
    lin.record(res, "fusion")
    assert lin.stale(res) == {"calibration": "computed before fuse was redone",
                              "angles": "computed before fuse was redone"}  # fmt: skip
    res.clock_sync = ClockSync()
    lin.record(res, "clock_sync")  # a first sync after the fusion
    assert lin.stale(res)["fusion"] == "computed before sync was run"
    assert Lineage.from_tree(json.loads(json.dumps(lin.to_tree()))) == lin
    generations = {k: s.generation for k, s in lin.stamps.items()}  # one counter, never reused
    assert generations == {"fusion": 5, "calibration": 4, "angles": 3, "clock_sync": 6}
