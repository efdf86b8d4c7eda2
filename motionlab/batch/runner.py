"""Run every session of a study: a local process pool by default, a Dask cluster on request.

Each session runs :func:`motionlab.pipeline.run_pipeline` (the code of ``motionlab run``) into
``OUTDIR/<subject>/<visit>/`` inside a worker process (:func:`run_session`), which returns an
:class:`Outcome` and never raises for a bad session: an :class:`~motionlab.errors.InputError` or a
bug becomes a one-line error and the other sessions go on.

Sessions that are current (:mod:`motionlab.batch.state`) are skipped. A session whose worker
process dies (killed, out of memory, a crash in native code) is submitted again, up to ``retry``
more times. Only the sessions that were *running* in a dead worker count the attempt — their
claim file survived; sessions merely queued there go again for free, and a session that had
finished (its stamp is current) is not run again.

- local pool (:class:`concurrent.futures.ProcessPoolExecutor`, ``spawn``): one dead worker breaks
  the pool, so the pool is restarted and its unfinished sessions resubmitted. The pool stops the
  healthy workers with SIGTERM, on which they drop their claim and exit; a worker whose batch
  process died (killed) does the same within half a second.
- Dask (``--scheduler``): the scheduler itself re-runs a task whose worker died, up to its
  ``distributed.scheduler.allowed-failures``; when it gives up (``KilledWorker``) the session is
  resubmitted as above. Input and output paths must be the same on every machine (a shared
  file system).

Workers use one BLAS/OpenMP thread each (as Dask workers do), so ``N`` workers use ``N`` cores.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from motionlab.atomic import atomic_path
from motionlab.batch.manifest import Manifest, manifest_spelling
from motionlab.batch.state import (
    GAIT,
    MARKER,
    METRICS,
    STAMP,
    FileHashes,
    claim,
    claimed,
    is_current,
    prepare_outdir,
    read_stamp,
    release,
    session_key,
    sweep_temp,
    write_stamp,
)
from motionlab.errors import InputError
from motionlab.lock import holder, lock_path, session_lock
from motionlab.pipeline import SESSION_FILE, PipelineOptions

#: ``run_pipeline(inputs, outdir, options)`` of motionlab.pipeline (tests pass a stand-in)
Pipeline = Callable[..., Any]
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_POLL_S = 0.2
_PARENT_POLL_S = 0.5
_CONNECT_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class SessionTask:
    """What a worker needs to process one session (absolute paths, picklable): its files, its
    output folder and every option of ``motionlab run`` (protocol, map, reference, ...)."""

    index: int
    subject: str
    visit: str
    files: tuple[str, ...]
    outdir: str
    key: str
    options: PipelineOptions


@dataclass
class Outcome:
    """How one session ended: ``status`` is ``done``, ``skipped`` or ``failed``.

    ``kind`` of a failure: ``input`` (bad input, the error names it), ``internal`` (a bug),
    ``worker_died`` (its worker process died on every attempt). ``seconds`` of the last attempt.
    """

    subject: str
    visit: str
    status: str
    error: str = ""
    kind: str = ""
    seconds: float = 0.0
    attempts: int = 0


@dataclass
class Progress:
    """Counts for a progress display; ``eta_s`` from the pace of the sessions run so far."""

    total: int
    to_run: int = 0
    done: int = 0
    skipped: int = 0
    failed: int = 0
    ran: int = 0
    started: float = field(default_factory=time.monotonic)

    @property
    def finished(self) -> int:
        return self.done + self.skipped + self.failed

    def eta_s(self) -> float | None:
        """Seconds left, or None before the first session has finished."""
        if self.ran == 0:
            return None
        return (self.to_run - self.ran) * (time.monotonic() - self.started) / self.ran


@dataclass
class StudyResult:
    """Outcomes in manifest order and the study output files."""

    outcomes: list[Outcome]
    outputs: dict[str, Path]

    @property
    def ok(self) -> bool:
        """True when no session failed."""
        return all(o.status != "failed" for o in self.outcomes)

    def count(self, status: str) -> int:
        return sum(o.status == status for o in self.outcomes)


# ------------------------------------------------------------------------------ worker side

_ACTIVE: set[Path] = set()  # the session folders this worker process is writing


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def run_session(task: SessionTask, pipeline: Pipeline | None = None) -> Outcome:
    """Process one session in this process; return its outcome, never raise for bad input.

    ``pipeline`` defaults to :func:`motionlab.pipeline.run_pipeline`. The session's metric
    table goes to ``batch_metrics.csv``, a walk's gait summary to ``batch_gait.csv`` (as the
    session's ``spatiotemporal_summary.csv``), then the stamp is written (all atomically).
    """
    folder = Path(task.outdir)
    start = time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    sweep_temp(folder)
    (folder / STAMP).unlink(missing_ok=True)
    _ACTIVE.add(folder)  # before the claim: a SIGTERM in between must not leave it
    claim(folder)
    try:
        if pipeline is None:
            from motionlab.pipeline import run_pipeline as pipeline
        with session_lock(folder / SESSION_FILE):  # what a stage command on it holds too
            result = pipeline([Path(f) for f in task.files], folder, task.options)
        with atomic_path(folder / METRICS, force=True) as tmp:
            result.metrics.to_csv(tmp, index=False, lineterminator="\n")
        if result.gait is None:
            (folder / GAIT).unlink(missing_ok=True)  # an earlier run's walk
        else:
            from motionlab.report.csv import write_frame

            with atomic_path(folder / GAIT, force=True) as tmp:
                write_frame(result.gait, tmp)
        seconds = time.perf_counter() - start
        write_stamp(folder, task.key, seconds)
        return Outcome(task.subject, task.visit, "done", seconds=seconds)
    except InputError as exc:
        error, kind = exc.respelled(manifest_spelling).line(), "input"
    except Exception as exc:  # a bug in one session must not stop the study
        error, kind = f"internal error ({type(exc).__name__}: {exc})", "internal"
    finally:
        _ACTIVE.discard(folder)
        release(folder)
    seconds = time.perf_counter() - start
    return Outcome(task.subject, task.visit, "failed", _one_line(error), kind, seconds)


def _on_terminate(signum: int, frame: object) -> None:
    """The pool stops healthy workers when another one died: drop the claim, exit at once."""
    for folder in list(_ACTIVE):
        release(folder)
    os._exit(128 + signum)


def _watch_parent(parent: int) -> None:
    """Stop this worker when the batch process that started it is gone (SIGKILL, out of
    memory): a worker of a dead pool went on with the sessions queued to it, then waited on
    the dead pool's queue for ever."""
    while os.getppid() == parent:
        time.sleep(_PARENT_POLL_S)
    _on_terminate(signal.SIGTERM, None)


