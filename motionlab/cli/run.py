"""``motionlab run``: the whole analysis in one command (see :mod:`motionlab.pipeline`)."""

from __future__ import annotations

from pathlib import Path

import click

from motionlab import stages
from motionlab.atomic import atomic_path, check_output
from motionlab.cli.paths import FOLDER, INPUT_FILE
from motionlab.pipeline import RESULTS_JSON, PipelineOptions, run_pipeline


@click.command("run")
@click.argument("files", nargs=-1, required=True, type=INPUT_FILE)
@click.option("--protocol", "protocol", required=True, help="Protocol YAML file or packaged name.")
@click.option(
    "--map",
    "map_path",
    type=INPUT_FILE,
    help="Sensor map YAML for raw recordings (see 'motionlab ingest --help').",
)
@click.option(
    "--reference",
    type=INPUT_FILE,
    help="Reference to validate against: markers (C3D, TRC, a session), a CSV of segment "
    "quaternions or a C3D of model joint angles (see 'motionlab validate --help').",
)
@click.option(
    "--calibration",
    "calibration_dir",
    type=FOLDER,
    help="Folder of per-serial sensor calibrations (motionlab sensorcal) for fusion.",
)
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=FOLDER,
    help="Output folder: session.h5, report.pdf, report.txt, csv/, results.json.",
)
@click.option(
    "--filter",
    "estimator",
    default=stages.DEFAULT_ESTIMATOR,
    show_default=True,
    help="Estimator for the fusion stage (names: 'motionlab fuse --list').",
)
@click.option(
    "--magnetometer/--no-magnetometer",
    default=stages.MAGNETOMETER,
    help="Fuse with the magnetometers (default 6-D: indoor fields turn headings mid-task).",
)
@click.option(
    "--orientation",
    type=click.Choice(stages.ORIENTATIONS),
    default="fused",
    show_default=True,
    help="'vendor': use the orientation the sensors carry (their own fusion, a .sto) instead "
    "of fusing; recordings with orientations only always do.",
)
@click.option(
    "--clock-sync/--no-clock-sync",
    default=stages.CLOCK_SYNC,
    show_default=True,
    help="Put IMUs recorded on their own clocks on one clock (from the joints they share).",
)
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False),
    help="Also write the results JSON (as OUTDIR/results.json and 'motionlab export --to json').",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--force", is_flag=True, help="Replace existing outputs.")
@click.option("--quiet", is_flag=True, help="No progress on stderr.")
def command(
    files,
    protocol,
    map_path,
    reference,
    calibration_dir,
    estimator,
    magnetometer,
    orientation,
    clock_sync,
    outdir,
    json_path,
    seed,
    force,
    quiet,
) -> None:
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
      motionlab run --protocol knee sim.h5 -o results/sim --json sim_results.json
      motionlab run --protocol lumbar_seated --map protocols/examples/trunk_map.yaml \\
          trial/imu -o results/trunk
    """
    if json_path is not None:
        check_output(json_path, force, inputs=list(files))
    options = PipelineOptions(
        protocol=protocol,
        map_path=Path(map_path) if map_path else None,
        reference=Path(reference) if reference else None,
        calibration_dir=Path(calibration_dir) if calibration_dir else None,
        magnetometer=magnetometer,
        clock_sync=clock_sync,
        seed=seed,
        estimator=estimator,
        orientation=orientation,
        force=force,
        progress=not quiet,
    )
    result = run_pipeline([Path(f) for f in files], Path(outdir), options)
    if json_path is not None:  # the very bytes of OUTDIR/results.json
        with atomic_path(json_path, force=force) as tmp:
            tmp.write_bytes((Path(outdir) / RESULTS_JSON).read_bytes())
    click.echo(result.summary)
