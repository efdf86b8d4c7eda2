"""``motionlab export``: a session's results for other tools (OpenSim, C3D readers, JSON)."""

from __future__ import annotations

from pathlib import Path

import click

from motionlab.atomic import check_output
from motionlab.errors import InputError
from motionlab.export import FORMATS, export_session
from motionlab.session import load_session


@click.command("export")
@click.argument("session", type=click.Path(dir_okay=False))
@click.option(
    "--to",
    "--format",
    "fmt",
    type=click.Choice(FORMATS),
    help="sto, mot, c3d or json (default: from the output's extension).",
)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="File.")
@click.option("--force", is_flag=True, help="Replace an existing output file.")
def command(session: str, fmt: str | None, output: str, force: bool) -> None:
    """Write SESSION's results in another tool's format.

    \b
    sto   sensor orientations for OpenSense (one w,x,y,z column per IMU, Z-up earth frame
          as OpenSense's readers write it: keep sensor_to_opensim_rotations = -1.5708 0 0)
    mot   joint angles as an OpenSim motion file (degrees, inDegrees=yes), with the
          Rajagopal model's coordinate names and signs where they map (knee_angle_r,
          hip_flexion_r, lumbar_extension, ...), motionlab's names for the others
    c3d   joint angles as POINT:ANGLES model outputs (deg) and the markers, if any (mm)
    json  machine-readable results: metadata, angles with grades, metrics, validation

    \b
    Example:
      motionlab export results/P017/session.h5 --to sto -o P017_orientations.sto
      motionlab export results/P017/session.h5 -o P017_angles.mot
      motionlab export results/P017/session.h5 --to json -o P017.json
    """
    fmt = fmt or Path(output).suffix.lstrip(".").lower()
    if fmt not in FORMATS:
        raise click.BadParameter(
            f"cannot tell the format from '{output}'; give --to {'|'.join(FORMATS)}",
            param_hint="--to",
        )
    check_output(output, force, inputs=[session])  # --force never replaces the session itself
    try:
        summary = export_session(load_session(session), fmt, output, force=force)
    except InputError as exc:  # what the session lacks: name the session
        if exc.path is not None:
            raise
        raise InputError(
            exc.message, session, exc.where, exc.remedy, exc.arguments or None
        ) from None
    click.echo(f"wrote {output}: {summary}")
