"""``motionlab sync``: put IMUs recorded on their own clocks on one clock."""

from __future__ import annotations

import click

from motionlab.cli.paths import INPUT_FILE


@click.command("sync")
@click.argument("session", type=INPUT_FILE)
@click.option("--protocol", "protocol_path", required=True, help="Protocol YAML file or name.")
@click.option("--force", is_flag=True, help="Redo an earlier synchronisation.")
def command(session: str, protocol_path: str, force: bool) -> None:
    """Estimate each IMU's clock offset and drift against its neighbour's and correct the stamps.

    Two segments joined at a joint feel the same acceleration at the joint centre; the clock
    shift that makes the two sensors agree on it is fitted for every pair of neighbours (the
    protocol's joints, pelvis-thigh, thorax-upper arm, ...). In gait the heel strikes time every
    pair of sensors too, and all clocks are solved at once, a measurement that disagrees with the
    others set aside; each line says what timed the sensor. Corrections are applied only where
    reliable and non-zero; the recorded stamps can be restored with --force and are kept in each
    sensor's attributes. The first stage after ingest: run it before fuse (motionlab run does).

    \b
    Example:
      motionlab sync session.h5 --protocol knee
    """
    from motionlab import stages
    from motionlab.clocksync import describe
    from motionlab.lock import session_lock
    from motionlab.protocol import load_protocol
    from motionlab.session import load_session, save_session

    protocol = load_protocol(protocol_path)
    with session_lock(session):  # read-modify-write: one writer at a time
        ses = load_session(session)
        fits = list(
            stages.sync(ses, protocol, force=force, path=session, record=False).fits.values()
        )
        ses.add_provenance(parameters={"protocol": str(protocol.path), "stage": "sync"})
        save_session(ses, session, force=True)
    if not fits:
        click.echo("no pair of neighbouring segments with sensors: nothing to synchronise")
    for fit in fits:
        click.echo(describe(fit))
