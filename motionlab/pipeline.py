"""The whole analysis in one call: recordings → session → angles and metrics → report.

:func:`run_pipeline` chains the stages' library functions in memory, as the commands
``ingest``, ``fuse`` (``--calibration``), ``calibrate``, ``angles``, ``metrics`` and ``validate``
would one after the other, and writes into ``OUTDIR``:

- ``session.h5``: the session with every stage's results and the provenance log;
- ``report.pdf`` and ``report.txt`` (the report's text, page by page);
- ``csv/``: the report's CSV tables (:mod:`motionlab.report.csv`);
- ``results.json``: the machine-readable results (:func:`motionlab.export.results_json`, as
  ``motionlab export --format json`` writes them).

Inputs are raw recordings (any format :func:`motionlab.io.read_any` knows; optical files among
them become marker sets) or one motionlab session file (e.g. from ``motionlab simulate``). A
session file whose sensors have no ingest quality checks gets them here (clock repair, checks,
short gaps filled), as ingest does. Validation runs when a reference is given or the inputs hold
markers. Outputs that exist are replaced only with ``force``; all are checked before any work.
"""

from __future__ import annotations

import contextlib
import dataclasses
import shlex
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import pandas as pd

from motionlab import timebase
from motionlab.atomic import check_folder_writable, refuse_input_as_output
from motionlab.errors import InputError
from motionlab.fusion.stage import fusable, fuse_session
from motionlab.ingest import DEFAULT_GAP_MAX, check_and_fill, ingest
from motionlab.protocol import Protocol, load_protocol
from motionlab.segments import calibrate, sensor_for_segment
from motionlab.session import (
    FORMAT_NAME,
    SensorStream,
    Session,
    load_session,
    save_session,
    sha256_file,
)

SESSION_FILE = "session.h5"
REPORT_FILE = "report.pdf"
RESULTS_JSON = "results.json"
CSV_DIR = "csv"


@dataclass
class PipelineResult:
    """Where :func:`run_pipeline` wrote its outputs, the metrics and the one-screen summary.

    ``metrics`` has one row per joint metric (scalar rows of
    :func:`motionlab.kinematics.metrics.metrics_table`: ``block, joint, angle, metric, value,
    unit``; the cycle curves are left out).
    """

    session_path: Path
    report_path: Path
    csv_dir: Path
    metrics: pd.DataFrame
    summary: str


