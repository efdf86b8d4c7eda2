"""``motionlab metrics``: range of motion, repetitions, cycle curves and out-of-plane metrics."""

from __future__ import annotations

import click

from motionlab.atomic import atomic_path, check_output
from motionlab.cli.paths import INPUT_FILE, OUTPUT_FILE
from motionlab.errors import InputError


def _parse_tasks(items: tuple[str, ...]) -> dict[str, tuple[float, float]] | None:
    """``("gait=95:150", ...)`` → ``{"gait": (95.0, 150.0)}``."""
    if not items:
        return None
    out = {}
    for item in items:
        name, _, rng = item.partition("=")
        start, _, end = rng.partition(":")
        try:
            t0, t1 = float(start), float(end)
        except ValueError:
            t0 = t1 = float("nan")
        if name and t0 >= t1:  # the form is right (NaN compares false)
            raise InputError(
                f"--task {item!r} starts at or after its end", remedy="give START < END (s)"
            )
        if not name or not t0 < t1:
            raise InputError(f"--task {item!r} is not NAME=START:END", remedy="e.g. gait=95:150")
        out[name] = (t0, t1)
    return out


@click.command("metrics")
@click.argument("session", type=INPUT_FILE)
@click.option("--csv", "csv_path", type=OUTPUT_FILE, help="Also write a CSV.")
@click.option("--protocol", "protocol_path", help="Protocol (default: the calibration's).")
@click.option(
    "--task",
    "tasks",
    multiple=True,
    help="Task time range NAME=START:END in s (repeat); default: found in the recording.",
)
@click.option("--force", is_flag=True, help="Replace existing metrics and CSV.")
def command(
    session: str,
    csv_path: str | None,
    protocol_path: str | None,
    tasks: tuple[str, ...],
    force: bool,
) -> None:
    """Per task, joint and plane: range of motion, peaks, repetitions, mean ± SD cycle curve;
    and the protocol's out-of-plane metrics (cross-talk, lumbar out-of-plane offset, trunk
    compensation, knee varus thrust and stance rotation).

    Needs a calibrated session (motionlab calibrate); the angles are computed as
    motionlab angles does, then low-passed at 6 Hz for the metrics (a sensor's wobble
    on the skin is not a peak of the joint). The CSV has one row per number:
    block, joint, angle, column, metric, percent, value, unit, grade (the angle's: determined,
    weak, not determined).

    \b
    Example:
      motionlab metrics session.h5 --csv metrics.csv
      motionlab metrics session.h5 --task gait=95:117 --task squat=120:131 --force
      (the blocks of the demo's knee session, motionlab-demo/knee/session.h5, by hand)
    """
    import numpy as np

    from motionlab import stages
    from motionlab.kinematics.metrics import metrics_table, protocol_columns
    from motionlab.lock import session_lock
    from motionlab.segments.grades import column_grades, with_grades
    from motionlab.session import load_session, save_session

    if csv_path:
        check_output(csv_path, force, inputs=[session, protocol_path])
    with session_lock(session):  # read-modify-write: one writer at a time
        ses = load_session(session)
        result = stages.metrics(
            ses, protocol_path, _parse_tasks(tasks), force=force, path=session, record=False
        )
        protocol = stages.stage_protocol(ses, protocol_path, session)
        method = ses.results.angles.method if ses.results.angles is not None else "imu"
        table = metrics_table(result, protocol_columns(protocol))
        table = with_grades(table, protocol, ses.results.calibration, method)
        grades = column_grades(protocol, ses.results.calibration, method)
        if csv_path:
            with atomic_path(csv_path, force=force) as tmp:
                table.to_csv(tmp, index=False, float_format="%.4f")
        ses.add_provenance(parameters={"stage": "metrics", "protocol": str(protocol.path)})
        save_session(ses, session, force=True)
    for block, rng in result.blocks.items():
        click.echo(f"task {block:<20} {rng.start_s:8.2f}–{rng.end_s:8.2f} s")
        for col, m in result.joints[block].items():
            if not np.isfinite(m.rom_deg):
                continue
            click.echo(
                f"  {col:<32} ROM {m.rom_deg:6.1f}  min {m.min_deg:6.1f}  "
                f"max {m.max_deg:6.1f}  cycles {m.repetitions}  {grades.get(col, '')}".rstrip()
            )
    click.echo(f"{len(table)} rows" + (f" written to {csv_path}" if csv_path else ""))
