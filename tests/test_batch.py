"""Batch runs on the local process pool, with a fast stand-in pipeline (tests/batch_fakes.py)."""

import csv
import dataclasses
import inspect
import json
import os
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from batch_fakes import fake_pipeline, good_sessions, make_study
from click.testing import CliRunner

from motionlab.batch import load_manifest, run_study
from motionlab.batch.state import CLAIM, STAMP, TABLES, FileHashes, session_key
from motionlab.cli import main
from motionlab.errors import InputError


def _run(manifest: Path, out: Path, **kw):
    return run_study(load_manifest(manifest), out, pipeline=fake_pipeline, **kw)


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _leftovers(out: Path) -> list[Path]:
    return [p for p in out.rglob("*") if p.name.endswith(".tmp") or p.name == CLAIM]


def test_study_runs_isolates_failures_and_writes_outputs(tmp_path):
    sessions = good_sessions() | {
        ("S9", "v1"): "corrupt",
        ("S9", "v2"): "bug",
    }
    result = _run(make_study(tmp_path, sessions), tmp_path / "out", workers=2)
    status = {(o.subject, o.visit): o.status for o in result.outcomes}
    assert [status[k] for k in good_sessions()] == ["done"] * 6
    assert status["S9", "v1"] == status["S9", "v2"] == "failed" and not result.ok
    rows = _rows(tmp_path / "out" / "study_metrics.csv")
    assert len(rows) == 6 * 6  # six sessions of six joint metrics, in manifest order
    assert [(r["subject"], r["visit"]) for r in rows[::6]] == list(good_sessions())
    rom = {(r["subject"], r["visit"]): float(r["value"]) for r in rows
           if r["metric"] == "rom_deg" and r["angle"] == "flexion"}  # fmt: skip
    assert rom["S3", "v2"] == 20 + 30 + 5 and rom["S1", "v1"] == 30
    failures = _rows(tmp_path / "out" / "study_failures.csv")
    assert [(f["subject"], f["visit"], f["kind"]) for f in failures] == [
        ("S9", "v1", "input"),
        ("S9", "v2", "internal"),
    ]
    assert failures[0]["error"] == "rec.txt line 3: 7 columns, expected 10 — is the delimiter ';'?"
    assert failures[1]["error"] == "internal error (ValueError: something went wrong)"
    assert (tmp_path / "out" / "study_report.pdf").read_bytes()[:5] == b"%PDF-"
    assert (tmp_path / "out" / "S1" / "v1" / "report.txt").is_file()
    assert not _leftovers(tmp_path / "out")


def test_rerun_skips_finished_sessions_and_reruns_changed_ones(tmp_path):
    manifest = make_study(tmp_path, good_sessions(2))
    out = tmp_path / "out"
    _run(manifest, out, workers=1)
    first = (out / "study_metrics.csv").read_bytes()
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob(STAMP)}
    again = _run(manifest, out, workers=1)
    assert [o.status for o in again.outcomes] == ["skipped"] * 4
    assert {p: p.stat().st_mtime_ns for p in out.rglob(STAMP)} == stamps
    assert (out / "study_metrics.csv").read_bytes() == first
    (tmp_path / "raw" / "S2" / "v1" / "rec.txt").write_text("0 99 1")
    changed = _run(manifest, out, workers=1)
    assert [o.status for o in changed.outcomes] == ["skipped", "skipped", "done", "skipped"]
    after = (out / "study_metrics.csv").read_bytes()
    assert after != first
    # every session again, on two workers: the same bytes as one worker and skipped sessions
    assert _run(manifest, out, workers=2, force=True).count("done") == 4
    assert (out / "study_metrics.csv").read_bytes() == after


def test_session_key_follows_contents_names_protocol_and_version(tmp_path):
    a, b, p = tmp_path / "a.txt", tmp_path / "b.txt", tmp_path / "p.yaml"
    a.write_text("1"), b.write_text("1"), p.write_text("name: x")
    key = session_key([a], p, None, None, FileHashes())
    assert key == session_key([a], p, None, None, FileHashes())
    assert key != session_key([b], p, None, None, FileHashes())  # same bytes, other name
    assert key != session_key([a], p, None, None, FileHashes(), version="9.9")
    assert key != session_key([a], p, None, a, FileHashes())
    assert key != session_key([a], p, None, None, FileHashes(), markers=b)  # a marker map
    p.write_text("name: y")
    assert key != session_key([a], p, None, None, FileHashes())


