"""``motionlab validate``: IMU orientations and joint angles against optical motion capture."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from motionlab import stages
from motionlab.atomic import atomic_path, check_output
from motionlab.cli.paths import FOLDER, INPUT_FILE
from motionlab.errors import InputError
from motionlab.lock import session_lock
from motionlab.results import Validation
from motionlab.session import load_session, save_session
from motionlab.validation.align import MODES
from motionlab.validation.markermap import load_marker_map
from motionlab.validation.model_angles import load_angle_map
from motionlab.validation.reference import choose_marker_set, read_reference
from motionlab.validation.reference_kinds import REFERENCE_KINDS, load_reference, session_reference
from motionlab.validation.segment_csv import FRAMES
from motionlab.validation.tables import CSV_FILES, summary, tables
from motionlab.validation.time_offset import SYNC_SOURCES


@click.command("validate")
@click.argument("session", type=INPUT_FILE)
@click.option("--reference", "reference", type=INPUT_FILE,
              help="C3D/TRC/BROAD file or a session with markers, a C3D of model joint "
              "angles, or a CSV of segment quaternions (default: the session's own "
              "markers).")  # fmt: skip
@click.option("--reference-kind", type=click.Choice(REFERENCE_KINDS), default="auto",
              show_default=True, help="markers, segments (quaternion CSV) or angles (C3D "
              "POINT:ANGLES, e.g. Plug-in Gait); auto: from the file.")  # fmt: skip
@click.option("--frames", type=click.Choice(FRAMES), default="anatomical", show_default=True,
              help="Segment CSV: its quaternions are anatomical segment frames (ISB) or "
              "arbitrary body frames.")  # fmt: skip
@click.option("--angle-map", "angle_map_path", type=INPUT_FILE, help="Model-angle reference: "
              "YAML 'column: {label, component, sign}' (default: Plug-in Gait).")  # fmt: skip
@click.option("--sync-on", type=click.Choice(SYNC_SOURCES), default="gyroscope",
              show_default=True, help="IMU signal of the clock sync: the gyroscope (as interval "
              "averages) or the orientations' angular velocity.")  # fmt: skip
@click.option("--static", "static_path", type=INPUT_FILE,
              help="Static trial (C3D/TRC/session) showing the clusters and landmarks "
              "(default: a still window of the reference).")  # fmt: skip
@click.option("--markers", "markers_path", type=INPUT_FILE,
              help="Marker map YAML (default: markers by name).")  # fmt: skip
@click.option("--protocol", "protocol_path", help="Protocol (default: the calibration's).")
@click.option("--mode", type=click.Choice(MODES), help="Alignment: full (9-D), heading (6-D: "
              "vertical shared), none [default: full after 9-D fusion, else heading].")  # fmt: skip
@click.option("--no-sync", is_flag=True, help="The streams already share one clock.")
@click.option("--movement-only", is_flag=True, help="Statistics over movement phases only.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Random seed (the RANSAC clock fit).")  # fmt: skip
@click.option("--csv", "csv_dir", type=FOLDER, help="Write CSV tables here.")
@click.option("--json", "as_json", is_flag=True, help="Print the results as JSON.")
@click.option("--force", is_flag=True, help="Replace existing validation results and CSV files.")
def command(
    session: str,
    reference: str | None,
    reference_kind: str,
    frames: str,
    angle_map_path: str | None,
    sync_on: str,
    static_path: str | None,
    markers_path: str | None,
    protocol_path: str | None,
    mode: str | None,
    no_sync: bool,
    movement_only: bool,
    seed: int,
    csv_dir: str | None,
    as_json: bool,
    force: bool,
) -> None:
    """Compare SESSION with an optical reference: clock sync, frame alignment, orientation
    errors and joint-angle agreement; results go into the session for the report.

    \b
    Example:
      motionlab validate session.h5 --reference trial.c3d --markers map.yaml --json
      motionlab validate session.h5 --reference walk.c3d --static static.c3d
      motionlab validate broad.h5 --mode none --no-sync --movement-only
      motionlab validate session.h5 --reference pig.c3d --reference-kind angles  # PiG angles
      motionlab validate session.h5 --reference segments.csv     # time, thigh_r_qw, ...
    """
    with session_lock(session):  # read-modify-write: one writer at a time
        ses = load_session(session)
        done = ses.results.validation is not None
        stages.refuse_to_redo(done, "validation", "validation results", force, session)
        mmap = load_marker_map(markers_path) if markers_path else None
        name = mmap.marker_set if mmap else None
        if angle_map_path and reference_kind == "auto":  # a map of model angles tells the kind
            reference_kind = "angles"
        if reference is None:
            ref, kind = session_reference(ses, reference_kind, name, session)
        else:
            ref, kind = load_reference(reference, reference_kind, name)
        angle_map = load_angle_map(angle_map_path) if angle_map_path else None
        static = None
        if static_path is not None:
            sets = read_reference(static_path)
            static = choose_marker_set(
                sets, name if name in {m.name for m in sets} else None, static_path
            )
        protocol = None
        if protocol_path is not None or ses.results.calibration is not None:
            protocol = stages.stage_protocol(ses, protocol_path, session)
        written = []
        extra_inputs = [reference, static_path, markers_path, protocol_path, angle_map_path]
        if csv_dir:
            folder = Path(csv_dir)
            if folder.exists() and not folder.is_dir():
                raise InputError(
                    "is not a folder", folder, remedy="give a folder for the CSV tables"
                )
            folder.mkdir(parents=True, exist_ok=True)
            for fname in CSV_FILES:
                check_output(folder / fname, force, inputs=[session, *extra_inputs])
        mode = mode or stages.validation_mode(ses)
        result = stages.validate(
            ses, protocol, ref, marker_map=mmap, static=static, mode=mode, clock=not no_sync,
            movement_only=movement_only, seed=seed, force=force, path=session,
            reference_kind=kind, frames=frames, angle_map=angle_map, sync_on=sync_on,
            record=False,
        )  # fmt: skip
        if csv_dir:
            for fname, table in tables(result).items():
                with atomic_path(folder / fname, force=force) as tmp:
                    table.to_csv(tmp, index=False, float_format="%.6g")
                written.append(str(folder / fname))
        inputs = [session] + [
            p for p in (reference, static_path, markers_path, angle_map_path) if p
        ]
        parameters = {
            "stage": "validate",
            "mode": mode,
            "reference_kind": kind,
            "sync": not no_sync,
            "sync_on": sync_on,
            "movement_only": movement_only,
            "seed": seed,
            "protocol": protocol.name if protocol else None,
        }
        ses.add_provenance(parameters=parameters, inputs=inputs)  # fmt: skip
        save_session(ses, session, force=True)
    if as_json:
        click.echo(json.dumps(summary(result), indent=2))
        return
    _print(result)
    if written:
        click.echo(f"wrote {', '.join(written)}")


def _num(value: float | None, fmt: str = ".2f") -> str:
    """``value`` formatted, ``n/a`` when it is not given (``None`` or not finite)."""
    return "n/a" if value is None or not math.isfinite(value) else format(value, fmt)


def _print(result: Validation) -> None:
    """The human-readable summary (degrees)."""
    sync = result.sync
    if sync.method != "none":
        ends = sync.ends_standard_error_s  # None: a file written before the ends were graded
        where = "ms" if ends is None else f"ms at the centre, ± {_num(1e3 * ends)} ms at the ends"
        click.echo(
            f"clock: offset {sync.time_offset_s:.4f} s, drift {sync.drift_words()}, "
            f"inliers {_num(sync.inlier_ratio, '.0%')}, ± {_num(1e3 * sync.standard_error_s)} "
            f"{where} ({sync.grade}; {sync.method})"
        )
    else:
        click.echo("clock: not synchronised (--no-sync)")
    al = result.alignment
    if result.reference.kind == "model_angles":
        mapping = result.reference.mapping or {}
        click.echo(
            "reference: model joint angles " + ", ".join(f"{k} = {v}" for k, v in mapping.items())
        )
    elif al is not None:
        click.echo(f"alignment ({al.mode}): lab → earth {al.lab_to_earth.angle_deg:.2f}°")
    for label, o in result.orientation.sensors.items():
        if o.withheld:
            click.echo(f"{label:<16} not stated: {o.withheld}")
            continue
        click.echo(
            f"{label:<16} total {_num(o.total_rmse_deg)}°  heading "
            f"{_num(o.heading_rmse_deg)}°  inclination {_num(o.inclination_rmse_deg)}°  "
            f"median {_num(o.median_deg)}°"
        )
    for col, a in (result.angles.columns if result.angles is not None else {}).items():
        if a.withheld:
            click.echo(f"{col:<30} not stated: {a.withheld}")
            continue
        lo, hi = a.loa_deg
        click.echo(
            f"{col:<30} RMSE {_num(a.rmse_deg)}°  offset-free {_num(a.rmse_centred_deg)}°  "
            f"bias {_num(a.bias_deg, '+.2f')}°  "
            f"LoA [{_num(lo, '+.1f')}, {_num(hi, '+.1f')}]°  r {_num(a.r, '.3f')}  "
            f"CMC {_num(a.cmc, '.3f')}"
        )
    for note in result.notes:
        click.echo(f"note: {note}")
