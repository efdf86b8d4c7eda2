"""``motionlab run``: the whole analysis in one command (see :mod:`motionlab.pipeline`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from motionlab.atomic import atomic_path, check_output
from motionlab.cli import frozen_imports
from motionlab.cli.paths import FOLDER, INPUT_FILE
from motionlab.cli.run_options import run_click_options, run_values
from motionlab.pipeline import RESULTS_JSON, RUN_IMPORTS, PipelineOptions, run_pipeline


@click.command("run")
@click.argument("files", nargs=-1, required=True, type=INPUT_FILE)
@run_click_options
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=FOLDER,
    help="Output folder: session.h5, report.pdf, report.txt, csv/, results.json.",
)
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False),
    help="Also write the results JSON (as OUTDIR/results.json and 'motionlab export --to json').",
)
def command(files: tuple[str, ...], outdir: str, json_path: str | None, **params: Any) -> None:
    """Analyse recording FILES (or one session file) from raw data to the report.

    ingest → clock sync → sensor calibration (with --calibration) → fuse → calibrate → angles →
    metrics → validate (with --reference, or when the inputs hold markers) → report. Every
    intermediate result is kept in OUTDIR/session.h5; the report is OUTDIR/report.pdf with its
    text in report.txt and its tables in OUTDIR/csv/; OUTDIR/results.json holds the results
    for programs (as 'motionlab export --format json' writes them).

    \b
    Example:
      motionlab run --protocol knee --map map.yaml pelvis.txt thigh_r.txt thigh_l.txt \\
          shank_r.txt shank_l.txt --reference gait.c3d -o results/P017
      motionlab run --protocol knee sim.h5 -o results/sim
      motionlab run --protocol knee sim.h5 --filter madgwick -o results/sim_madgwick
      motionlab run --protocol walk --map map.yaml trial.sto --orientation vendor -o results/sto
      motionlab run --protocol knee sim.h5 -o results/sim_json --json sim_results.json
      motionlab run --protocol lumbar_seated --map protocols/examples/trunk_map.yaml \\
          trial/imu -o results/trunk
    """
    options = PipelineOptions(**run_values(params))
    if json_path is not None:
        check_output(json_path, options.force, inputs=list(files))
    with frozen_imports(*RUN_IMPORTS):
        result = run_pipeline([Path(f) for f in files], Path(outdir), options)
    if json_path is not None:  # the very bytes of OUTDIR/results.json
        with atomic_path(json_path, force=options.force) as tmp:
            tmp.write_bytes((Path(outdir) / RESULTS_JSON).read_bytes())
    click.echo(result.summary)