def test_killed_workers_are_retried_and_bystanders_not_charged(tmp_path):
    sessions = good_sessions(2) | {
        ("S8", "v1"): "crash sleep 0.5 0 40 2",  # dies once, then succeeds
        ("S8", "v2"): "crash-always 0 1",  # dies every time
    }
    sessions[("S1", "v1")] = "sleep 3 0 30 5 1"  # running while the other worker dies
    result = _run(make_study(tmp_path, sessions), tmp_path / "out", workers=2, retry=1)
    got = {(o.subject, o.visit): (o.status, o.kind, o.attempts) for o in result.outcomes}
    assert got["S8", "v1"] == ("done", "", 2)
    assert got["S8", "v2"] == ("failed", "worker_died", 2)
    assert got["S1", "v1"] == ("done", "", 1)  # stopped by the broken pool: not its fault
    assert len((tmp_path / "raw" / "S1" / "v1" / "rec.runs").read_text().split()) >= 2
    assert result.count("done") == 5
    assert len(_rows(tmp_path / "out" / "study_metrics.csv")) == 5 * 6
    assert not _leftovers(tmp_path / "out")


def test_outdir_of_other_files_needs_force(tmp_path):
    manifest = make_study(tmp_path, good_sessions(1, ("v1",)))
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "thesis.docx").write_text("keep me")
    with pytest.raises(InputError, match="not written by motionlab batch"):
        _run(manifest, tmp_path / "busy")
    assert _run(manifest, tmp_path / "busy", force=True).ok
    assert (tmp_path / "busy" / "thesis.docx").read_text() == "keep me"


def test_another_manifests_study_folder_needs_force(tmp_path):
    """The real walk study run into the trunk study's folder replaced its study_metrics.csv,
    study_failures.csv and study_report.pdf without a word; now that needs force, as a folder
    of other files does, and the folder then belongs to the new manifest."""
    first = make_study(tmp_path / "a", good_sessions(1, ("v1",)))
    second = make_study(tmp_path / "b", good_sessions(2, ("v1",)))
    out = tmp_path / "out"
    assert _run(first, out, workers=1).ok
    tables = (out / "study_metrics.csv").read_bytes()
    with pytest.raises(InputError, match="out argument outdir: holds the study of another "
                       "manifest .*a.study.yaml"):  # fmt: skip
        _run(second, out, workers=1)
    assert (out / "study_metrics.csv").read_bytes() == tables
    assert _run(first, out, workers=1).count("skipped") == 1  # its own manifest: no force
    assert _run(second, out, workers=1, force=True).ok
    assert len(_rows(out / "study_metrics.csv")) == 2 * 6
    assert _run(second, out, workers=1).count("skipped") == 2


def test_a_study_folder_inside_an_input_folder_is_refused_before_anything_is_written(tmp_path):
    """``batch study.yaml -o trial/imu/out`` (a real trunk trial's x-IMU3 export) wrote the
    study folder and its tables into the recording, each session failing on it (exit 3)."""
    from tests import ximu3_export as xe

    imu = xe.write(tmp_path / "trial", xe.export_files())
    before = sorted(p.relative_to(imu) for p in imu.rglob("*"))
    (tmp_path / "study.yaml").write_text(
        "protocol: lumbar_seated\nsessions:\n  - {subject: A, visit: v1, files: trial/imu}\n"
    )
    device = next(p for p in imu.iterdir() if p.is_dir())
    for out in (imu / "out", device / "out"):
        res = CliRunner().invoke(main, ["batch", str(tmp_path / "study.yaml"), "-o", str(out)])
        assert res.exit_code == 2, res.output
        assert "the output folder is inside the input folder imu" in res.output
        assert len(res.output.strip().splitlines()) == 1
    assert sorted(p.relative_to(imu) for p in imu.rglob("*")) == before


