"""``motionlab fuse``: orientation of every sensor by a registered estimator."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import click

from motionlab import stages
from motionlab.atomic import check_output
from motionlab.cli.paths import FOLDER, INPUT_FILE, OUTPUT_FILE
from motionlab.errors import InputError
from motionlab.fusion import registry
from motionlab.fusion.stage import fusable
from motionlab.lock import session_lock
from motionlab.session import load_session, save_session


def parse_params(items: tuple[str, ...]) -> dict[str, str]:
    """``("beta=0.1", ...)`` → ``{"beta": "0.1"}`` (values are converted by the registry)."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise InputError(f"--param {item!r} is not key=value", remedy="e.g. --param beta=0.1")
        out[key.strip()] = value.strip()
    return out


def _progress(labels: list[str], text: str) -> Iterator[str]:
    """A progress bar on stderr over the sensors, shown on a terminal only (a log or a pipe
    gets one line per outcome: the result, or the error)."""
    if not sys.stderr.isatty():
        yield from labels
        return
    with click.progressbar(labels, label=text, file=sys.stderr) as bar:
        yield from bar


@click.command("fuse")
@click.argument("session", type=INPUT_FILE, required=False)
@click.option(
    "--filter", "name", default=stages.ESTIMATOR, show_default=True, help="Estimator name."
)
@click.option(
    "--param",
    "params",
    multiple=True,
    help="Estimator parameter key=value (repeat), in SI units as --list shows them "
    "(angles in rad, rates in rad/s).",
)
@click.option("--sensor", "labels", multiple=True, help="Sensor label (repeat; default: all).")
@click.option("--force", is_flag=True, help="Replace existing fusion results or output file.")
@click.option("-o", "--output", type=OUTPUT_FILE, help="Write here, not in place.")
@click.option("--list", "list_", is_flag=True, help="List the estimators and their parameters.")
@click.option(
    "--calibration",
    type=FOLDER,
    help="Folder of per-serial sensor calibrations (motionlab sensorcal) to apply first.",
)
@click.option(
    "--with-markers", is_flag=True, help="Fuse the session's marker clusters (Liu 2010) too."
)
@click.option("--markers", "markers_path", help="Marker map YAML (implies --with-markers).")
@click.option(
    "--magnetometer/--no-magnetometer",
    default=stages.MAGNETOMETER,
    show_default=True,
    help="Use the magnetometers (9-D); the default fuses 6-D (gyr + acc), as motionlab run.",
)
@click.option(
    "--orientation",
    type=click.Choice(stages.ORIENTATIONS),
    default="fused",
    show_default=True,
    help="'vendor': keep the orientation the sensors carry (their own fusion) instead of fusing.",
)
def command(
    session: str | None,
    name: str,
    params: tuple[str, ...],
    labels: tuple[str, ...],
    force: bool,
    output: str | None,
    list_: bool,
    calibration: str | None,
    with_markers: bool,
    markers_path: str | None,
    magnetometer: bool,
    orientation: str,
) -> None:
    """Estimate each sensor's orientation (sensor → ENU earth) and store it in the session.

    6-D (gyroscope and accelerometer) by default, as motionlab run: indoor fields turn a
    sensor's heading mid-task, and joint angles need only the heading of each segment relative
    to its neighbour, which calibrate aligns. Run motionlab sync first (a warning says so when
    the session has not been synchronised).

    \b
    Example:
      motionlab sync session.h5 --protocol knee && motionlab fuse session.h5
      motionlab fuse session.h5 --filter madgwick --param beta=0.1 --sensor shank_r --force
      motionlab fuse session.h5 --filter liu_gn --with-markers --markers map.yaml --force
      motionlab fuse session.h5 --magnetometer --force   # 9-D: a calibrated magnetometer outdoors
      motionlab fuse --list
    """
    if list_:
        click.echo(registry.describe())
        return
    if session is None:
        raise InputError("no session file given", remedy="motionlab fuse SESSION (or --list)")
    if output is not None:
        check_output(output, force, inputs=[session, markers_path])
    with session_lock(output or session):  # read-modify-write: one writer at a time
        ses = load_session(session)
        unknown = [lab for lab in labels if lab not in ses.sensors]
        if unknown:
            raise InputError(
                f"no sensor {', '.join(unknown)}",
                session,
                remedy=f"sensors are {', '.join(ses.sensors) or 'none'}",
            )
        chosen = list(labels) or list(ses.sensors)
        usable = fusable(ses, chosen)
        if orientation == "vendor":  # sensors with their own orientation need no raw signals
            usable = [k for k in chosen if k in usable or ses.sensors[k].quat is not None]
        if labels and len(usable) < len(chosen):
            bad = sorted(set(chosen) - set(usable))
            raise InputError(
                f"sensor {', '.join(bad)} has no gyroscope or accelerometer",
                session,
                remedy="fusion needs both",
            )
        if not usable:
            raise InputError("no sensor has gyroscope and accelerometer data", session)
        parsed = parse_params(params)
        mmap = None
        if markers_path:
            from motionlab.validation.markermap import load_marker_map

            mmap = load_marker_map(markers_path)
        unsynced = not stages.synced(ses)  # said after the checks: an error comes first
        fused = stages.fuse(
            ses,
            name,
            parsed,
            usable,
            magnetometer=magnetometer,
            calibration_dir=calibration,
            markers=with_markers or markers_path is not None,
            marker_map=mmap,
            force=force,
            path=session,
            progress=_progress,
            orientation=orientation,
            record=False,
        )
        done, notes = list(fused), stages.fusion_notes(ses, list(fused), calibration)
        fusion = ses.results.fusion
        with_refs = any(fusion[k].markers is not None for k in done)
        ses.add_provenance(
            parameters={"stage": "fuse", "filter": name, "params": parsed, "sensors": done}
            | ({"calibration": calibration} if calibration else {})
            | ({"with_markers": True, "markers": markers_path} if with_refs else {})
            | {"magnetometer": magnetometer, "orientation": orientation},
            inputs=[session] + ([markers_path] if markers_path else []),
        )
        save_session(ses, output or session, force=True)
    if unsynced:
        click.echo(
            "warning: the session has not been clock-synchronised: run 'motionlab sync SESSION "
            "--protocol NAME' first, as motionlab run does (sensors on one radio-synchronised "
            "clock can skip it)",
            err=True,
        )
    for label in chosen:
        state = "fused" if label in done else "skipped (no gyr/acc)"
        if label in done and fusion[label].name == "vendor":
            state = "vendor orientation kept"
        elif label in done:
            state += (
                " (9-D, magnetometer)" if fusion[label].magnetometer else " (6-D, no magnetometer)"
            )
        click.echo(f"{label:<16} {state}" + (f", {notes[label]}" if label in notes else ""))
