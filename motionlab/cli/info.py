"""``motionlab info``: a readable (or JSON) summary of a session file."""

from __future__ import annotations

import json
import math

import click

from motionlab.cli.paths import INPUT_FILE
from motionlab.lineage import rerun_commands
from motionlab.sensor_map import unmatched_place


@click.command("info")
@click.argument("session", type=INPUT_FILE)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def command(session: str, as_json: bool) -> None:
    """Summarise a session file: sensors, rates, gaps, QC flags, markers, results.

    \b
    Example:
      motionlab info session.h5
      motionlab info session.h5 --json
    """
    from motionlab.cli.flags import to_flags  # the run options' table: the pipeline
    from motionlab.session import load_session
    from motionlab.summary import session_summary

    ses = load_session(session)
    summary = session_summary(ses)
    if summary.get("stale"):  # runnable as printed: the file, the protocol, the flags
        commands = rerun_commands(ses, summary["stale"], list(summary["stale"]), session)
        summary["rerun"] = to_flags(commands, ("force", "protocol"))
    if as_json:
        click.echo(json.dumps(_no_nan(summary), indent=2, default=float))
        return
    click.echo(format_summary(summary))


def _no_nan(value):
    """NaN/inf → null, so that the JSON is standard."""
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_no_nan(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _fmt(value, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def _spans(spans: list, limit: int = 4) -> str:
    text = ", ".join(f"{a:.2f}–{b:.2f} s" for a, b in spans[:limit])
    return text + (f" and {len(spans) - limit} more" if len(spans) > limit else "")


#: a sensor starting this long (s) after the session's first sample is told so
LATE_START_S = 1.0


def _sensor_lines(s: dict) -> list[str]:
    qc = s["qc"]
    place = " ".join(p for p in (s["side"], s["segment"]) if p) or "unassigned"
    lines = [
        f"  {s['label']:<16} {place:<14} {_fmt(s['rate_hz'], '8.2f')} Hz"
        f"  {s['n_samples']:>8} samples  {s['duration_s']:8.2f} s  {','.join(s['channels'])}"
    ]
    if (s.get("start_s") or 0.0) > LATE_START_S:  # streams that do not start together
        lines.append(f"    starts at {s['start_s']:.2f} s of the session")
    if qc:
        clock = f"    clock: jitter {_fmt(qc.get('jitter_ms'), '.3f')} ms"
        if qc.get("dropped_samples"):
            clock += (
                f", {qc['dropped_samples']} samples missing ({qc.get('gaps_filled', 0)} short"
                f" gaps filled, {len(s['gaps'])} kept)"
            )
        repairs = [
            f"{qc[k]} {k.replace('_', ' ')}"
            for k in (
                "duplicates_dropped",
                "reordered",
                "restamped",
                "nan_time_dropped",
                "nan_rows_dropped",
            )
            if qc.get(k)
        ]
        if repairs:
            clock += "; repaired: " + ", ".join(repairs)
        if qc.get("resampled_to_hz"):
            clock += f"; resampled to {qc['resampled_to_hz']:g} Hz"
        lines.append(clock)
    if s["gaps"]:
        lines.append(f"    gaps kept as missing: {_spans(s['gaps'])}")
    for ch, spans in qc.get("nan_spans", {}).items():
        lines.append(f"    NaN in {ch}: {_spans(spans)}")
    flags = [k for k, v in s["flags"].items() if v]
    lines.append(f"    qc flags: {', '.join(flags) if flags else 'none'}")
    if s["flags"].get("held_samples"):
        lines.append(
            f"    held samples: {100 * qc['held_share']:.0f} % of the rows repeat the previous one,"
            f" ≈ {qc['effective_rate_hz']:.0f} Hz real"
        )
    if qc.get("identical_to"):
        lines.append(f"    identical to: {', '.join(qc['identical_to'])} (the same data twice?)")
    notes = list(s.get("notes", []))
    if s["flags"].get("rate_assumed"):
        assumed = [n for n in notes if "assumed" in n] or ["the file gives no rate"]
        lines.append(f"    rate assumed: {assumed[0]}")
        notes = [n for n in notes if n != assumed[0]]
    lines += [f"    note: {n}" for n in notes]  # what the reader did not read or assumed
    return lines


def format_summary(summary: dict) -> str:
    """Plain-text rendering of :func:`~motionlab.summary.session_summary`."""
    meta = summary["metadata"]
    lines = [f"motionlab session (schema {summary['schema_version']})"]
    for key in ("subject", "session"):
        if meta.get(key):
            lines.append(f"  {key}: " + ", ".join(f"{k}={v}" for k, v in meta[key].items()))
    files = meta.get("files", {})
    if files:
        lines.append(f"  files: {len(files)}")
        lines += [f"    {name} ({info.get('format', '?')})" for name, info in files.items()]
    if "time_origin_s" in meta:
        lines.append(f"  time origin: {meta['time_origin_s']:.6f} s (source clock) = 0 s here")
    if meta.get("clocks_unrelated"):
        lines.append(
            f"  warning: starts differ by {meta['start_spread_s']:.0f} s: the files do not share"
            " a clock, synchronise the streams before comparing them"
        )
    for entry in meta.get("map_unmatched", []):
        where = unmatched_place(entry)
        lines.append(f"  warning: sensor map key '{entry['key']}'{f' ({where})' if where else ''}"
                     " named no sensor in the input files")  # fmt: skip
    shown = ("subject", "session", "files", "time_origin_s", "start_spread_s", "clocks_unrelated",
             "map_unmatched")  # fmt: skip
    for key, value in meta.items():
        if key not in shown:
            lines.append(f"  {key}: {value}")
    lines.append(f"sensors: {len(summary['sensors'])}")
    for s in summary["sensors"]:
        lines += _sensor_lines(s)
    lines.append(f"marker sets: {len(summary['markers'])}")
    for m in summary["markers"]:
        lines.append(
            f"  {m['name']:<16} {_fmt(m['rate_hz'], '8.2f')} Hz  {m['n_markers']} markers"
            f"  {m['n_frames']} frames  unit {m['units']}"
        )
        if m.get("subjects"):
            lines.append(f"    subjects (label prefixes stripped): {', '.join(m['subjects'])}")
        for kind, o in m.get("model_outputs", {}).items():
            units = ", ".join(u or "unit not given" for u in o["units"])
            names = ", ".join(o["names"][:4]) + (" …" if o["count"] > 4 else "")
            lines.append(f"    model outputs, {kind}: {o['count']} ({units}): {names}")
        flags = [k for k, v in m.get("flags", {}).items() if v]
        lines.append(f"    qc flags: {', '.join(flags) if flags else 'none'}")
        lines += [f"    warning: {w}" for w in m.get("warnings", [])]
    if summary["results"]:
        lines.append(f"results: {', '.join(summary['results'])}")
    stale = summary.get("stale", {})
    for stage, why in stale.items():
        lines.append(f"  stale: {stage} ({why})")
    if stale and summary.get("rerun"):
        lines.append(f"  to bring them up to date: {summary['rerun']}")
    lines.append(f"provenance entries: {len(summary['provenance'])}")
    for p in summary["provenance"]:
        lines.append(f"  {p.get('time', '')}  {p.get('software', '')}  {p.get('command', '')}")
    return "\n".join(lines)