def test_dask_not_installed_is_one_line_before_any_folder(tmp_path, monkeypatch):
    """``--scheduler`` without Dask printed a '0/1' progress bar above the one-line error and
    left the study folder made, holding only its marker."""
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed: ImportError
    monkeypatch.setattr("motionlab.cli.batch.run_study", partial(run_study, pipeline=fake_pipeline))
    manifest = make_study(tmp_path, good_sessions(1, ("v1",)))
    res = CliRunner().invoke(main, ["batch", str(manifest), "-o", str(tmp_path / "out"),
                                    "--scheduler", "tcp://127.0.0.1:8786"])  # fmt: skip
    assert res.exit_code == 2
    assert (
        res.output == "error: --scheduler: Dask is not installed — pip install 'motionlab[dask]'\n"
    )
    assert not (tmp_path / "out").exists()


def test_the_walks_gait_numbers_and_their_withheld_cells_reach_the_study(tmp_path):
    """The real 16-IMU walk study (with and without its pelvis sensor) had no cadence, stride
    time or step-time asymmetry in any study table: study_metrics.csv holds joint metrics only.
    study_gait.csv now gathers each walk's gait summary, a withheld number an empty cell with
    its note; a session whose walk is gone (re-run as no walk) leaves it, and a stamp from
    before the gait table is not current."""
    sessions = {("S1", "v1"): "walk 112 0 30 2", ("S1", "v2"): "0 40 2",
                ("S2", "v1"): "walk 98.5 0 35 1"}  # fmt: skip
    manifest = make_study(tmp_path, sessions)
    out = tmp_path / "out"
    assert _run(manifest, out, workers=1).ok
    rows = _rows(out / "study_gait.csv")
    got = [(r["subject"], r["visit"], r["parameter"], r["mean"], r["note"]) for r in rows]
    clocks = "not given: the two legs' sensor clocks are not linked"
    assert got == [
        ("S1", "v1", "cadence_steps_per_min", "112.0000", ""),
        ("S1", "v1", "step_time_asymmetry_pct", "", clocks),
        ("S2", "v1", "cadence_steps_per_min", "98.5000", ""),
        ("S2", "v1", "step_time_asymmetry_pct", "", clocks),
    ]
    assert _run(manifest, out, workers=1).count("skipped") == 3
    (tmp_path / "raw" / "S2" / "v1" / "rec.txt").write_text("0 35 1")  # no walk now
    assert _run(manifest, out, workers=1).count("done") == 1
    assert [r["subject"] for r in _rows(out / "study_gait.csv")] == ["S1", "S1"]
    stamp = out / "S1" / "v1" / STAMP
    doc = json.loads(stamp.read_text())
    del doc["gait_sha256"], doc["tables"]  # as written before the gait table
    stamp.write_text(json.dumps(doc))
    assert _run(manifest, out, workers=1).count("done") == 1
    assert len(_rows(out / "study_gait.csv")) == 2


def test_a_session_of_older_tables_is_run_again(tmp_path):
    """The metric rows gained their normal ranges, notes and the joints not measured, and the
    gait counts changed meaning, under the same motionlab version: a study resumed after that
    skipped its sessions and gathered their old tables (no normal range, no hips) with new
    ones. A stamp of older tables is not current."""
    manifest = make_study(tmp_path, {("S1", "v1"): "walk 112 0 30 2", ("S2", "v1"): "0 40 2"})
    out = tmp_path / "out"
    assert _run(manifest, out, workers=1).count("done") == 2
    stamp = out / "S2" / "v1" / STAMP
    doc = json.loads(stamp.read_text())
    assert doc["tables"] == TABLES
    del doc["tables"]  # as written before
    stamp.write_text(json.dumps(doc))
    again = _run(manifest, out, workers=1)
    assert (again.count("done"), again.count("skipped")) == (1, 1)