def _init_worker(parent: int) -> None:
    signal.signal(signal.SIGTERM, _on_terminate)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


# ------------------------------------------------------------------------------ backends


@contextlib.contextmanager
def _one_thread_per_worker() -> Iterator[None]:
    """Environment for starting workers: one BLAS/OpenMP thread unless the user chose."""
    saved = {k: os.environ.get(k) for k in _THREAD_VARIABLES}
    for k in _THREAD_VARIABLES:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def default_workers() -> int:
    """The number of cores this process may use."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


class _LocalPool:
    """A process pool that is restarted when a worker died."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.pool: ProcessPoolExecutor | None = None

    def submit(self, task: SessionTask, pipeline: Pipeline | None) -> Future:
        if self.pool is None:
            self.pool = ProcessPoolExecutor(
                self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_init_worker,
                initargs=(os.getpid(),),
            )
        with _one_thread_per_worker():  # workers start during submit
            return self.pool.submit(run_session, task, pipeline)

    @staticmethod
    def died(future: Future) -> bool:
        return isinstance(future.exception(), BrokenProcessPool)

    def after_death(self) -> None:
        """Wait for the broken pool to stop every worker (so claims are final); start anew."""
        self.pool.shutdown(wait=True)
        self.pool = None

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)


def _connect(distributed: Any, address: str) -> Any:
    """A Dask client of the scheduler at ``address``, or one clear :class:`InputError`: a
    closed port, and also a server that is no Dask scheduler (an HTTP server let the handshake
    wait for ever; another answered bytes that read as a 3 EiB message, a MemoryError). The
    connection is made in a daemon thread given twice :data:`_CONNECT_TIMEOUT_S`."""
    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = distributed.Client(
                address, timeout=_CONNECT_TIMEOUT_S, set_as_default=False
            )
        except Exception as exc:  # whatever a non-scheduler makes of the handshake
            box["error"] = exc

    thread = threading.Thread(target=connect, daemon=True)
    thread.start()
    thread.join(2 * _CONNECT_TIMEOUT_S)
    if "client" in box:
        return box["client"]
    why = _one_line(box["error"]) if "error" in box else (
        f"no Dask answer within {2 * _CONNECT_TIMEOUT_S:.0f} s"
    )  # fmt: skip
    raise InputError(
        f"cannot reach the Dask scheduler {address!r} ({why})",
        where="argument scheduler",
        remedy="start one with 'dask scheduler' or check the address (a Dask scheduler's port)",
        argument="scheduler",
    )


