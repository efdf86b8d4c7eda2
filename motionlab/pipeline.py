"""The whole analysis in one call: recordings → session → angles and metrics → report.

:func:`run_pipeline` chains the stage functions of :mod:`motionlab.stages` in memory, the ones
the commands ``ingest``, ``sync``, ``fuse`` (``--calibration``), ``calibrate``, ``angles``,
``metrics`` and ``validate`` call one after the other, with the same defaults; every option is
in one :class:`PipelineOptions`. It writes into ``OUTDIR``:

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
import numbers
import shlex
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py

from motionlab import stages as stages_lib
from motionlab.atomic import (
    check_folder_writable,
    check_name_length,
    refuse_folder_in_input_folder,
    refuse_input_as_output,
)
from motionlab.binding import (
    check_joints,
    foreign_segments,
    sensed_protocol,
    sensor_for_segment,
    sensor_list,
    unsensed_joints,
)
from motionlab.errors import InputError
from motionlab.ingest import DEFAULT_GAP_MAX, ingest, unmatched_keys
from motionlab.lock import session_lock
from motionlab.protocol import Protocol, load_protocol
from motionlab.qc import doubts as qc_doubts
from motionlab.session import (
    MarkerSet,
    Session,
    is_session_file,
    load_session,
    save_session,
    sha256_file,
)

if TYPE_CHECKING:
    import pandas as pd

    from motionlab.validation.markermap import MarkerMap

SESSION_FILE = "session.h5"
REPORT_FILE = "report.pdf"
RESULTS_JSON = "results.json"
CSV_DIR = "csv"


@dataclass
class PipelineResult:
    """Where :func:`run_pipeline` wrote its outputs, the metrics and the one-screen summary.

    ``metrics`` has one row per joint metric (scalar rows of
    :func:`motionlab.kinematics.metrics.metrics_table`: ``block, joint, angle, column, metric,
    value, unit``; the cycle curves are left out), the ``grade`` of the row's angle
    (``determined``, ``weak``, ``not determined``; empty for a row of no angle column), its
    normal range and comparison as ``metrics.csv`` gives them and a ``note`` why it is not
    determined (:func:`motionlab.report.csv.with_normals`); a joint of the protocol dropped for
    a segment with no sensor has its rows too, empty, graded ``not measured``
    (:func:`motionlab.kinematics.metrics.with_not_measured`).
    ``gait``: the rows of ``spatiotemporal_summary.csv`` (cadence, stride and step times, ...
    per side, each withheld number's ``note``; :func:`motionlab.report.csv.gait_summary_frame`),
    None without a gait analysis.
    """

    session_path: Path
    report_path: Path
    csv_dir: Path
    metrics: pd.DataFrame
    summary: str
    gait: pd.DataFrame | None = None


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
    """Clock repair, quality checks and short-gap filling for the sensors of a session file that
    has not been through ingest (:func:`motionlab.stages.prepare`)."""
    stages_lib.prepare(session, gap_max)


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
            "map_path= applies to raw recordings; a session file already names its sensors",
            map_path,
            remedy="leave out map_path=, or ingest the raw files with it",
            argument="map_path",
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
        check_joints(protocol, session, inputs[0] if len(inputs) == 1 else None)
        return
    gap = "none of them" if missing == needed else f"none on {', '.join(missing)}"
    unmatched = [e["key"] for e in session.metadata.get("map_unmatched", [])
                 if e.get("segment") in missing]  # fmt: skip
    if unmatched:
        gap += f" (the sensor map's {', '.join(repr(k) for k in unmatched)} named no sensor)"
    foreign = foreign_segments(protocol, session)
    has = {seg for seg in protocol.segments if sensor_for_segment(session, seg)}
    joints = [j for j in protocol.joints.values() if {j.proximal, j.distal} <= has]
    if all(s.segment for s in session.sensors.values()) and not foreign and not joints:
        # no joint of the protocol has both its segments: making them optional measures nothing
        pairs = ", ".join(f"{j.proximal}–{j.distal}" for j in protocol.joints.values())
        remedy = (f"none of its joints ({pairs}) has sensors on both its segments, so no copy "
                  "of it measures this recording: record sensors on both segments of one of "
                  "them, or write a protocol with a joint between the segments "
                  "recorded")  # fmt: skip
    elif all(s.segment for s in session.sensors.values()) and not foreign:
        # every sensor is mapped to a segment of the protocol: the recording lacks the others
        remedy = (
            f"record sensors on {', '.join(missing)}, or copy the protocol and set "
            "'required: false' on the segments the recording has no sensor on"
        )
    else:
        form = map_form(session, missing)
        remedy = (f"map each sensor to its segment in a sensor map, map_path=map.yaml, of the "
                  f"form 'sensors: {form}' (docs/ingest.md, 'The map')")  # fmt: skip
    raise InputError(
        f"the '{protocol.name}' protocol needs sensors on {', '.join(needed)}; the input has "
        f"{gap}{foreign} (its sensors: {sensor_list(session)})",
        inputs[0] if len(inputs) == 1 else None,
        remedy=remedy,
        argument="map_path",
    )


def map_form(session: Session, missing: list[str]) -> str:
    """The sensor map a user has to write, in YAML's one-line form, with the recording's own
    sensor labels (at most three) and the segments to choose from: ``{Back: {segment: <pelvis or
    thorax>}, Chair: {segment: ...}, ...}``."""
    labels = [k for k, s in session.sensors.items() if not s.segment] or [*session.sensors]
    labels = labels or ["<sensor label>"]
    choice = " or ".join(missing) if len(missing) <= 3 else f"{missing[0]}, {missing[1]}, ..."
    entries = [f"{labels[0]}: {{segment: <{choice}>}}"]
    entries += [f"{k}: {{segment: ...}}" for k in labels[1:3]] + ["..."] * (len(labels) > 3)
    return "{" + ", ".join(entries) + "}"


def _announce(labels: list[str], text: str) -> list[str]:
    print(f"  {text}: {len(labels)} sensors", file=sys.stderr, flush=True)
    return labels


def _check_estimator(name: str, magnetometer: bool) -> None:
    """Raise :class:`InputError` before any work for an unknown estimator, or one that needs the
    magnetometer when fusing 6-D."""
    from motionlab.fusion import registry

    est = registry.get(name)
    if est.needs_mag and not magnetometer:
        raise InputError(
            f"estimator '{name}' needs a magnetometer",
            remedy="add magnetometer=True",
            argument="magnetometer",
        )


def _outputs(
    outdir: Path, force: bool, inputs: Sequence[Path | None] = ()
) -> tuple[Path, Path, Path]:
    """The output paths in ``outdir``, checked before any work: the folder (or the first
    folder above it that exists, where it will be created) writable, no output one of the
    ``inputs``, and none replaced without ``force``."""
    if outdir.exists() and not outdir.is_dir():
        raise InputError("is not a folder", outdir, remedy="give a folder for the outputs")
    check_name_length(outdir)
    session_path, report_path, csv_dir = (
        outdir / SESSION_FILE,
        outdir / REPORT_FILE,
        outdir / CSV_DIR,
    )
    for p in (session_path, report_path, report_path.with_suffix(".txt")):
        refuse_input_as_output(p, inputs)
    refuse_folder_in_input_folder(outdir, inputs)
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
                raise InputError(
                    "output exists", p, f"in {outdir}", "use force=True to replace it",
                    argument="force",
                )  # fmt: skip
    return session_path, report_path, csv_dir


@dataclass(frozen=True)
class RunOption:
    """How one field of :class:`PipelineOptions` is set from outside: the one table the click
    options of ``motionlab run`` and ``motionlab batch``, the CLI's flag table
    (``cli/flags.FLAGS``), the manifest keys (``batch/manifest.OPTION_KEYS``) and
    :meth:`PipelineOptions.command` are made from."""

    #: the flag (``--filter``); a boolean's ``--name/--no-name`` pair, or the one flag that
    #: turns it off (``--quiet`` for ``progress``, with ``kind="off"``)
    flag: str
    #: the ``--help`` text (``motionlab batch`` adds the default)
    help: str
    #: ``text``, ``int``, ``bool`` (a flag pair), ``flag`` (a flag alone), ``off`` (a flag that
    #: sets False), ``file`` (to read), ``folder``, ``choice`` (one of :attr:`choices`)
    kind: str = "text"
    choices: tuple[str, ...] = ()
    #: the study manifest's key (``filter``), or ``None``
    manifest: str | None = None
    #: also a ``motionlab batch`` flag and a manifest key for the study or one session
    batch: bool = False
    #: the stage commands that take the same flag (``tests/test_cli_flags.py`` checks them)
    stages: tuple[str, ...] = ()
    #: the ``--help`` shows the default
    show_default: bool = False
    #: the smallest value an ``int`` option takes, and what that value means (``None``: any)
    minimum: int | None = None
    minimum_means: str = ""

    def below_minimum(self) -> str:
        """What a value below :attr:`minimum` is told (checked before any work is done)."""
        means = f" ({self.minimum} {self.minimum_means})" if self.minimum_means else ""
        return f"expected {self.minimum} or more{means}"


def _option(default: Any, flag: str, help: str, **option: Any) -> Any:  # noqa: A002
    """A :class:`PipelineOptions` field (``default``; ``dataclasses.MISSING``: required) with
    its :class:`RunOption`."""
    return dataclasses.field(default=default, metadata={"option": RunOption(flag, help, **option)})


@dataclass(frozen=True)
class PipelineOptions:
    """Every option of ``motionlab run`` (and of each session of ``motionlab batch``); each
    field's flag, help text and manifest key are its :class:`RunOption` (:data:`RUN_OPTIONS`).

    protocol
        Protocol YAML file, the name of a packaged protocol (``knee``) or a loaded
        :class:`~motionlab.protocol.Protocol`.
    map_path
        Sensor map YAML for raw recordings (segment and side of each sensor, subject).
    reference
        Reference for the validation stage: markers (C3D, TRC or a session with markers), a CSV
        of segment quaternions or a C3D of model joint angles
        (:mod:`motionlab.validation.reference_kinds`).
    frames
        A segment-quaternion reference's frames: ``anatomical`` (ISB) or ``body`` (arbitrary,
        carried to the segments by the IMU calibration; :mod:`motionlab.validation.segment_csv`).
    markers_path
        Marker map YAML of the reference (:func:`motionlab.validation.markermap.load_marker_map`;
        default: markers by name).
    calibration_dir
        Folder of per-serial sensor calibrations (``motionlab sensorcal``) applied before fusion.
    seed
        Random seed of the stochastic steps (the validation's RANSAC clock fit).
    estimator
        Fusion estimator name (``motionlab fuse --list``; ``--filter``).
    orientation
        ``fused`` (default) or ``vendor``: use the orientation the sensors carry (the vendor's
        fusion, an OpenSense ``.sto``) instead of fusing (:func:`motionlab.stages.fuse`).
    magnetometer
        Fuse with the magnetometers (default 6-D, :data:`motionlab.stages.MAGNETOMETER`).
    clock_sync
        Put the IMUs on one clock from their shared joint centres and heel strikes first
        (``motionlab sync``).
    angle_lowpass_hz
        The joint angles' zero-phase low-pass (Hz; 0: as computed; ``None``: the protocol's,
        else 6; :mod:`motionlab.kinematics.angle_filter`).
    force
        Replace existing outputs.
    progress
        Print the stage counter and fusion progress on stderr.
    """

    # each field: default, flag, help text, then its RunOption's other keys
    protocol: str | Path | Protocol = _option(
        dataclasses.MISSING, "--protocol", "Protocol YAML file or packaged name.",
        manifest="protocol", stages=("sync", "calibrate", "angles", "metrics", "validate"),
    )  # fmt: skip
    map_path: Path | None = _option(
        None, "--map", "Sensor map YAML for raw recordings (see 'motionlab ingest --help').",
        kind="file", manifest="map", stages=("ingest",),
    )  # fmt: skip
    reference: Path | None = _option(
        None, "--reference", "Reference to validate against: markers (C3D, TRC, a session), a "
        "CSV of segment quaternions or a C3D of model joint angles (see 'motionlab validate "
        "--help').", kind="file", manifest="reference", stages=("validate",),
    )  # fmt: skip
    frames: str = _option(
        "anatomical", "--frames", "Segment-quaternion reference: its quaternions are anatomical "
        "segment frames (ISB) or arbitrary body frames.", kind="choice",
        choices=("anatomical", "body"), manifest="frames", batch=True, stages=("validate",),
        show_default=True,
    )  # fmt: skip
    markers_path: Path | None = _option(
        None, "--markers", "Marker map YAML of the reference (default: markers by name).",
        kind="file", manifest="markers", stages=("validate",),
    )  # fmt: skip
    calibration_dir: Path | None = _option(
        None, "--calibration", "Folder of per-serial sensor calibrations (motionlab sensorcal) "
        "for fusion.", kind="folder", manifest="calibration", batch=True, stages=("fuse",),
    )  # fmt: skip
    seed: int = _option(
        0, "--seed", "Random seed.", kind="int", manifest="seed", batch=True,
        stages=("validate",), show_default=True,
    )  # fmt: skip
    estimator: str = _option(
        stages_lib.ESTIMATOR, "--filter", "Estimator for the fusion stage (names: 'motionlab "
        "fuse --list').", manifest="filter", batch=True, stages=("fuse",), show_default=True,
    )  # fmt: skip
    orientation: str = _option(
        "fused", "--orientation", "'vendor': use the orientation the sensors carry (their own "
        "fusion, a .sto) instead of fusing; recordings with orientations only always do.",
        kind="choice", choices=stages_lib.ORIENTATIONS, manifest="orientation", batch=True,
        stages=("fuse",), show_default=True,
    )  # fmt: skip
    magnetometer: bool = _option(
        stages_lib.MAGNETOMETER, "--magnetometer/--no-magnetometer", "Fuse with the "
        "magnetometers (default 6-D: indoor fields turn headings mid-task).", kind="bool",
        manifest="magnetometer", batch=True, stages=("fuse",),
    )  # fmt: skip
    clock_sync: bool = _option(
        stages_lib.CLOCK_SYNC, "--clock-sync/--no-clock-sync", "Put IMUs recorded on their own "
        "clocks on one clock (from the joints they share).", kind="bool",
        manifest="clock_sync", batch=True, show_default=True,
    )  # fmt: skip
    angle_lowpass_hz: int | None = _option(
        None, "--angle-lowpass", "Low-pass the joint angles at this many Hz (zero-phase; a "
        "sensor's wobble on the skin is not the joint moving); 0 keeps them as computed "
        "[default: the protocol's angle_lowpass_hz, else 6].", kind="int",
        manifest="angle_lowpass", batch=True, stages=("angles",), minimum=0,
        minimum_means="keeps the angles as computed",
    )  # fmt: skip
    force: bool = _option(
        False, "--force", "Replace existing outputs.", kind="flag",
        stages=("ingest", "sync", "fuse", "calibrate", "angles", "metrics", "validate"),
    )  # fmt: skip
    progress: bool = _option(True, "--quiet", "No progress on stderr.", kind="off")

    def __post_init__(self) -> None:
        """Each option of its kind (:class:`RunOption`): ``clock_sync="no"`` is truthy and ran
        the sync, ``frames="bogus"`` was taken as ``body``, ``seed="x"`` failed deep inside."""
        for f in dataclasses.fields(self):
            spec, value = f.metadata["option"], getattr(self, f.name)
            kind = spec.kind
            if kind in ("bool", "flag", "off") and not isinstance(value, bool):
                wrong = "expected True or False"
            elif (
                kind == "int"
                and (value is not None or f.default is not None)
                and (isinstance(value, bool) or not isinstance(value, numbers.Integral))
            ):
                wrong = "expected an integer"
            elif kind == "choice" and value not in spec.choices:
                wrong = f"expected one of {', '.join(spec.choices)}"
            elif kind in ("file", "folder") and not isinstance(value, (str, Path, type(None))):
                wrong = "expected a path"
            elif kind == "text" and f.name != "protocol" and not isinstance(value, str):
                wrong = "expected a name"
            elif spec.minimum is not None and value is not None and value < spec.minimum:
                wrong = spec.below_minimum()
            else:
                continue
            raise InputError(
                f"{f.name}={value!r}: {wrong}",
                remedy="see help(motionlab.PipelineOptions)",
                argument=f.name,
            )

    def load_protocol(self) -> Protocol:
        """The protocol, loaded (and so checked)."""
        return (
            self.protocol if isinstance(self.protocol, Protocol) else load_protocol(self.protocol)
        )

    def analysis(self) -> dict[str, object]:
        """The options that change the numbers and differ from the defaults (``reference`` and
        ``map_path`` aside): ``{"seed": 3, "magnetometer": True, ...}`` (paths as text)."""
        out: dict[str, object] = {}
        for f in dataclasses.fields(self):
            if f.name in ("protocol", "map_path", "reference", "markers_path", "force", "progress"):
                continue
            value = getattr(self, f.name)
            if value != f.default:
                out[f.name] = str(value) if isinstance(value, Path) else value
        return out

    def command(self, inputs: list[Path], outdir: Path) -> str:
        """The ``motionlab run`` command line these options stand for (the options that differ
        from their defaults, in the order of the fields)."""
        protocol = self.protocol.path if isinstance(self.protocol, Protocol) else self.protocol
        words = ["motionlab", "run", "--protocol", str(protocol), *map(str, inputs)]
        words += ["-o", str(outdir)]
        for f in dataclasses.fields(self):
            value, option = getattr(self, f.name), RUN_OPTIONS[f.name]
            if f.name in ("protocol", "force", "progress") or value == f.default:
                continue
            if option.kind == "bool":
                on, off = option.flag.split("/")
                words.append(on if value else off)
            else:
                words += [option.flag, str(value)]
        return shlex.join(words)


#: field of :class:`PipelineOptions` → its :class:`RunOption`, in the order of the fields
RUN_OPTIONS: dict[str, RunOption] = {
    f.name: f.metadata["option"] for f in dataclasses.fields(PipelineOptions)
}


def analyse(
    session: Session,
    options: PipelineOptions,
    stages: _Stages | None = None,
    reference: tuple[MarkerSet, str] | None = None,
    marker_map: MarkerMap | None = None,
    record: bool = True,
) -> None:
    """The stages after ingest, in memory, each by its function in :mod:`motionlab.stages` (as
    the stage commands call them): (sync) → fuse (with the sensor calibrations) → calibrate →
    angles → metrics (and gait) → (validate, with ``options.reference`` or the session's own
    markers). Results go to ``session.results``' stage attributes, as the stage commands store them.

    ``options.clock_sync`` puts sensors recorded on their own clocks on one clock
    (:func:`motionlab.clocksync.synchronise`; corrections only where reliable and non-zero).

    Fusion is 6-D (no magnetometer) unless ``options.magnetometer``: joint angles need the
    heading of each segment relative to its neighbour only, which the heading alignment gives
    (:func:`motionlab.segments.segment_orientations`), while indoors an uncalibrated or
    disturbed magnetometer made the default estimator turn a sensor's heading by 20-60° in the
    middle of a task (knee sessions simulated with the ``typical`` preset, seeds 0-9 at 100, 60
    and 50 Hz: with the magnetometer 3 of 30 had a knee rotation RMSE of 21-23°, without it none
    above 2°). Validation then aligns each sensor's heading separately (mode ``heading``).

    ``reference``: ``options.reference`` already read (its marker set and kind,
    :func:`~motionlab.validation.reference_kinds.load_reference`), and ``marker_map``
    ``options.markers_path``, as :func:`run_pipeline` reads them before any work. With
    ``record`` one provenance entry (``stage`` ``analyse``, the protocol and the options that
    differ from the defaults) is added; :func:`run_pipeline` writes its own.
    """

    protocol = options.load_protocol()
    check_joints(protocol, session)  # before the joints of absent segments are dropped
    protocol = sensed_protocol(protocol, session)
    stages = stages or _Stages([], progress=options.progress)
    if options.clock_sync:
        with stages("clock sync"):
            stages_lib.sync(session, protocol, force=True, record=False)
    with stages("fuse"):
        stages_lib.fuse(
            session,
            options.estimator,
            magnetometer=options.magnetometer,
            calibration_dir=options.calibration_dir,
            force=True,
            progress=_announce if stages.progress else None,
            orientation=options.orientation,
            record=False,
        )
    with stages("calibrate"):
        cal = stages_lib.calibrate(session, protocol, force=True, record=False)
    with stages("angles"):
        stages_lib.angles(session, protocol, angle_lowpass_hz=options.angle_lowpass_hz,
                          force=True, record=False)  # fmt: skip
    with stages("metrics"):
        stages_lib.metrics(session, protocol, force=True, record=False)
    if options.reference is not None or session.markers:
        from motionlab.validation.reference_kinds import load_reference, session_reference

        with stages("validate"):  # markers, segment quaternions or model angles
            if marker_map is None and options.markers_path is not None:
                marker_map = _read_marker_map(options)
            name = marker_map.marker_set if marker_map is not None else None
            if reference is not None:
                marker_set, kind = reference
            elif options.reference is not None:
                marker_set, kind = load_reference(Path(options.reference), name=name)
            else:
                marker_set, kind = session_reference(session, name=name)
            stages_lib.validate(session, protocol, marker_set, seed=options.seed, force=True,
                                reference_kind=kind, frames=options.frames,
                                marker_map=marker_map, record=False)  # fmt: skip
    if record:
        session.add_provenance(
            parameters={"stage": "analyse", "protocol": str(protocol.path)} | options.analysis()
        )
    doubts = [f"{s.label}: {line}" for s in session.sensors.values() for line in qc_doubts(s)]
    doubts = unmatched_keys(session) + doubts
    for line in [*doubts, *cal.warnings] if stages.progress else []:  # after the stages
        print(f"warning: {line}", file=sys.stderr, flush=True)


#: the modules :func:`run_pipeline` imports when it is called (the exports, the metrics table,
#: the report with pandas and matplotlib), for a caller that loads them first
#: (:func:`motionlab.cli.frozen_imports`)
RUN_IMPORTS = (
    "motionlab.export",
    "motionlab.kinematics.metrics",
    "motionlab.report",
    "motionlab.report.console",
    "motionlab.report.csv",
    "motionlab.segments.grades",
)


def _read_reference(
    options: PipelineOptions, marker_map: MarkerMap | None
) -> tuple[MarkerSet, str] | None:
    """``options.reference`` read (the marker set ``marker_map`` names, or its only one, and
    its kind), or None without one; the validation's readers are imported only then."""
    if options.reference is None:
        return None
    from motionlab.validation.reference_kinds import load_reference

    name = marker_map.marker_set if marker_map is not None else None
    return load_reference(Path(options.reference), name=name)


