"""``motionlab fuse``: orientation of every sensor by a registered estimator."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import click

from motionlab.atomic import check_output
from motionlab.cli.paths import FOLDER, INPUT_FILE, OUTPUT_FILE
from motionlab.errors import InputError
from motionlab.fusion import registry
from motionlab.fusion.stage import fusable, fuse_session
from motionlab.sensorcal.calfile import apply_calibration_dir
from motionlab.session import Session, load_session, save_session


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


def _marker_references(ses: Session, name: str, markers_path: str | None, labels: list[str]):
    """Marker reference vectors of the sensors that carry a cluster (``--with-markers``)."""
    from motionlab.fusion.marker_registration import session_references
    from motionlab.validation.markermap import load_marker_map

    if not registry.takes_references(name):
        takes = [k for k in registry.available() if registry.takes_references(k)]
        raise InputError(
            f"estimator '{name}' cannot fuse markers", remedy=f"use --filter {' or '.join(takes)}"
        )
    mmap = load_marker_map(markers_path) if markers_path else None
    return session_references(ses, mmap, labels=labels)


@click.command("fuse")
@click.argument("session", type=INPUT_FILE, required=False)
@click.option("--filter", "name", default="default", show_default=True, help="Estimator name.")
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
    default=True,
    show_default=True,
    help="Use the magnetometers; --no-magnetometer fuses 6-D (gyr + acc, arbitrary heading).",
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
) -> None:
    """Estimate each sensor's orientation (sensor → ENU earth) and store it in the session.

    \b
    Example:
      motionlab fuse session.h5
      motionlab fuse session.h5 --filter madgwick --param beta=0.1 --sensor shank_r
      motionlab fuse session.h5 --filter liu_gn --with-markers --markers map.yaml
      motionlab fuse session.h5 --no-magnetometer   # 6-D, e.g. indoors near steel
      motionlab fuse --list
    """
    if list_:
        click.echo(registry.describe())
        return
    if session is None:
        raise InputError("no session file given", remedy="motionlab fuse SESSION (or --list)")
    if output is not None:
        check_output(output, force, inputs=[session, markers_path])
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
    if not magnetometer and registry.get(name).needs_mag:
        raise InputError(
            f"estimator '{name}' needs a magnetometer", remedy="drop --no-magnetometer"
        )
    recorded, notes, calibrated = dict(ses.sensors), {}, {}
    if calibration is not None:  # fuse calibrated data; the session keeps the data as recorded
        calibrated, notes = apply_calibration_dir(ses.sensors, calibration, usable)
        ses.sensors.update(calibrated)
    refs, marker_info = {}, {}
    if with_markers or markers_path:
        refs, marker_info = _marker_references(ses, name, markers_path, usable)
    done = fuse_session(
        ses,
        name,
        parsed,
        usable,
        force=force,
        path=session,
        references=refs,
        magnetometer=magnetometer,
        progress=_progress,
    )
    ses.sensors = recorded
    for label, stream in calibrated.items():
        ses.results["fusion"][label]["calibration"] = stream.attrs["calibration"]
    for label in refs:
        record = marker_info["sensors"][label] | {"lab_to_earth": marker_info["lab_to_earth"]}
        ses.results["fusion"][label]["markers"] = record
        seen = f"markers seen {100 * record['visible_fraction']:.0f} %"
        notes[label] = f"{notes[label]}, {seen}" if label in notes else seen
    ses.add_provenance(
        parameters={"stage": "fuse", "filter": name, "params": parsed, "sensors": done}
        | ({"calibration": calibration} if calibration else {})
        | ({"with_markers": True, "markers": markers_path} if refs else {})
        | ({} if magnetometer else {"magnetometer": False}),
        inputs=[session] + ([markers_path] if markers_path else []),
    )
    save_session(ses, output or session, force=True)
    for label in chosen:
        state = "fused" if label in done else "skipped (no gyr/acc)"
        if label in done and not magnetometer:
            state += " (6-D, no magnetometer)"
        click.echo(f"{label:<16} {state}" + (f", {notes[label]}" if label in notes else ""))