class _DaskCluster:
    """Sessions as tasks of a running Dask distributed scheduler."""

    def __init__(self, address: str) -> None:
        try:
            import distributed
        except ImportError:
            raise InputError(
                "Dask is not installed", where="argument scheduler",
                remedy="pip install 'motionlab[dask]'", argument="scheduler",
            ) from None  # fmt: skip
        self._killed = distributed.KilledWorker
        self.client = _connect(distributed, address)

    def submit(self, task: SessionTask, pipeline: Pipeline | None) -> Any:
        key = f"motionlab-batch-{task.subject}/{task.visit}-{uuid.uuid4().hex[:8]}"
        return self.client.submit(run_session, task, pipeline, key=key, pure=False)

    def died(self, future: Any) -> bool:
        return future.status == "error" and isinstance(future.exception(), self._killed)

    def after_death(self) -> None:
        """The scheduler keeps going: nothing to restart."""

    def close(self) -> None:
        self.client.close()


def _execute(
    backend: _LocalPool | _DaskCluster,
    tasks: list[SessionTask],
    retry: int,
    pipeline: Pipeline | None,
    state: Progress,
    report: Callable[[Progress], None],
) -> dict[int, Outcome]:
    """Submit every task, collect outcomes, resubmit the sessions whose worker died.

    When workers die, only the sessions that were running in them (their claim file survived)
    count an attempt; sessions merely queued there go again for free. If no session held a
    claim, all of them count it, so that a pool that keeps dying comes to an end.
    """
    outcomes: dict[int, Outcome] = {}
    deaths = dict.fromkeys((t.index for t in tasks), 0)

    def record(task: SessionTask, outcome: Outcome, attempts: int = 0) -> None:
        outcome.attempts = attempts or deaths[task.index] + 1
        outcomes[task.index] = outcome
        state.ran += 1
        state.done += outcome.status == "done"
        state.failed += outcome.status == "failed"

    pending = {backend.submit(t, pipeline): t for t in tasks}
    while pending:
        done = [f for f in pending if f.done()]
        if not done:
            report(state)
            time.sleep(_POLL_S)
            continue
        if any(backend.died(f) for f in done):
            backend.after_death()
            done = [f for f in pending if f.done()]
        lost = []
        for future in done:
            task = pending.pop(future)
            if backend.died(future):
                lost.append(task)
                continue
            try:
                outcome = future.result()
            except Exception as exc:  # the task could not run at all (e.g. not picklable)
                error = _one_line(f"internal error ({type(exc).__name__}: {exc})")
                outcome = Outcome(task.subject, task.visit, "failed", error, "internal")
            record(task, outcome)
        for task in [t for t in lost if is_current(Path(t.outdir), t.key)]:
            lost.remove(task)  # it finished: only its answer went down with the worker
            seconds = float((read_stamp(Path(task.outdir)) or {}).get("seconds", 0.0))
            record(task, Outcome(task.subject, task.visit, "done", seconds=seconds))
        blamed = [t for t in lost if claimed(Path(t.outdir))] or lost
        for task in lost:
            release(Path(task.outdir))
            deaths[task.index] += task in blamed
            if deaths[task.index] <= retry:
                pending[backend.submit(task, pipeline)] = task
                continue
            n = deaths[task.index]
            error = f"the worker process died while processing this session, {n} times"
            record(task, Outcome(task.subject, task.visit, "failed", error, "worker_died"), n)
        report(state)
    return outcomes


# ------------------------------------------------------------------------------ the study


