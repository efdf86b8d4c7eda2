"""Helpers of the integrity tests and ``bench/concurrency.py`` (issue 26): a small analysed
session, the CLI in a forked child (killable, with its own stdout/stderr file and limits)."""

from __future__ import annotations

import hashlib
import os
import resource
import signal
import sys
import time
from pathlib import Path

#: the simulated session: a 30 s walk without calibration steps, 5 sensors at 50 Hz
PROTOCOL = "walk"
SIM_ARGS = ["--protocol", PROTOCOL, "--duration", "30", "--no-calibration", "--rate", "50"]


def make_sessions(folder: Path) -> tuple[Path, Path]:
    """``(raw, analysed)``: a simulated session file and the same analysed by ``run``'s stages
    (no clock sync: a few seconds), both in ``folder``."""
    from motionlab.pipeline import PipelineOptions, analyse
    from motionlab.session import load_session, save_session
    from motionlab.simulate import simulate

    folder.mkdir(parents=True, exist_ok=True)
    raw, analysed = folder / "raw.h5", folder / "analysed.h5"
    session, _ = simulate(PROTOCOL, 30.0, 0, "typical", rate_hz=50.0, calibration=False)
    save_session(session, raw)
    session = load_session(raw)
    analyse(session, PipelineOptions(protocol=PROTOCOL, clock_sync=False, progress=False))
    save_session(session, analysed)
    return raw, analysed


def sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def fork_cli(
    args: list[str],
    log: Path,
    env: dict[str, str] | None = None,
    fsize: int | None = None,
    cwd: Path | None = None,
) -> int:
    """Run ``motionlab ARGS`` in a forked child (motionlab already imported: no start-up time);
    its stdout and stderr go to ``log``; ``fsize``: RLIMIT_FSIZE in bytes (SIGXFSZ ignored, so
    that a write past it fails with EFBIG as on a full disk). Returns the child's pid."""
    args = [str(a) for a in args]
    pid = os.fork()
    if pid:
        return pid
    code = 99
    try:
        fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        sys.stdout = sys.stderr = open(fd, "w", buffering=1, closefd=False)  # noqa: SIM115
        os.environ.update(env or {})
        if cwd is not None:
            os.chdir(cwd)
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
        sys.argv = ["motionlab", *args]
        from motionlab.cli import main

        try:
            main(args, prog_name="motionlab")
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        sys.stdout.flush()
        os._exit(code)


def wait(pid: int, timeout: float = 60.0) -> int | None:
    """The exit code of child ``pid`` (``-signal`` if killed), or ``None`` when it did not end
    within ``timeout`` s (it is then killed: a hang)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        time.sleep(0.02)
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
    return None


def kill_at(pid: int, delay: float, folder: Path | None = None, after_tmp: bool = False) -> None:
    """SIGKILL child ``pid`` ``delay`` s from now, or, with ``after_tmp``, ``delay`` s after a
    temporary output file (``.*.tmp``) appears in ``folder`` (the moment of writing)."""
    if after_tmp and folder is not None:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not any(folder.glob(".*.tmp")):
            # ended already (a write too quick to be seen): look without reaping it, so that
            # wait() still gets its exit status
            if os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None:
                return
            time.sleep(0.001)
    time.sleep(delay)
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def one_error_line(text: str) -> bool:
    """Whether ``text`` (a child's output) holds exactly one line starting ``error:`` and no
    traceback."""
    lines = [line for line in text.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error:")]
    return len(errors) == 1 and "Traceback" not in text