def _read_marker_map(options: PipelineOptions) -> MarkerMap | None:
    """``options.markers_path`` read, or None without one."""
    if options.markers_path is None:
        return None
    from motionlab.validation.markermap import load_marker_map

    return load_marker_map(options.markers_path)


def run_pipeline(inputs: list[Path], outdir: Path, options: PipelineOptions) -> PipelineResult:
    """Ingest → (clock sync) → fuse (with sensor calibrations) → calibrate → angles → metrics →
    (validate) → report.

    ``inputs``: raw recording files, or one motionlab session file. ``outdir``: output folder
    (created): ``session.h5``, ``report.pdf``, ``report.txt``, ``csv/``, ``results.json``.
    ``options``: everything else (:class:`PipelineOptions`); the protocol and the estimator are
    checked before any work.
    """
    from motionlab.export import write_json
    from motionlab.kinematics.metrics import metrics_table, protocol_columns, with_not_measured
    from motionlab.report import load_views, write_report
    from motionlab.report.console import run_summary
    from motionlab.report.csv import gait_summary_frame, with_normals
    from motionlab.segments.grades import with_grades

    t_start = time.perf_counter()
    inputs = [Path(p) for p in inputs]
    outdir = Path(outdir)
    if not inputs:
        raise InputError("no input files", remedy="give one or more recordings or a session file")
    proto = options.load_protocol()
    _check_estimator(options.estimator, options.magnetometer)
    session_path, report_path, csv_dir = _outputs(
        outdir,
        options.force,
        [*inputs, options.map_path, options.reference, options.markers_path, proto.path],
    )
    marker_map = _read_marker_map(options)  # an unreadable one is told before any work
    reference = _read_reference(options, marker_map)  # and so is a reference
    command = options.command(inputs, outdir)
    names = ["ingest", "fuse", "calibrate", "angles", "metrics", "report"]
    if options.clock_sync:
        names.insert(1, "clock sync")
    if options.reference is not None or _holds_markers(inputs):
        names.insert(-1, "validate")
    stages = _Stages(names, options.progress)

    with stages("ingest"):
        map_path = Path(options.map_path) if options.map_path else None
        session = load_inputs(inputs, map_path, command)
        check_segments(session, proto, inputs)
        unsensed = unsensed_joints(proto, session)
        full, proto = proto, sensed_protocol(proto, session)
    analyse(session, dataclasses.replace(options, protocol=proto), stages, reference, marker_map,
            record=False)  # fmt: skip
    validated = session.results.validation is not None
    session.add_provenance(
        command,
        parameters={
            "stage": "run",
            "protocol": str(proto.path),
            "protocol_sha256": sha256_file(proto.path),
            "seed": options.seed,
            "estimator": options.estimator,
            "magnetometer": options.magnetometer,
            "clock_sync": options.clock_sync,
            "validated": validated,
        }
        | (
            {"calibration": str(options.calibration_dir)}
            if options.calibration_dir is not None
            else {}
        ),
    )
    outdir.mkdir(parents=True, exist_ok=True)
    with session_lock(session_path):  # the session, its report and JSON from one writer
        save_session(session, session_path, force=options.force)
        with stages("report"):
            views = load_views([session], full, [session_path])
            out = write_report(views, report_path, csv_dir, force=options.force)
            write_json(session, outdir / RESULTS_JSON, force=options.force)
    table = metrics_table(session.results.metrics, protocol_columns(proto))
    metrics = table[table["percent"].isna()].drop(columns="percent").reset_index(drop=True)
    res = session.results
    metrics = with_grades(metrics, proto, res.calibration, res.angles.method)
    metrics = with_not_measured(metrics, full, unsensed, list(res.metrics.joints))
    metrics = with_normals(views[0], metrics)
    summary = run_summary(
        views[0],
        out,
        stages.times,
        time.perf_counter() - t_start,
        session_file=SESSION_FILE,
        csv_dir=CSV_DIR,
        results_json=RESULTS_JSON,
    )
    gait = gait_summary_frame(views[0])
    return PipelineResult(session_path, report_path, csv_dir, metrics, summary, gait)
