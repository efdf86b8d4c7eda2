"""``motionlab angles``: knee, elbow and lumbar joint angles of a calibrated session."""

from __future__ import annotations

import click

from motionlab.atomic import atomic_path, check_output
from motionlab.cli.paths import INPUT_FILE, OUTPUT_FILE


@click.command("angles")
@click.argument("session", type=INPUT_FILE)
@click.option("--csv", "csv_path", type=OUTPUT_FILE, help="Also write a CSV.")
@click.option(
    "--method",
    type=click.Choice(["imu", "accel-only"]),
    default="imu",
    show_default=True,
    help="imu: fused orientations; accel-only: elbow from accelerometers only (Lee 2012).",
)
@click.option("--protocol", "protocol_path", help="Protocol (default: the calibration's).")
@click.option("--no-calibration", is_flag=True, help="Use sensor frames as segment frames.")
# run's option (pipeline.PipelineOptions.angle_lowpass_hz) spelled out, so that --help does not
# import the pipeline; tests/test_cli_flags.py checks that the two default alike
@click.option(
    "--angle-lowpass",
    "angle_lowpass_hz",
    type=int,
    help="Low-pass the joint angles at this many Hz (zero-phase; a sensor's wobble on the skin "
    "is not the joint moving); 0 keeps them as computed [default: the protocol's "
    "angle_lowpass_hz, else 6].",
)
@click.option("--force", is_flag=True, help="Replace existing angles and CSV.")
def command(
    session: str,
    csv_path: str | None,
    method: str,
    protocol_path: str | None,
    no_calibration: bool,
    angle_lowpass_hz: int | None,
    force: bool,
) -> None:
    """Compute joint angles (degrees) and store them in the session.

    \b
    Example:
      motionlab angles session.h5 --csv angles.csv
      motionlab angles session.h5 --angle-lowpass 0 --force   # as computed, unfiltered
    """
    import numpy as np
    import pandas as pd

    from motionlab import stages
    from motionlab.lock import session_lock
    from motionlab.segments.grades import NOT_DETERMINED, column_grades
    from motionlab.session import load_session, save_session

    if csv_path:
        check_output(csv_path, force, inputs=[session, protocol_path])
    with session_lock(session):  # read-modify-write: one writer at a time
        ses = load_session(session)
        table = stages.angles(
            ses,
            protocol_path,
            method=method,
            calibrated=not no_calibration,
            angle_lowpass_hz=angle_lowpass_hz,
            force=force,
            path=session,
            record=False,
        )
        protocol = stages.stage_protocol(ses, protocol_path, session)
        grades = (
            column_grades(protocol, ses.results.calibration, method) if not no_calibration else {}
        )
        if csv_path:  # an angle not determined is an empty column, as in run's csv/
            columns = {
                c: np.where(grades.get(c) == NOT_DETERMINED, np.nan, v)
                for c, v in table.columns().items()
            }
            with atomic_path(csv_path, force=force) as tmp:
                pd.DataFrame(columns).to_csv(tmp, index=False, float_format="%.4f")
        lowpass = table.lowpass_hz
        ses.add_provenance(
            parameters={"stage": "angles", "method": method, "angle_lowpass_hz": lowpass}
        )
        save_session(ses, session, force=True)
    click.echo(f"{len(table.time)} samples, {len(table.data)} angles")
    for c, v in table.data.items():
        grade = grades.get(c, "not graded (sensor frames)" if no_calibration else "")
        if grade == NOT_DETERMINED:  # withheld, as in the CSV and the report
            click.echo(f"{c:<34} min {'-':>8}  max {'-':>8}  {grade}")
            continue
        click.echo(f"{c:<34} min {np.nanmin(v):8.1f}  max {np.nanmax(v):8.1f}  {grade}".rstrip())