def _alive(pid: int) -> bool:
    """A process that runs (a zombie waiting for its new parent to reap it does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="reads /proc")
def test_a_worker_stops_when_its_batch_process_is_killed(tmp_path):
    """A ``motionlab batch`` of the real trunk study killed with SIGKILL left its worker running:
    it processed the sessions queued to it, then waited on the dead pool's queue for ever."""
    import signal
    import subprocess
    import sys
    import time

    sessions = {(f"S{k}", "v1"): "sleep 2 0 30 1" for k in range(1, 5)}
    manifest = make_study(tmp_path, sessions)
    code = (
        "import sys; sys.path.insert(0, sys.argv[3]); from batch_fakes import fake_pipeline;"
        "from motionlab.batch import load_manifest, run_study;"
        "run_study(load_manifest(sys.argv[1]), sys.argv[2], workers=1, pipeline=fake_pipeline)"
    )
    here = str(Path(__file__).parent)
    batch = subprocess.Popen([sys.executable, "-c", code, str(manifest), str(tmp_path / "out"),
                              here])  # fmt: skip
    first = tmp_path / "raw" / "S1" / "v1" / "rec.runs"
    for _ in range(200):  # the worker has started the first session
        if first.is_file() and first.read_text().strip():
            break
        time.sleep(0.1)
    worker = int(first.read_text().split()[0])
    batch.send_signal(signal.SIGKILL)
    batch.wait()
    for _ in range(40):
        if not _alive(worker):
            break
        time.sleep(0.1)
    alive = _alive(worker)
    if alive:
        os.kill(worker, signal.SIGKILL)
    assert not alive
    started = [p for p in (tmp_path / "raw").rglob("rec.runs")]
    assert len(started) == 1  # none of the queued sessions was taken on after the kill
    assert not (tmp_path / "out" / "S1" / "v1" / CLAIM).exists()


def test_a_range_no_session_determined_is_a_dash_in_the_study_report():
    """The real walk study's report printed 'nan [ nan, nan] n=0' for the knees' adduction and
    rotation, which no session determined."""
    import pandas as pd

    from motionlab.batch.outputs import range_summary

    assert range_summary(pd.Series([np.nan, np.nan])) == (f"{'—':>7} {'':16}", 0, 2)
    text, n, left = range_summary(pd.Series([10.0, 20.0, 30.0, np.nan]))
    assert (text.split(), n, left) == (["20.0", "[", "15.0,", "25.0]"], 3, 1)
    assert range_summary(pd.Series([10.0]))[2] == 0


def test_the_study_range_table_fits_the_page_and_names_every_joint_whole():
    """The seated trunk study's summary page cut its lines at the page's edge ('(2 weak, not
    determined or not measure') and the joint 'trunk_chair' to 'trunk_chai'; past 28 rows the
    rest were dropped without a word."""
    import pandas as pd

    from motionlab.batch.outputs import SUMMARY_ROWS, range_table

    rows = [("trunk_movement", "trunk_chair", "sideways", v) for v in (11.6, np.nan, np.nan)]
    rows += [("walk", f"joint{k}", "flexion", 40.0) for k in range(SUMMARY_ROWS + 2)]
    main = pd.DataFrame(rows, columns=["block", "joint", "angle", "value"])
    lines = range_table(main)
    assert lines[0].split() == ["task", "joint", "angle", "median", "[quartiles]", "n", "left",
                                "out"]  # fmt: skip
    assert lines[1].split() == ["trunk_movement", "trunk_chair", "sideways", "11.6", "[",
                                "11.6,", "11.6]", "1", "2"]  # fmt: skip
    assert len(lines) == 1 + SUMMARY_ROWS + 1
    assert lines[-1] == "… and 3 more in study_metrics.csv"
    assert max(map(len, lines)) <= 110


def test_runner_calls_the_pipeline_with_its_signature():
    pipeline = pytest.importorskip("motionlab.pipeline")
    params = inspect.signature(pipeline.run_pipeline).parameters
    assert list(params) == ["inputs", "outdir", "options"]
    fields = {f.name for f in dataclasses.fields(pipeline.PipelineOptions)}
    assert {"protocol", "map_path", "reference", "force", "progress"} <= fields


def test_run_options_from_manifest_flags_and_sessions(tmp_path):
    """A session's own key wins over a flag, a flag over the study's key; changed options
    make a session run again."""
    manifest = make_study(tmp_path, good_sessions(1, ("v1", "v2")))
    text = manifest.read_text().replace("sessions:", "seed: 1\nfilter: madgwick\nsessions:", 1)
    manifest.write_text(text.replace("files: raw/S1/v2/*.txt}", "files: raw/S1/v2/*.txt, seed: 5}"))
    out = tmp_path / "out"
    assert _run(manifest, out, options={"seed": 3, "magnetometer": True}, workers=1).ok
    report = {v: (out / "S1" / v / "report.txt").read_text() for v in ("v1", "v2")}
    assert "seed 3, magnetometer True, filter madgwick" in report["v1"]
    assert "seed 5, magnetometer True, filter madgwick" in report["v2"]
    again = _run(manifest, out, options={"seed": 3, "magnetometer": True}, workers=1)
    assert again.count("skipped") == 2
    assert _run(manifest, out, options={"seed": 3}, workers=1).count("done") == 2


