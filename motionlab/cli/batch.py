"""``motionlab batch``: every session of a study manifest, on local cores or a Dask cluster."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import click

from motionlab.atomic import refuse_folder_holding_inputs, refuse_folder_in_input_folder
from motionlab.batch import Progress, load_manifest, run_study
from motionlab.batch.manifest import Manifest
from motionlab.cli.paths import INPUT_FILE
from motionlab.cli.run_options import batch_click_options, run_values
from motionlab.errors import InputError
from motionlab.fusion import registry

#: exit code when the study ran but some sessions failed (bad input is 2, a bug 1)
EXIT_SESSIONS_FAILED = 3
_BAR = 24


def _clock(seconds: float) -> str:
    minutes, s = divmod(int(round(seconds)), 60)
    h, m = divmod(minutes, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def progress_line(p: Progress) -> str:
    """``[#####.....] 120/200  done 100  skipped 15  failed 5  ETA 2:31``."""
    filled = round(_BAR * p.finished / p.total) if p.total else _BAR
    eta = p.eta_s()
    return (
        f"[{'#' * filled}{'.' * (_BAR - filled)}] {p.finished}/{p.total}  done {p.done}  "
        f"skipped {p.skipped}  failed {p.failed}  ETA {'--' if eta is None else _clock(eta)}"
    )


class _ProgressBar:
    """Redraws one line on a terminal; prints a line every ``every_s`` into a log file."""

    def __init__(self, every_s: float = 10.0) -> None:
        self.tty = sys.stderr.isatty()
        self.every_s = 0.5 if self.tty else every_s
        self.last = -float("inf")
        self.shown = ""

    def __call__(self, p: Progress) -> None:
        line = progress_line(p)
        now = time.monotonic()
        final = p.finished == p.total
        if line == self.shown or (now - self.last < self.every_s and not final):
            return
        self.last, self.shown = now, line
        if self.tty:
            click.echo(f"\r{line}", err=True, nl=final)
        else:
            click.echo(line, err=True)


@click.command("batch")
@click.argument("manifest", type=INPUT_FILE)
@click.option(
    "-o", "--output", "outdir", required=True,
    help="Study output folder (not one that is or holds an input of the study).",
)  # fmt: skip
@click.option("--workers", type=int, help="Local worker processes [default: number of cores].")
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Run on a Dask distributed scheduler (tcp://host:8786); pip install 'motionlab[dask]'.",
)
@click.option(
    "--retry",
    type=int,
    default=1,
    show_default=True,
    help="Resubmit a session whose worker process died this many times.",
)
@batch_click_options
@click.option("--force", is_flag=True, help="Re-run up-to-date sessions; write into any folder.")
def command(
    manifest: str,
    outdir: str,
    workers: int | None,
    scheduler: str | None,
    retry: int,
    force: bool,
    **params: Any,
) -> None:
    """Process every session of the study MANIFEST (study.yaml) as 'motionlab run' does.

    Each session goes to OUTDIR/<subject>/<visit>/. Sessions whose input files (SHA-256),
    protocol, options and motionlab version are unchanged since their last successful run are
    skipped,
    so an interrupted study resumes where it stopped. A failing session is listed in
    OUTDIR/study_failures.csv and the others go on. All sessions' metrics are collected in
    OUTDIR/study_metrics.csv, the walks' gait summaries in OUTDIR/study_gait.csv, and the
    ranges summarised in OUTDIR/study_report.pdf.

    The options of 'motionlab run' (--calibration, --seed, --filter, --orientation,
    --magnetometer, --no-clock-sync) are also manifest keys, for the study or for one session;
    a flag given here replaces the manifest's study-wide setting, a session's own setting
    replaces both.

    Exit code: 0 when every session succeeded, 3 when some failed, 2 for a bad manifest.

    \b
    Example:
      motionlab batch study.yaml -o results/ --workers 8
      motionlab batch study.yaml -o results/ --scheduler tcp://10.0.0.5:8786
      motionlab batch study.yaml -o results/ --calibration calibration/ --seed 3
    """
    if scheduler is not None and not scheduler.strip():  # '' ran the local pool unasked
        raise InputError(
            "is empty", where="--scheduler", remedy="give tcp://host:8786, or leave it out"
        )
    if scheduler and workers is not None:
        raise InputError(
            "--workers is for the local pool",
            where="--workers",
            remedy="leave it out with --scheduler: the Dask cluster has its own workers",
        )
    flags = run_values(params, batch=True)
    if "estimator" in flags:
        registry.get(flags["estimator"])  # an unknown name fails before any work
    calibration_dir = flags.get("calibration_dir")
    if calibration_dir is not None and not calibration_dir.is_dir():
        raise InputError(
            "no such calibration folder",
            calibration_dir,
            "--calibration",
            "run motionlab sensorcal",
        )
    study = load_manifest(manifest)
    inputs = _inputs(study, calibration_dir)
    refuse_folder_holding_inputs(outdir, inputs)
    refuse_folder_in_input_folder(outdir, inputs)  # an x-IMU3 export, a calibration folder
    start = time.monotonic()
    result = run_study(
        study,
        outdir,
        workers=workers,
        scheduler=scheduler,
        retry=retry,
        force=force,
        options=flags,
        progress=_ProgressBar(),
    )
    failed = result.count("failed")
    names = ", ".join(p.name for p in result.outputs.values())
    click.echo(
        f"{len(result.outcomes)} session{'s' if len(result.outcomes) != 1 else ''}: "
        f"{result.count('done')} processed, "
        f"{result.count('skipped')} up to date, {failed} failed "
        f"in {_clock(time.monotonic() - start)} -> {names} in {Path(outdir)}"
    )
    if failed:
        first = next(o for o in result.outcomes if o.status == "failed")
        click.echo(f"first failure: {first.subject}/{first.visit}: {first.error}", err=True)
        sys.exit(EXIT_SESSIONS_FAILED)


def _inputs(study: Manifest, calibration_dir: Path | None) -> list[Path | None]:
    """Every file and folder the study reads: the manifest, protocol, maps, recordings,
    references, marker maps and calibration folders."""
    paths: list[Path | None] = [study.path, study.protocol, study.map, calibration_dir]
    paths += [study.options.get("calibration_dir"), study.markers]
    for s in study.sessions:
        paths += [*s.files, s.reference, s.markers, s.map, s.options.get("calibration_dir")]
    return paths