class _Stages:
    """A stage counter on stderr (``[3/7] calibrate ...``) and stage times; silent without
    ``progress``."""

    def __init__(self, names: list[str], progress: bool) -> None:
        self.names = names
        self.progress = progress
        self.times: dict[str, float] = {}

    @contextlib.contextmanager
    def __call__(self, name: str) -> Iterator[None]:
        if name not in self.names:  # a stage found necessary on the way (validate)
            self.names.insert(-1 if self.names else 0, name)
        k = self.names.index(name) + 1
        if self.progress:
            print(f"[{k}/{len(self.names)}] {name} ...", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        yield
        self.times[name] = time.perf_counter() - t0


def is_session_file(path: Path) -> bool:
    """Whether ``path`` is a motionlab session (HDF5 with the session format attribute)."""
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == FORMAT_NAME
    except OSError:
        return False


def _holds_markers(inputs: list[Path]) -> bool:
    """Whether the inputs hold optical data: a session with markers, or a C3D/TRC file."""
    from motionlab.io import detect_format

    for p in inputs:
        if not p.is_file():
            continue
        if is_session_file(p):
            with h5py.File(p, "r") as f:
                if len(f.get("markers", {})):
                    return True
        else:
            with contextlib.suppress(InputError):
                if detect_format(p) in ("c3d", "trc"):
                    return True
    return False


def prepare_sensors(session: Session, gap_max: float = DEFAULT_GAP_MAX) -> None:
    """Clock repair, quality checks and short-gap filling, as ingest does
    (:func:`motionlab.timebase.repair_clock`, :func:`motionlab.ingest.check_and_fill`), for the
    sensors of a session file that has not been through ingest (no ``qc``)."""
    for label, stream in list(session.sensors.items()):
        if not stream.qc:
            stream, report = timebase.repair_clock(stream)
            session.sensors[label] = check_and_fill(stream, report, gap_max)


def load_inputs(inputs: list[Path], map_path: Path | None, command: str) -> Session:
    """One session from raw recordings (ingest) or from one session file."""
    sessions = [p for p in inputs if p.is_file() and is_session_file(p)]
    if not sessions:
        return ingest(inputs, map_path, command=command)
    if len(inputs) > 1:
        raise InputError(
            "a session file cannot be combined with other inputs",
            sessions[0],
            remedy="give either raw recordings or one session file",
        )
    if map_path is not None:
        raise InputError(
            "--map applies to raw recordings; a session file already names its sensors",
            map_path,
            remedy="leave out --map, or ingest the raw files with it",
        )
    session = load_session(sessions[0])
    prepare_sensors(session)
    session.add_provenance(command, {"stage": "load", "gap_max_s": DEFAULT_GAP_MAX}, sessions)
    return session


def check_segments(session: Session, protocol: Protocol, inputs: list[Path]) -> None:
    """Raise one clear error when required protocol segments have no sensor."""
    needed = [s for s, spec in protocol.segments.items() if spec.required]
    missing = [s for s in needed if sensor_for_segment(session, s) is None]
    if not missing:
        return
    labels = ", ".join(f"{k} ({s.segment})" if s.segment else k for k, s in session.sensors.items())
    gap = "none of them" if missing == needed else f"none on {', '.join(missing)}"
    raise InputError(
        f"the '{protocol.name}' protocol needs sensors on {', '.join(needed)}; the input has "
        f"{gap} (its sensors: {labels or 'none'})",
        inputs[0] if len(inputs) == 1 else None,
        remedy="map each sensor to its segment with --map map.yaml (see 'motionlab ingest --help')",
    )


def _announce(labels: list[str], text: str) -> list[str]:
    print(f"  {text}: {len(labels)} sensors", file=sys.stderr, flush=True)
    return labels


def _fuse(
    session: Session,
    calibrated: dict[str, SensorStream],
    progress: bool,
    magnetometer: bool,
    estimator: str = "default",
) -> None:
    """Every sensor with gyroscope and accelerometer by ``estimator``, as ``motionlab fuse``
    does; sensors in ``calibrated`` are fused from their corrected data (the session keeps the
    data as recorded)."""
    usable = fusable(session)
    if not usable:
        return
    recorded = dict(session.sensors)
    session.sensors.update(calibrated)
    try:
        fuse_session(
            session,
            estimator,
            sensors=usable,
            force=True,
            magnetometer=magnetometer,
            progress=_announce if progress else None,
        )
    finally:
        session.sensors = recorded
    for label, stream in calibrated.items():
        session.results["fusion"][label]["calibration"] = stream.attrs["calibration"]


def _validate(
    session: Session, protocol: Protocol, reference: Path | None, seed: int, shared_earth: bool
) -> None:
    """Validation against the reference; ``shared_earth``: the sensors were fused with their
    magnetometers (one earth frame), else each has its own heading (alignment mode heading)."""
    from motionlab.validation import validate
    from motionlab.validation.reference import choose_marker_set, read_reference

    marker_set = None
    if reference is not None:
        marker_set = choose_marker_set(read_reference(reference), None, reference)
        name, n = marker_set.name, 2
        while name in session.markers:
            name, n = f"{marker_set.name}_{n}", n + 1
        session.markers[name] = dataclasses.replace(marker_set, name=name)
    validate(session, marker_set, None, protocol, "full" if shared_earth else "heading", seed=seed)


def _check_estimator(name: str, magnetometer: bool) -> None:
    """Raise :class:`InputError` before any work for an unknown estimator, or one that needs the
    magnetometer when fusing 6-D."""
    from motionlab.fusion import registry

    est = registry.get(name)
    if est.needs_mag and not magnetometer:
        raise InputError(f"estimator '{name}' needs a magnetometer", remedy="add --magnetometer")


def _outputs(
    outdir: Path, force: bool, inputs: Sequence[Path | None] = ()
) -> tuple[Path, Path, Path]:
    """The output paths in ``outdir``, checked before any work: the folder (or the first
    folder above it that exists, where it will be created) writable, no output one of the
    ``inputs``, and none replaced without ``force``."""
    if outdir.exists() and not outdir.is_dir():
        raise InputError("is not a folder", outdir, remedy="give a folder for the outputs")
    session_path, report_path, csv_dir = (
        outdir / SESSION_FILE,
        outdir / REPORT_FILE,
        outdir / CSV_DIR,
    )
    for p in (session_path, report_path, report_path.with_suffix(".txt")):
        refuse_input_as_output(p, inputs)
    existing = outdir.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError("is not a folder", existing, remedy="give a folder for the outputs")
    check_folder_writable(existing, outdir)
    if outdir.is_dir() and not force:
        results = outdir / RESULTS_JSON
        for p in (session_path, report_path, report_path.with_suffix(".txt"), csv_dir, results):
            if p.exists():
                raise InputError("output exists", p, remedy="use --force to replace it")
    return session_path, report_path, csv_dir


def analyse(
    session: Session,
    protocol: Protocol,
    reference: Path | None = None,
    seed: int = 0,
    calibration_dir: Path | None = None,
    stages: _Stages | None = None,
    magnetometer: bool = False,
    clock_sync: bool = True,
    estimator: str = "default",
) -> None:
    """The stages after ingest, in memory: (clock sync) → (sensor calibration) → fuse →
    calibrate → angles → metrics → (validate, with ``reference`` or the session's own markers).
    Results go to ``session.results`` under the names the stage commands use.

    ``clock_sync`` puts sensors recorded on their own clocks on one clock
    (:func:`motionlab.clocksync.synchronise`; corrections only where reliable and non-zero).

    Fusion is 6-D (no magnetometer) unless ``magnetometer``: joint angles need the heading of
    each segment relative to its neighbour only, which the heading alignment gives
    (:func:`motionlab.segments.segment_orientations`), while indoors an uncalibrated or
    disturbed magnetometer made the default estimator turn a sensor's heading by 20-60° in the
    middle of a task (knee sessions simulated with the ``typical`` preset, seeds 0-9 at 100, 60
    and 50 Hz: with the magnetometer 3 of 30 had a knee rotation RMSE of 21-23°, without it none
    above 2°). Validation then aligns each sensor's heading separately (mode ``heading``).

    ``estimator`` names the fusion estimator (:func:`motionlab.fusion.registry.available`).
    """
    from motionlab.kinematics.gait import analyse_gait, sensed_protocol
    from motionlab.kinematics.metrics import is_gait, session_metrics
    from motionlab.kinematics.session_angles import session_angles

    protocol = sensed_protocol(protocol, session)
    stages = stages or _Stages([], progress=False)
    if clock_sync:
        from motionlab.clocksync import synchronise

        with stages("clock sync"):
            synchronise(session, protocol)
    calibrated: dict[str, SensorStream] = {}
    if calibration_dir is not None:
        from motionlab.sensorcal import apply_calibration_dir

        with stages("sensorcal"):
            usable = fusable(session)
            calibrated, _ = apply_calibration_dir(session.sensors, calibration_dir, usable)
    with stages("fuse"):
        _fuse(session, calibrated, stages.progress, magnetometer, estimator)
    with stages("calibrate"):
        cal = calibrate(session, protocol)
        for line in cal["warnings"] if stages.progress else []:
            print(f"warning: {line}", file=sys.stderr, flush=True)
        cal["protocol_path"] = str(protocol.path)
        session.results["calibration"] = cal
    with stages("angles"):
        corrections: dict = {}
        session.results["angles"] = session_angles(session, protocol, cal, corrections=corrections)
        session.results["angles"]["method"] = "imu"
        session.results["heading"] = corrections
    with stages("metrics"):
        session.results["metrics"] = session_metrics(session, protocol)
    if any(is_gait(t) for t in protocol.tasks):
        with stages("gait"):
            session.results["gait"] = analyse_gait(session, protocol)
    if reference is not None or session.markers:
        with stages("validate"):
            _validate(session, protocol, Path(reference) if reference else None, seed, magnetometer)


def run_pipeline(
    inputs: list[Path],
    protocol: Path | str,
    outdir: Path,
    map_path: Path | None = None,
    reference: Path | None = None,
    force: bool = False,
    progress: bool = True,
    seed: int = 0,
    calibration_dir: Path | None = None,
    magnetometer: bool = False,
    clock_sync: bool = True,
    estimator: str = "default",
) -> PipelineResult:
    """Ingest → (clock sync) → (sensor calibration) → fuse → calibrate → angles → metrics →
    (validate) → report.

    Parameters
    ----------
    inputs
        Raw recording files, or one motionlab session file.
    protocol
        Protocol YAML file or the name of a packaged protocol (``knee``).
    outdir
        Output folder (created): ``session.h5``, ``report.pdf``, ``report.txt``, ``csv/``,
        ``results.json``.
    map_path
        Sensor map YAML for raw recordings (segment and side of each sensor, subject).
    reference
        Optical reference (C3D, TRC or a session with markers) for the validation stage.
    force
        Replace existing outputs.
    progress
        Print the stage counter and fusion progress bar on stderr.
    seed
        Random seed of the stochastic steps (the validation's RANSAC clock fit).
    calibration_dir
        Folder of per-serial sensor calibrations (``motionlab sensorcal``) applied before fusion.
    magnetometer
        Fuse with the magnetometers (default 6-D, see :func:`analyse`).
    clock_sync
        Put the IMUs on one clock from their shared joint centres (see :func:`analyse`).
    estimator
        Fusion estimator name (``motionlab fuse --list``); checked before any work.
    """
    from motionlab.export import write_json
    from motionlab.kinematics.gait import sensed_protocol
    from motionlab.kinematics.metrics import metrics_table
    from motionlab.report import load_views, write_report

    t_start = time.perf_counter()
    inputs = [Path(p) for p in inputs]
    outdir = Path(outdir)
    if not inputs:
        raise InputError("no input files", remedy="give one or more recordings or a session file")
    proto = load_protocol(protocol)
    _check_estimator(estimator, magnetometer)
    session_path, report_path, csv_dir = _outputs(
        outdir, force, [*inputs, map_path, reference, proto.path]
    )
    command = shlex.join(
        ["motionlab", "run", "--protocol", str(protocol), *map(str, inputs), "-o", str(outdir)]
        + (["--map", str(map_path)] if map_path else [])
        + (["--reference", str(reference)] if reference else [])
        + (["--calibration", str(calibration_dir)] if calibration_dir else [])
        + (["--seed", str(seed)] if seed else [])
        + (["--filter", estimator] if estimator != "default" else [])
        + (["--magnetometer"] if magnetometer else [])
        + ([] if clock_sync else ["--no-clock-sync"])
    )
    names = ["ingest", "fuse", "calibrate", "angles", "metrics", "report"]
    if calibration_dir is not None:
        names.insert(1, "sensorcal")
    if clock_sync:
        names.insert(1, "clock sync")
    if reference is not None or _holds_markers(inputs):
        names.insert(-1, "validate")
    stages = _Stages(names, progress)

    with stages("ingest"):
        session = load_inputs(inputs, map_path, command)
        check_segments(session, proto, inputs)
        proto = sensed_protocol(proto, session)
    analyse(
        session,
        proto,
        reference,
        seed,
        calibration_dir,
        stages,
        magnetometer,
        clock_sync,
        estimator,
    )
    validated = "validation" in session.results
    session.add_provenance(
        command,
        parameters={
            "stage": "run",
            "protocol": str(proto.path),
            "protocol_sha256": sha256_file(proto.path),
            "seed": seed,
            "estimator": estimator,
            "magnetometer": magnetometer,
            "clock_sync": clock_sync,
            "validated": validated,
        },
    )
    outdir.mkdir(parents=True, exist_ok=True)
    save_session(session, session_path, force=force)
    with stages("report"):
        views = load_views([session], proto, [session_path])
        out = write_report(views, report_path, csv_dir, force=force)
        write_json(session, outdir / RESULTS_JSON, force=force)
    table = metrics_table(session.results["metrics"])
    metrics = table[table["percent"].isna()].drop(columns="percent").reset_index(drop=True)
    summary = run_summary(views[0], out, stages.times, time.perf_counter() - t_start)
    return PipelineResult(session_path, report_path, csv_dir, metrics, summary)


def grade_lines(view, width: int = 100) -> list[str]:
    """Summary lines on the angles' grades: how many the recording determined, then the weak
    and not determined ones by column name, grouped by reason (wrapped at ``width``)."""
    import textwrap

    from motionlab.report.model import grade_rows

    rows = grade_rows(view)
    good = sum(r["grade"] == "determined" for r in rows)
    lines = [f"  angles determined by the recording: {good}/{len(rows)}"]
    groups: dict[tuple[str, str], list[str]] = {}
    for r in rows:
        if r["grade"] != "determined":
            groups.setdefault((r["grade"], r["reason"]), []).append(r["column"])
    for (grade, reason), cols in groups.items():
        text = f"{grade}: {', '.join(cols)}" + (f" - {reason}" if reason else "")
        lines += textwrap.wrap(
            text, width, initial_indent="    ", subsequent_indent="      ", break_on_hyphens=False
        )
    return lines


def run_summary(view, report, times: dict[str, float], total_s: float) -> str:
    """One screen: subject, data, calibration, tasks, flexion ranges, validation, outputs."""
    from motionlab.report.model import (
        angle_grades,
        calibration_rows,
        grade_mark,
        quality_rows,
        rom_rows,
    )
    from motionlab.report.text import findings, span, task_name

    ses, proto = view.session, view.protocol
    q = quality_rows(view)
    flagged = sorted({f for r in q for f in r["flags"]})
    rate = q[0]["rate_hz"] if q else float("nan")
    lines = [
        f"motionlab run: {proto.name} ({proto.title}) - subject {view.subject}, {view.date}",
        f"  data: {len(ses.sensors)} sensors at {rate:.0f} Hz, {view.angles['time_s'][-1]:.0f} s;"
        f" quality flags: {', '.join(flagged) or 'none'}",
    ]
    fusion = {
        f"{e.get('name')}{'' if e.get('magnetometer', True) else ' (6-D, no magnetometer)'}"
        for e in ses.results.get("fusion", {}).values()
    }
    lines.append(f"  fusion: {', '.join(sorted(fusion)) or 'sensor orientations'}")
    synced = ses.results.get("clock_sync", {})
    if synced:
        moved = [f"{k} {1e3 * v['offset_s']:+.1f} ms" for k, v in synced.items()
                 if v["status"] == "applied"]  # fmt: skip
        lines.append(
            f"  clock sync: {', '.join(moved) if moved else 'no correction needed or reliable'}"
            f" ({len(synced)} sensor pairs checked)"
        )
    segs = {r["segment"]: r["segment_ok"] for r in calibration_rows(view)}
    bad = [s for s, ok in segs.items() if not ok]
    lines.append(
        f"  calibration: {len(segs) - len(bad)}/{len(segs)} segments ok"
        + (f"; check {', '.join(bad)}" if bad else "")
    )
    cal = ses.results.get("calibration", {})
    lines += [f"  warning: {w}" for w in cal.get("warnings", [])]
    tied = [
        f"{j} by its {h['source'].replace('_', ' ')} ({h['range_deg']:.1f}° range)"
        for j, h in ses.results.get("heading", {}).items()
        if h.get("anchors") and h.get("source") != "steps"
    ]
    if tied:
        lines.append("  heading tied by the joints: " + ", ".join(tied))
    lines += grade_lines(view)
    lines.append(
        "  tasks: "
        + ", ".join(f"{task_name(k)} {a:.0f}-{b:.0f} s" for k, (a, b) in view.blocks().items())
    )
    lines.append(_gait_line(ses.results.get("gait")))
    flexion = [r for r in rom_rows(view) if r["angle"] == "flexion"]
    if flexion:
        lines.append("  flexion range (typical, deg):")
    for r in flexion:
        normal = (
            f"normal {r['normal'][0]:g}-{r['normal'][1]:g}, {r['status'] or 'not compared'}"
            if r["normal"]
            else "no normal range"
        )
        lines.append(
            f"    {task_name(r['task']):<14} {r['joint']:<8} "
            f"{span(r['typical_min_deg'], r['typical_max_deg']):>10}  ({normal})"
            + (f" {grade_mark(r['grade'])}" if grade_mark(r["grade"]) else "")
        )
    val = ses.results.get("validation", {}).get("angles", {})
    grades = angle_grades(view)
    rmse = [
        f"{c.removesuffix('_deg')} {v['rmse_deg']:.1f}"
        + (f" {grade_mark(grades[c][0])}" if c in grades and grade_mark(grades[c][0]) else "")
        for c, v in val.items()
        if isinstance(v, dict) and "rmse_deg" in v
    ]
    if rmse:
        lines.append(
            f"  validation RMSE (deg): {', '.join(rmse[:6])}" + (" ..." if len(rmse) > 6 else "")
        )
    lines.append("  findings:")
    lines += [f"    - {f}" for f in findings(view, limit=4)]
    lines.append(f"outputs in {report.pdf_path.parent}:")
    lines.append(
        f"  {SESSION_FILE}, {report.pdf_path.name} ({len(report.pages)} pages), "
        f"{report.text_path.name}, {CSV_DIR}/ ({len(report.csv_paths)} tables), {RESULTS_JSON}"
    )
    steps = ", ".join(f"{k} {v:.1f}" for k, v in times.items())
    lines.append(f"time: {total_s:.1f} s ({steps})")
    return "\n".join(lines)


def _gait_line(gait: dict | None) -> str:
    """One summary line about gait: its main numbers, or why there are no gait pages."""
    if gait is None:
        return "  gait: none in this recording (the protocol has no gait task); no gait pages"
    if gait.get("status") != "ok":
        return f"  gait: {gait.get('status')}; no gait pages"
    s = gait["summary"]
    gps = gait.get("map", {}).get("gps", {}).get("overall", float("nan"))
    return (
        f"  gait: {s['strides_kept']} strides, cadence {s['cadence_steps_per_min']:.1f} steps/min,"
        f" step-time asymmetry {s['step_time_asymmetry_pct']:.1f} %, GPS {gps:.1f} deg"
    )