def test_cli_exit_codes_progress_and_summary(tmp_path, monkeypatch):
    monkeypatch.setattr("motionlab.cli.batch.run_study", partial(run_study, pipeline=fake_pipeline))
    manifest = make_study(tmp_path, good_sessions(1) | {("S9", "v1"): "corrupt"})
    runner = CliRunner()
    res = runner.invoke(main, ["batch", str(manifest), "-o", str(tmp_path / "out"),
                               "--workers", "1"])  # fmt: skip
    assert res.exit_code == 3, res.output
    assert "3 sessions: 2 processed, 0 up to date, 1 failed" in res.output
    assert "done 2  skipped 0  failed 1" in res.output
    assert "first failure: S9/v1: rec.txt line 3" in res.output
    (tmp_path / "raw" / "S9" / "v1" / "rec.txt").write_text("0 10")
    res = runner.invoke(main, ["batch", str(manifest), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "1 processed, 2 up to date, 0 failed" in res.output
    res = runner.invoke(main, ["batch", str(manifest), "-o", "x", "--workers", "2",
                               "--scheduler", "tcp://127.0.0.1:1"])  # fmt: skip
    assert res.exit_code == 2 and "--workers is for the local pool" in res.output
    assert os.listdir(tmp_path / "out" / "S9" / "v1")


def test_the_study_statistics_leave_out_ranges_a_session_did_not_determine(tmp_path):
    """The study report's median and quartiles of the real trunk trials' trunk-against-chair
    rotation (weak in every session but one, up to 150°) mixed weak ranges in without a word."""
    from types import SimpleNamespace as NS

    from motionlab.batch.outputs import write_metrics
    from motionlab.batch.state import METRICS

    head = "block,joint,angle,metric,value,unit,grade\n"
    sessions, outcomes = [], []
    for k, (value, grade) in enumerate([(30.0, "determined"), (150.0, "weak"), (40.0, "")]):
        folder = Path(f"S{k}") / "v1"
        (tmp_path / folder).mkdir(parents=True)
        rows = head + f"move,lumbar,flexion,rom_deg,{value},deg,{grade}\n"
        if not grade:  # a session's table from before the grade column
            rows = rows.replace(",grade", "").replace(",\n", "\n")
        (tmp_path / folder / METRICS).write_text(rows)
        sessions.append(NS(folder=folder, subject=f"S{k}", visit="v1"))
        outcomes.append(NS(status="done"))
    main = write_metrics(tmp_path, NS(sessions=sessions), outcomes, tmp_path / "study.csv")
    assert main["value"].tolist()[0] == 30.0 and main["value"].isna().tolist() == [
        False, True, False
    ]  # fmt: skip
    assert main["grade"].tolist() == ["determined", "weak", ""]
    assert _rows(tmp_path / "study.csv")[1]["grade"] == "weak"  # the table keeps every number


def test_a_server_that_is_no_dask_scheduler_is_one_line():
    """``--scheduler`` at a server that is no Dask scheduler: its bytes read as a 3 EiB message
    (MemoryError: "internal error"), or the handshake waited for ever (an HTTP server). Both
    are now one line naming the address, before any session."""
    import types

    from motionlab.batch import runner
    from motionlab.errors import InputError

    def garbage(*a, **k):
        raise MemoryError("Unable to allocate 3.07 EiB")

    fake = types.SimpleNamespace(Client=garbage)
    with pytest.raises(InputError, match="cannot reach the Dask scheduler 'tcp://h:1'.*3.07 EiB"):
        runner._connect(fake, "tcp://h:1")


def test_a_study_folder_that_cannot_be_created_is_one_line(tmp_path, monkeypatch):
    """``batch … -o ro/res`` on a read-only file system ended in an internal error (OSError)."""
    from pathlib import Path

    from motionlab.batch import state
    from motionlab.errors import InputError

    def read_only(self, *a, **k):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(Path, "mkdir", read_only)
    manifest = tmp_path / "study.yaml"
    manifest.write_text("protocol: knee\nsessions: []\n")
    with pytest.raises(InputError, match="cannot create the folder \\(Read-only file system\\)"):
        state.prepare_outdir(tmp_path / "res", manifest, force=False)


def test_an_empty_scheduler_is_refused(tmp_path):
    """``--scheduler ''`` ran the local pool without a word."""
    from click.testing import CliRunner

    from motionlab.cli import main

    (tmp_path / "study.yaml").write_text("protocol: knee\nsessions: []\n")
    res = CliRunner().invoke(main, ["batch", str(tmp_path / "study.yaml"), "-o",
                                    str(tmp_path / "res"), "--scheduler", ""])  # fmt: skip
    assert res.exit_code == 2 and "--scheduler: is empty" in res.output


def test_a_second_batch_into_the_same_study_folder_is_refused(tmp_path):
    """Two ``motionlab batch`` into one folder at once processed the same sessions twice, each
    writing over the other's; the second is now refused naming the first, and runs once the
    first has finished."""
    import threading

    from motionlab.batch.state import MARKER
    from motionlab.lock import session_lock

    manifest = make_study(tmp_path, good_sessions(1, ("v1",)))
    out = tmp_path / "out"
    assert _run(manifest, out, workers=1).ok
    held, done = threading.Event(), threading.Event()

    def first_batch():
        with session_lock(out / MARKER):
            held.set()
            done.wait(10)

    thread = threading.Thread(target=first_batch)
    thread.start()
    try:
        held.wait(10)
        with pytest.raises(InputError, match="out -o: is being written by another motionlab batch"):
            _run(manifest, out, workers=1, force=True)
    finally:
        done.set()
        thread.join()
    assert _run(manifest, out, workers=1, force=True).ok


def test_a_range_not_determined_is_an_empty_cell_the_study_tables_take():
    """Every real walk leaves its knees' adduction empty in metrics.csv (not determined): the
    study tables crashed on it ("could not convert string to float: ''") after every session
    had run, and wrote nothing."""
    from motionlab.batch.outputs import _rom_rows

    head = ["block", "joint", "angle", "metric", "value", "unit", "grade"]
    rows = [["walk", "knee_r", "flexion", "rom_deg", "62.5", "deg", "determined"],
            ["walk", "knee_r", "adduction", "rom_deg", "", "deg", "not determined"]]  # fmt: skip
    got = _rom_rows("S1", "v1", head, rows)
    assert got[0][5] == 62.5 and np.isnan(got[1][5]) and got[1][6] == "not determined"


def test_the_change_over_visits_draws_no_median_of_one_subject():
    """A visit that one subject alone determined had its value drawn as the 'median' and joined
    to another visit's other subject: a change over visits that was a difference between
    subjects. The median is drawn only where two subjects or more have a value; every visit's
    tick says how many."""
    import pandas as pd

    from motionlab.batch.outputs import _changes, _distributions

    rows = [("S1", "v1", 10.0), ("S2", "v1", 20.0), ("S1", "v2", 30.0), ("S2", "v3", 50.0)]
    main = pd.DataFrame(
        [("walk", "knee_r", "flexion", s, v, x) for s, v, x in rows],
        columns=["block", "joint", "angle", "subject", "visit", "value"],
    )

    class Pages:
        figures: list = []

        def savefig(self, fig):
            self.figures.append(fig)

    pages = Pages()
    _changes(pages, main, ["v1", "v2", "v3"])
    ax = pages.figures[0].axes[0]
    median = [ln for ln in ax.get_lines() if ln.get_label().startswith("median")]
    assert len(median) == 1
    assert list(median[0].get_xdata()) == [0] and list(median[0].get_ydata()) == [15.0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["v1\nn=2", "v2\nn=1", "v3\nn=1"]
    assert {ln.get_label() for ln in ax.get_lines()} >= {"S1", "S2"}
    pages.figures.clear()
    _distributions(pages, main.assign(value=[10.0, np.nan, 30.0, 50.0]))
    ticks = [t.get_text() for t in pages.figures[0].axes[0].get_xticklabels()]
    assert ticks == ["flexion\nn=2"]  # S2's mean over v1 (NaN) and v3: one value per subject
