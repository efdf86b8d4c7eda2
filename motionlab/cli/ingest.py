"""``motionlab ingest``: recording files → one session file (common clock, QC, provenance)."""

from __future__ import annotations

import shlex

import click

from motionlab.atomic import check_output
from motionlab.cli.paths import INPUT_FILE, OUTPUT_FILE
from motionlab.errors import InputError
from motionlab.ingest import DEFAULT_GAP_MAX, ingest, unmatched_keys
from motionlab.lock import session_lock
from motionlab.qc import doubts
from motionlab.session import save_session


@click.command("ingest")
@click.argument("files", nargs=-1, required=True, type=INPUT_FILE)
@click.option(
    "--map",
    "map_path",
    type=INPUT_FILE,
    help="Sensor map YAML: segment/side/label per sensor, subject and reader options.",
)
@click.option(
    "--rate",
    type=float,
    default=None,
    metavar="HZ",
    help="Resample every stream onto the clock k/HZ.",
)
@click.option(
    "--gap-max",
    type=float,
    default=DEFAULT_GAP_MAX,
    show_default=True,
    metavar="S",
    help="Fill gaps up to S seconds; longer gaps are kept as missing and reported.",
)
@click.option(
    "-o",
    "--output",
    required=True,
    type=OUTPUT_FILE,
    help="Session file to write (HDF5).",
)
@click.option("--force", is_flag=True, help="Replace an existing output file.")
def command(files, map_path, rate, gap_max, output, force) -> None:  # fmt: skip
    """Read recording FILES into one session file.

    One file per sensor, one file with several sensors, or optical files (C3D, TRC) that become
    marker sets. All streams share one time origin (the earliest start = 0 s). Duplicate rows
    are dropped and one out-of-order stamp is repaired; gaps up to --gap-max are interpolated
    (SLERP for orientations), longer gaps stay missing and are listed by 'motionlab info'.

    \b
    Map file (--map):
      subject: {id: P017, height_m: 1.78}
      session: {date: 2024-05-02, protocol: knee}
      sensors:
        00B421ED: {segment: shank, side: right}
        00B421AF: {segment: thigh, side: r, label: thigh_r}
      reader: {format: generic, ...}   # options for every reader

    \b
    Example:
      motionlab ingest shank.txt thigh.txt --map map.yaml -o session.h5
      motionlab ingest trial/imu --map map.yaml -o session.h5   # x-IMU3 export folders
    """
    check_output(output, force, inputs=[*files, map_path])
    args = ["motionlab", "ingest", *files, "-o", output]
    for flag, value in (("--map", map_path), ("--rate", rate), ("--gap-max", gap_max)):
        args += [flag, str(value)] if value is not None else []
    args += ["--force"] if force else []
    session = ingest(files, map_path, rate=rate, gap_max=gap_max, command=shlex.join(args))
    try:
        with session_lock(output):  # one writer at a time (a stage command may be on it)
            save_session(session, output, force=force)
    except OSError as exc:
        raise InputError(f"cannot write the session ({exc.strerror or exc})", output,
                         remedy="choose a writable folder") from None  # fmt: skip
    for line in unmatched_keys(session):
        click.echo(f"warning: {line}", err=True)
    for s in session.sensors.values():
        place = " ".join(p for p in (s.side, s.segment) if p) or "unassigned"
        n_gaps = len(s.qc.get("gaps", []))
        click.echo(f"{s.label:<16} {place:<14} {s.rate_hz:8.2f} Hz {s.n_samples:>9} samples"
                   f"  gaps kept {n_gaps}, filled {s.qc.get('gaps_filled', 0)}")  # fmt: skip
        for line in doubts(s):
            click.echo(f"warning: {s.label}: {line}", err=True)
    for name, meta in session.metadata.get("files", {}).items():  # a file's own (APDM: many
        for note in meta.get("notes", []):  # sensors in one file, its repairs said once)
            if "truncated" in note:
                click.echo(f"warning: {name}: {note}", err=True)
    for m in session.markers.values():
        outputs = f", model outputs {len(m.model_outputs)}" if m.model_outputs else ""
        click.echo(f"{m.name:<16} markers {m.n_markers:>4}  {m.rate_hz:8.2f} Hz{outputs}")
        for line in m.attrs.get("warnings", []):
            click.echo(f"warning: {m.name}: {line}", err=True)
    click.echo(f"wrote {output}")
