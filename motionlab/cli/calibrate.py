"""``motionlab calibrate``: sensor-to-segment calibration from poses and movements."""

from __future__ import annotations

import click

from motionlab.cli.paths import INPUT_FILE


@click.command("calibrate")
@click.argument("session", type=INPUT_FILE)
@click.option("--protocol", "protocol_path", required=True, help="Protocol YAML file or name.")
@click.option("--force", is_flag=True, help="Replace an existing calibration.")
def command(session: str, protocol_path: str, force: bool) -> None:
    """Find the protocol's calibration steps, fit each segment's mounting, report quality.

    \b
    Example:
      motionlab calibrate session.h5 --protocol knee
    """
    from motionlab import stages
    from motionlab.lock import session_lock
    from motionlab.protocol import load_protocol
    from motionlab.results import SegmentQuality
    from motionlab.segments.steps import unfound_step
    from motionlab.session import load_session, save_session

    protocol = load_protocol(protocol_path)
    with session_lock(session):  # read-modify-write: one writer at a time
        ses = load_session(session)
        result = stages.calibrate(ses, protocol, force=force, path=session, record=False)
        ses.add_provenance(parameters={"protocol": str(protocol.path), "stage": "calibrate"})
        save_session(ses, session, force=True)
    for line in result.warnings:
        click.echo(f"warning: {line}", err=True)
    for name, rng in result.steps.items():
        where = (
            f"{rng[0]:7.2f}–{rng[1]:7.2f} s"
            if rng
            else unfound_step(name, protocol, result.single_pose)
        )
        click.echo(f"step {name:<22} {where}")
    for seg, res in result.segments.items():
        q = res.quality or SegmentQuality(ok=True)
        click.echo(
            f"{seg:<12} {res.method:<12} min ρ {q.min_rho:.2f}  " + ("ok" if q.ok else "CHECK")
        )
        for msg in q.messages:
            click.echo(f"  - {msg}")
    for joint, g in result.grades.items():
        click.echo(f"{joint:<12} angles: {', '.join(g.grades)}")