def run_study(
    manifest: Manifest,
    outdir: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    retry: int = 1,
    force: bool = False,
    options: dict[str, Any] | None = None,
    pipeline: Pipeline | None = None,
    progress: Callable[[Progress], None] | None = None,
) -> StudyResult:
    """Process every session of ``manifest`` into ``outdir`` and write the study outputs.

    Parameters
    ----------
    manifest
        From :func:`~motionlab.batch.manifest.load_manifest`.
    outdir
        Study folder: ``<subject>/<visit>/`` per session, and ``study_metrics.csv``,
        ``study_failures.csv``, ``study_report.pdf``.
    workers
        Local worker processes (default: the number of cores); not used with ``scheduler``.
    scheduler
        Address of a running Dask distributed scheduler, e.g. ``tcp://10.0.0.5:8786``.
    retry
        How many more times a session whose worker died is submitted.
    force
        Run every session even if current; accept an ``outdir`` holding other files.
    options
        Options of ``motionlab run`` for every session (:class:`PipelineOptions` field names,
        the ``motionlab batch`` flags): they replace the manifest's top-level settings, and a
        session's own settings replace them.
    pipeline
        Stand-in for :func:`motionlab.pipeline.run_pipeline` (a picklable function).
    progress
        Called with the :class:`Progress` counts as sessions finish (and while waiting).
    """
    outdir = Path(outdir)
    if retry < 0:
        raise InputError(f"retry={retry} is negative", remedy="give 0 or more", argument="retry")
    if workers is not None and workers < 1:
        raise InputError(f"workers={workers} is below 1", remedy="give 1+", argument="workers")
    # the cluster first: Dask missing or unreachable is one line before any folder or progress
    cluster = _DaskCluster(scheduler) if scheduler else None
    try:
        prepare_outdir(outdir, manifest.path, force)
        with _one_batch(outdir):
            return _run_sessions(manifest, outdir, workers, cluster, retry, force, options,
                                 pipeline, progress)  # fmt: skip
    finally:
        if cluster is not None:
            cluster.close()


@contextlib.contextmanager
def _one_batch(outdir: Path) -> Iterator[None]:
    """Hold the study folder's lock for the whole batch: a second ``motionlab batch`` into the
    same folder processed the same sessions at once, each writing over the other's."""
    marker = outdir / MARKER
    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(session_lock(marker, wait=0))
        except InputError:
            who = holder(lock_path(marker)) or "another process"
            raise InputError(
                f"is being written by another motionlab batch ({who})",
                outdir,
                "-o",
                "wait for it to finish, or write this study to another folder",
            ) from None
        yield


def _run_sessions(
    manifest: Manifest,
    outdir: Path,
    workers: int | None,
    cluster: _DaskCluster | None,
    retry: int,
    force: bool,
    options: dict[str, Any] | None,
    pipeline: Pipeline | None,
    progress: Callable[[Progress], None] | None,
) -> StudyResult:
    """:func:`run_study` once its folder is ready and locked (``cluster``: the Dask one, which
    the caller closes; else a local pool)."""
    hashes = FileHashes()
    outcomes: dict[int, Outcome] = {}
    tasks: list[SessionTask] = []
    for i, spec in enumerate(manifest.sessions):
        folder = (outdir / spec.folder).resolve()
        problem, key = spec.problem, ""
        settings = manifest.options | (options or {}) | spec.options
        run_options = PipelineOptions(
            str(manifest.protocol.resolve()),
            map_path=spec.map.resolve() if spec.map else None,
            reference=spec.reference.resolve() if spec.reference else None,
            markers_path=spec.markers.resolve() if spec.markers else None,
            force=True,
            progress=False,
            **settings,
        )
        if run_options.calibration_dir is not None:
            run_options = replace(
                run_options, calibration_dir=run_options.calibration_dir.resolve()
            )
        if not problem:
            try:
                key = session_key(
                    list(spec.files),
                    manifest.protocol,
                    spec.map,
                    spec.reference,
                    hashes,
                    options=run_options.analysis(),
                    markers=spec.markers,
                )
            except OSError as exc:
                problem = f"cannot read an input ({_one_line(exc)})"
        if problem:
            outcomes[i] = Outcome(spec.subject, spec.visit, "failed", problem, "input")
        elif not force and is_current(folder, key):
            outcomes[i] = Outcome(spec.subject, spec.visit, "skipped")
        else:
            tasks.append(
                SessionTask(
                    index=i,
                    subject=spec.subject,
                    visit=spec.visit,
                    files=tuple(str(f.resolve()) for f in spec.files),
                    outdir=str(folder),
                    key=key,
                    options=run_options,
                )
            )
    state = Progress(total=len(manifest.sessions), to_run=len(tasks))
    state.skipped = sum(o.status == "skipped" for o in outcomes.values())
    state.failed = sum(o.status == "failed" for o in outcomes.values())
    report = progress or (lambda _state: None)
    report(state)
    if tasks:
        backend = cluster or _LocalPool(workers or default_workers())
        try:
            outcomes |= _execute(backend, tasks, retry, pipeline, state, report)
        finally:
            if cluster is None:
                backend.close()
            for task in tasks:
                sweep_temp(Path(task.outdir))
                release(Path(task.outdir))
    from motionlab.batch import outputs  # here: workers need not load matplotlib

    ordered = [outcomes[i] for i in range(len(manifest.sessions))]
    written = outputs.write_study_outputs(outdir, manifest, ordered)
    return StudyResult(ordered, written)
