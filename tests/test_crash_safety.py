"""Crash safety (issue 26): a stage command, a ``run`` and a batch worker killed with SIGKILL at
random moments (drawn with a fixed seed, some while the output is being written) leave every
input byte-identical and every output either the old complete file or the new complete one; a
full disk (RLIMIT_FSIZE in the child) is one line, exit 2, and the old file intact."""

from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from integrity_helpers import (  # noqa: E402
    PROTOCOL,
    fork_cli,
    kill_at,
    make_sessions,
    one_error_line,
    sha,
    wait,
)

from motionlab.errors import InputError  # noqa: E402
from motionlab.session import load_session  # noqa: E402

RNG = np.random.default_rng(26)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    from motionlab import stages

    raw, analysed = make_sessions(tmp_path_factory.mktemp("sessions"))
    stages.fuse(load_session(raw), "madgwick")  # compiled here, once, not in every child
    return raw, analysed


def old_or_new(path: Path, old: str, is_new) -> str:
    """``old`` (same bytes), ``new`` (``is_new(path)``: complete and new) or ``broken``."""
    if sha(path) == old:
        return "old"
    try:
        return "new" if is_new(path) else "broken"
    except (InputError, OSError, ValueError):
        return "broken"


def _fused_by(name: str):
    def check(path: Path) -> bool:
        ses = load_session(path)
        return all(e.name == name for e in ses.results.fusion.values())

    return check


@pytest.mark.parametrize("when", ["random", "writing"])
def test_a_killed_stage_command_leaves_the_old_or_the_new_session(sessions, tmp_path, when):
    path = tmp_path / "session.h5"
    verdicts = []
    for _ in range(2):
        shutil.copy(sessions[1], path)
        old = sha(path)
        pid = fork_cli(["fuse", path, "--filter", "madgwick", "--force"], tmp_path / "f.log")
        if when == "random":
            kill_at(pid, float(RNG.uniform(0.0, 1.5)))
        else:  # while the new file is written, or just after
            kill_at(pid, float(RNG.uniform(0.0, 0.05)), tmp_path, after_tmp=True)
        wait(pid)
        verdicts.append(old_or_new(path, old, _fused_by("madgwick")))
        for tmp in tmp_path.glob(".*.tmp"):  # what the next writer sweeps (under the lock)
            tmp.unlink()
    assert "broken" not in verdicts, verdicts


def _run_is_complete(out: Path):
    def check(path: Path) -> bool:
        ses = load_session(path)
        return ses.results.metrics is not None and ses.provenance[-1]["parameters"].get("seed") == 1

    return check


@pytest.mark.parametrize("when", ["random", "writing"])
def test_a_killed_run_leaves_its_input_and_old_or_new_outputs(sessions, tmp_path, when):
    raw = tmp_path / "raw.h5"
    shutil.copy(sessions[0], raw)
    before = sha(raw)
    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(sessions[1], out / "session.h5")  # the outputs of an earlier run
    (out / "results.json").write_text('{"old": true}')
    old = sha(out / "session.h5")
    args = ["run", "--protocol", PROTOCOL, raw, "-o", out, "--force", "--quiet",
            "--no-clock-sync", "--seed", "1"]  # fmt: skip
    pid = fork_cli(args, tmp_path / "run.log")
    if when == "random":
        kill_at(pid, float(RNG.uniform(0.2, 3.0)))
    else:
        kill_at(pid, float(RNG.uniform(0.0, 0.05)), out, after_tmp=True)
    wait(pid, timeout=120)
    assert sha(raw) == before
    assert old_or_new(out / "session.h5", old, _run_is_complete(out)) != "broken"
    json.loads((out / "results.json").read_text())  # old or new, whole


def test_a_killed_batch_worker_leaves_old_or_new_outputs(sessions, tmp_path):
    """What every ``batch`` worker runs for one session (:func:`run_session`, under the
    session's lock), killed while it writes."""
    import os

    from motionlab.batch.runner import SessionTask, run_session
    from motionlab.pipeline import PipelineOptions

    raw = tmp_path / "raw.h5"
    shutil.copy(sessions[0], raw)
    before = sha(raw)
    folder = tmp_path / "study" / "S1" / "V1"
    folder.mkdir(parents=True)
    shutil.copy(sessions[1], folder / "session.h5")
    old = sha(folder / "session.h5")
    options = PipelineOptions(protocol=PROTOCOL, clock_sync=False, seed=1, force=True,
                              progress=False)  # fmt: skip
    task = SessionTask(0, "S1", "V1", (str(raw),), str(folder), "key", options)
    pid = os.fork()
    if pid == 0:
        try:
            run_session(task)
        finally:
            os._exit(0)
    kill_at(pid, float(RNG.uniform(0.0, 0.05)), folder, after_tmp=True)
    wait(pid, timeout=120)
    assert sha(raw) == before
    assert old_or_new(folder / "session.h5", old, _run_is_complete(folder)) != "broken"


def test_a_full_disk_is_one_line_and_the_old_file_stays(sessions, tmp_path):
    path = tmp_path / "session.h5"
    shutil.copy(sessions[1], path)
    old = sha(path)
    size = path.stat().st_size
    t0 = time.monotonic()
    pid = fork_cli(["fuse", path, "--filter", "madgwick", "--force"], tmp_path / "full.log",
                   fsize=size // 2)  # fmt: skip
    code = wait(pid, timeout=60)
    out = (tmp_path / "full.log").read_text()
    assert code == 2 and one_error_line(out), (code, out[:2000])
    assert "cannot write the file (File too large)" in out and "the old file is kept" in out
    assert sha(path) == old
    assert not list(tmp_path.glob(".*.tmp"))
    assert time.monotonic() - t0 < 60
