"""``motionlab report``: the clinician PDF (and CSV tables) of analysed session files."""

from __future__ import annotations

from pathlib import Path

import click

from motionlab.atomic import refuse_input_as_output
from motionlab.cli.paths import FOLDER, INPUT_FILE, OUTPUT_FILE


@click.command("report")
@click.argument("sessions", nargs=-1, required=True, type=INPUT_FILE)
@click.option(
    "-o",
    "--output",
    required=True,
    type=OUTPUT_FILE,
    help="PDF file to write (its text goes beside it as .txt).",
)
@click.option(
    "--csv",
    "csv_dir",
    type=FOLDER,
    help="Also write the CSV tables into this folder.",
)
@click.option("--protocol", "protocol_path", help="Protocol (default: the calibration's).")
@click.option("--force", is_flag=True, help="Replace existing outputs.")
def command(sessions, output, csv_dir, protocol_path, force) -> None:
    """Write the report of analysed SESSIONS (from motionlab run, or calibrate + angles +
    metrics). Several sessions of one subject: each session's pages, then the progress over
    the visits.

    \b
    Example:
      motionlab report results/P017/session.h5 -o P017.pdf --csv P017_tables
      motionlab report visit1/session.h5 visit2/session.h5 -o P017_progress.pdf
    """
    from motionlab.lineage import refuse_stale
    from motionlab.protocol import load_protocol
    from motionlab.report import load_views, write_report
    from motionlab.session import load_session

    outputs = [Path(output), Path(output).with_suffix(".txt")]
    for out in outputs:
        refuse_input_as_output(out, [*sessions, protocol_path])
    protocol = load_protocol(protocol_path) if protocol_path else None
    paths = [Path(s) for s in sessions]
    loaded = [load_session(p) for p in paths]
    for path, ses in zip(paths, loaded, strict=True):  # a report never shows a stale result
        refuse_stale(ses, list(ses.lineage.stale(ses.results)), path)
    views = load_views(loaded, protocol, paths)
    out = write_report(views, output, csv_dir, force=force)
    click.echo(f"wrote {out.pdf_path} ({len(out.pages)} pages) and {out.text_path}")
    if out.csv_paths:
        click.echo(f"wrote {len(out.csv_paths)} tables into {csv_dir}")
