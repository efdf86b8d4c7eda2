"""``motionlab info``: a readable (or JSON) summary of a session file."""

from __future__ import annotations

import json

import click

from motionlab.session import load_session
from motionlab.summary import session_summary


@click.command("info")
@click.argument("session", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def command(session: str, as_json: bool) -> None:
    """Summarise a session file: sensors, rates, gaps, QC flags, markers, results.

    \b
    Example:
      motionlab info session.h5
      motionlab info session.h5 --json
    """
    summary = session_summary(load_session(session))
    if as_json:
        click.echo(json.dumps(summary, indent=2, default=float))
        return
    click.echo(format_summary(summary))


def format_summary(summary: dict) -> str:
    """Plain-text rendering of :func:`~motionlab.summary.session_summary`."""
    lines = [f"motionlab session (schema {summary['schema_version']})"]
    for key, value in summary["metadata"].items():
        lines.append(f"  {key}: {value}")
    lines.append(f"sensors: {len(summary['sensors'])}")
    for s in summary["sensors"]:
        place = " ".join(p for p in (s["side"], s["segment"]) if p) or "unassigned"
        lines.append(
            f"  {s['label']:<16} {place:<14} {s['rate_hz']:8.2f} Hz  {s['n_samples']:>8} samples"
            f"  {s['duration_s']:8.2f} s  {','.join(s['channels'])}"
        )
        if s["gaps"]:
            lines.append(f"    gaps: {len(s['gaps'])}")
        flags = [k for k, v in s["qc"].get("flags", {}).items() if v]
        if flags:
            lines.append(f"    qc flags: {', '.join(flags)}")
    lines.append(f"marker sets: {len(summary['markers'])}")
    for m in summary["markers"]:
        lines.append(
            f"  {m['name']:<16} {m['rate_hz']:8.2f} Hz  {m['n_markers']} markers"
            f"  {m['n_frames']} frames  unit {m['units']}"
        )
    if summary["results"]:
        lines.append(f"results: {', '.join(summary['results'])}")
    lines.append(f"provenance entries: {len(summary['provenance'])}")
    return "\n".join(lines)
