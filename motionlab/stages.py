"""One function per analysis stage: compute the stage's results and store them in the session.

The stage commands (``motionlab sync``, ``fuse``, ``calibrate``, ``angles``, ``metrics``,
``validate``) and ``motionlab run`` (:func:`motionlab.pipeline.analyse`) call these functions
with the same defaults, so the stage-by-stage path computes what ``run`` computes:

    sync → fuse → calibrate → angles → metrics → (validate)

Each function takes the session (in memory), stores its result in the stage's attribute of
``session.results`` (:class:`motionlab.results.Results`: ``clock_sync``, ``fusion``,
``calibration``, ``angles`` and ``heading``, ``metrics`` and ``gait``, ``validation``) and
returns it; ``force`` replaces earlier results of the stage (without it they
are an :class:`~motionlab.errors.InputError` naming ``path``, the session file). Every function
that reads the protocol uses :func:`motionlab.binding.sensed_protocol` (joints of
optional segments without a sensor left out), as ``run`` does.

A session file that has not been through ingest (``motionlab simulate`` writes one) gets
ingest's clock repair, quality checks and gap filling in the first stage that reads its sensors
(:func:`prepare`: ``sync`` or ``fuse``), as ``run`` gives them on loading it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import numbers
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from motionlab.binding import check_joints, sensed_protocol
from motionlab.errors import InputError
from motionlab.ingest import DEFAULT_GAP_MAX, check_and_fill, drop_kept_nan_runs
from motionlab.kinematics.angle_filter import ANGLES_LOWPASS_HZ, smoothed_table
from motionlab.lineage import protocol_sha256, refuse_stale
from motionlab.protocol import Protocol, load_protocol
from motionlab.results import (
    AngleTable,
    AppliedCalibration,
    ClockSync,
    FusionEntry,
    Gait,
    MarkerFusion,
    Metrics,
    SegmentCalibration,
    Validation,
    ValidationReference,
)
from motionlab.session import Session

if TYPE_CHECKING:
    from motionlab.session import MarkerSet
    from motionlab.validation.markermap import MarkerMap

#: the estimator ``fuse`` and ``run`` ask the registry for by default: its name ``default``
#: stands for :data:`motionlab.fusion.registry.DEFAULT_ESTIMATOR` (the smoother), so the
#: provenance and a study's options say ``default`` unless another estimator is chosen
ESTIMATOR = "default"
#: 6-D fusion by default: indoors an uncalibrated or disturbed magnetometer turned a sensor's
#: heading by 20-60° mid-task, while joint angles need only the heading of each segment relative
#: to its neighbour, which the heading alignment gives (see :func:`motionlab.pipeline.analyse`)
MAGNETOMETER = False
#: ``run`` puts IMUs recorded on their own clocks on one clock first (``motionlab sync``)
CLOCK_SYNC = True

Progress = Callable[[list[str], str], Iterable[str]]


@contextlib.contextmanager
def in_session_file(path: Any) -> Iterator[None]:
    """An :class:`InputError` about what the session holds (its fusion results, its
    calibration) that names no file is named by the session's file ``path`` (when given): "no
    fusion result" said where in the session, not which session."""
    try:
        yield
    except InputError as exc:
        if exc.path is not None or path is None:
            raise
        raise InputError(exc.message, path, exc.where, exc.remedy, exc.arguments or None) from None


def check_session(session: object) -> None:
    """An :class:`InputError` unless ``session`` is a :class:`Session` (a path given where the
    session goes raised ``AttributeError: 'str' object has no attribute 'results'``)."""
    if not isinstance(session, Session):
        what = "a path" if isinstance(session, (str, Path)) else type(session).__name__
        raise InputError(
            f"got {what} where a Session goes",
            remedy="load it first: session = motionlab.load_session(path)",
        )


def _recorded(session: Session, record: bool, stage: str, **parameters: Any) -> None:
    """With ``record``, a provenance entry of the stage and its parameters (those not ``None``)
    in ``session.provenance`` (the commands and :func:`motionlab.pipeline.run_pipeline` pass
    ``record=False`` and write their own, with the command line and the inputs' hashes):
    stages called from Python left none, and the report's provenance table then listed no
    step after ingest."""
    if record:
        session.add_provenance(
            parameters={"stage": stage} | {k: v for k, v in parameters.items() if v is not None}
        )


def refuse_to_redo(done: bool, stage: str, what: str, force: bool, path: Any = None) -> None:
    """Raise when the session already holds the ``stage``'s result (``done``) and not
    ``force``."""
    if done and not force:
        raise InputError(
            f"already holds {what}", path, f"results/{stage}", "add force=True to redo it",
            argument="force",
        )  # fmt: skip


def stage_protocol(
    session: Session, protocol: Protocol | str | Path | None, path: Any = None
) -> Protocol:
    """The protocol given (loaded), else the calibration's; without the joints of absent
    optional segments (:func:`~motionlab.binding.sensed_protocol`)."""

    if protocol is None:
        cal = session.results.calibration
        if cal is None:
            raise InputError("no protocol", path, remedy="give protocol=", argument="protocol")
        protocol = cal.protocol_source
        stamp = session.lineage.stamps.get("calibration")
        then = stamp.protocol_sha256 if stamp is not None else None
        now = protocol_sha256(protocol)
        if then is not None and now is not None and now != then:
            raise InputError(
                "the calibration's protocol file has changed since the calibration",
                protocol,
                remedy="re-run motionlab calibrate force=True, or give protocol=",
                argument=("force", "protocol"),
            )
    if not isinstance(protocol, Protocol):
        protocol = load_protocol(protocol)
    return sensed_protocol(protocol, session)


def _calibration(session: Session, path: Any) -> SegmentCalibration:
    cal = session.results.calibration
    if cal is None:
        raise InputError(
            "not calibrated", path, "results/calibration", "run motionlab calibrate first"
        )
    return cal


def prepare(session: Session, gap_max: float = DEFAULT_GAP_MAX) -> list[str]:
    """Clock repair, quality checks and short-gap filling, as ingest does
    (:func:`motionlab.timebase.repair_clock`, :func:`motionlab.ingest.check_and_fill`), for the
    sensors that have not been through ingest (no ``qc``); returns their labels. The others
    lose the long NaN runs their ingest kept (:func:`motionlab.ingest.drop_kept_nan_runs`)."""
    from motionlab import timebase

    done = []
    for label, stream in list(session.sensors.items()):
        if not stream.qc:
            stream, report = timebase.repair_clock(stream)
            session.sensors[label] = check_and_fill(stream, report, gap_max)
            done.append(label)
        else:
            session.sensors[label] = drop_kept_nan_runs(stream)
    return done


def sync(
    session: Session,
    protocol: Protocol | str | Path,
    *,
    force: bool = False,
    path: Any = None,
    record: bool = True,
) -> ClockSync:
    """Put the protocol's IMUs on one clock (:func:`motionlab.clocksync.synchronise`), every
    fit stored in ``results.clock_sync`` (by sensor, in the order made). Prepares sensors
    without QC first (:func:`prepare`). ``force`` redoes it from the recorded stamps."""
    check_session(session)
    from motionlab.clocksync import synchronise

    done = session.results.clock_sync is not None
    refuse_to_redo(done, "clock_sync", "a clock synchronisation", force, path)
    session.results.clock_sync = None  # a redo that fails leaves no stale result
    prepare(session)
    protocol = stage_protocol(session, protocol, path)
    result = ClockSync({fit.sensor: fit for fit in synchronise(session, protocol)})
    session.results.clock_sync = result
    session.lineage.record(session.results, "clock_sync", protocol)
    _recorded(session, record, "sync", protocol=protocol.name)
    return result


def fuse(
    session: Session,
    estimator: str = ESTIMATOR,
    params: dict[str, str] | None = None,
    sensors: list[str] | None = None,
    *,
    magnetometer: bool = MAGNETOMETER,
    calibration_dir: str | Path | None = None,
    markers: bool = False,
    marker_map: MarkerMap | None = None,
    force: bool = False,
    path: Any = None,
    progress: Progress | None = None,
    orientation: str = "fused",
    record: bool = True,
) -> dict[str, FusionEntry]:
    """Orientation of every sensor with gyroscope and accelerometer (of ``sensors``) by
    ``estimator`` (:func:`motionlab.fusion.stage.fuse_session`), stored in ``results.fusion``;
    returns the entries stored (sensor label → :class:`FusionEntry`: the vendor's orientations
    kept, then the sensors fused, in order; empty when there was nothing to do).
    :func:`fusion_notes` says what else was done to each.

    ``orientation="vendor"``: sensors that carry the vendor's own orientation (``quat``: an
    Xsens export's, an OpenSense ``.sto``, Xsens DOT) keep it instead of being fused (entry
    ``name: vendor``); the others are fused. Sessions without raw signals always use it.

    ``magnetometer``: 9-D where a sensor has one (default 6-D, :data:`MAGNETOMETER`).
    ``calibration_dir``: per-serial sensor calibrations (``motionlab sensorcal``) applied to the
    data fused; the session keeps the data as recorded. ``markers``: fuse the session's marker
    clusters too (``marker_map``, default by name). Prepares sensors without QC first.
    """
    check_session(session)
    from motionlab.fusion import registry
    from motionlab.fusion.stage import fusable, fuse_session

    if not magnetometer and registry.get(estimator).needs_mag:
        raise InputError(
            f"estimator '{estimator}' needs a magnetometer",
            remedy="add magnetometer=True",
            argument="magnetometer",
        )
    if orientation not in ORIENTATIONS:
        raise InputError(
            f"unknown orientation source {orientation!r}", where="argument orientation",
            remedy=f"use one of {', '.join(ORIENTATIONS)}", argument="orientation",
        )  # fmt: skip
    prepare(session)
    vendor: dict[str, FusionEntry] = {}
    if orientation == "vendor":
        vendor = _vendor_orientations(session, sensors, force, path)
    usable = [k for k in fusable(session, sensors) if k not in vendor]
    kept = [k for k in session.results.fusion if k not in usable and k not in vendor]
    if kept and "fusion" in session.lineage.stale(session.results):
        raise InputError(
            f"the orientations of {', '.join(kept)} are stale too (computed before the clock "
            "sync was redone)", path, "results/fusion", "fuse every sensor",
        )  # fmt: skip
    recorded, calibrated = dict(session.sensors), {}
    refs: dict[str, Any] = {}
    marker_info: dict[str, MarkerFusion] = {}
    done: dict[str, FusionEntry] = {}
    if usable:
        try:
            if calibration_dir is not None:
                from motionlab.sensorcal.calfile import apply_calibration_dir

                calibrated, _ = apply_calibration_dir(session.sensors, calibration_dir, usable)
                session.sensors.update(calibrated)
            if markers or marker_map is not None:
                refs, marker_info = _marker_references(session, estimator, marker_map, usable)
            done = fuse_session(
                session, estimator, params, usable, force=force, path=path, references=refs,
                magnetometer=magnetometer, progress=progress,
            )  # fmt: skip
        finally:
            session.sensors = recorded
    for label, stream in calibrated.items():
        entry = done[label]
        entry.sensor_calibration = AppliedCalibration.from_tree(stream.attrs["calibration"])
        if stream.acc is not None:  # the segment calibration reads the recorded accelerometer
            bias = 0.0 if entry.acc_bias is None else entry.acc_bias
            entry.acc_bias = recorded[label].acc - stream.acc + bias
    for label in refs:
        done[label].markers = marker_info[label]
    stored = vendor | done
    if stored:
        session.results.fusion.update(stored)
        session.lineage.record(session.results, "fusion")
        _recorded(session, record, "fuse", filter=estimator, params=params or {},
                  sensors=list(stored), magnetometer=magnetometer, orientation=orientation,
                  calibration=str(calibration_dir) if calibration_dir else None)  # fmt: skip
    return stored


def fusion_notes(
    session: Session, labels: list[str], calibration_dir: str | Path | None = None
) -> dict[str, str]:
    """One line per fused sensor of ``labels`` on what :func:`fuse` did besides the
    orientation, read from its stored entry: the sensor calibration applied (or none found in
    ``calibration_dir`` for its serial), runs of non-finite samples bridged, the share of the
    time its marker cluster was seen. Sensors with nothing to say are left out."""
    from motionlab.sensorcal.calfile import calibration_key

    notes = {}
    for label in labels:
        entry = session.results.fusion[label]
        if entry.name == "vendor":
            continue
        parts = []
        if entry.sensor_calibration is not None:
            parts.append(f"calibrated ({', '.join(entry.sensor_calibration.channels)})")
        elif calibration_dir is not None:
            parts.append(f"no calibration for {calibration_key(session.sensors[label])}")
        if entry.nan_bridged_s:
            parts.append(f"{len(entry.nan_bridged_s)} run(s) of non-finite samples bridged")
        if entry.markers is not None:
            parts.append(f"markers seen {100 * entry.markers.visible_fraction:.0f} %")
        if parts:
            notes[label] = ", ".join(parts)
    return notes


ORIENTATIONS = ("fused", "vendor")


def _vendor_orientations(
    session: Session, sensors: list[str] | None, force: bool, path: Any
) -> dict[str, FusionEntry]:
    """The vendor's orientation of every sensor that has one, as its fusion entry.

    Non-finite rows are treated as in fusion (:mod:`motionlab.fusion.stage`): runs up to
    ``NAN_BRIDGE_MAX_S`` hold the last orientation and are listed in ``nan_bridged_s``, longer
    runs are refused."""
    import numpy as np

    from motionlab.fusion.registry import hold_last_finite
    from motionlab.fusion.stage import bridged_spans

    out: dict[str, FusionEntry] = {}
    for label in sensors or list(session.sensors):
        s = session.sensors[label]
        if s.quat is None:
            continue
        if label in session.results.fusion and not force:
            raise InputError(
                "already has orientations", path, f"results/fusion/{label}",
                "use force=True to replace them", argument="force",
            )  # fmt: skip
        quat = np.asarray(s.quat, float)
        bridged = bridged_spans(label, s.time, {"quat": quat}, path)
        # the vendor's fusion shares one earth frame between its sensors (9-D)
        out[label] = FusionEntry(
            "vendor", hold_last_finite(quat), magnetometer=True, nan_bridged_s=bridged or None
        )
    return out


def _marker_references(
    session: Session, estimator: str, marker_map: MarkerMap | None, labels: list[str]
) -> tuple[dict[str, Any], dict[str, MarkerFusion]]:
    """Marker reference vectors of the sensors that carry a cluster, and what each cluster
    gave."""
    from motionlab.fusion import registry
    from motionlab.fusion.marker_registration import session_references

    if not registry.takes_references(estimator):
        takes = [k for k in registry.available() if registry.takes_references(k)]
        raise InputError(
            f"estimator '{estimator}' cannot fuse markers",
            remedy=f"use estimator={' or '.join(takes)}",
            argument="estimator",
        )
    return session_references(session, marker_map, labels=labels)


def synced(session: Session) -> bool:
    """Whether the session went through the clock sync stage (or has one sensor only)."""
    return session.results.clock_sync is not None or len(session.sensors) < 2


def calibrate(
    session: Session,
    protocol: Protocol | str | Path,
    *,
    force: bool = False,
    path: Any = None,
    record: bool = True,
) -> SegmentCalibration:
    """Sensor-to-segment calibration (:func:`motionlab.segments.calibrate_segments`), stored in
    ``results.calibration`` with the protocol's path."""
    check_session(session)
    from motionlab.segments import calibrate_segments

    done = session.results.calibration is not None
    refuse_to_redo(done, "calibration", "a calibration", force, path)
    refuse_stale(session, ("clock_sync", "fusion"), path)
    if not isinstance(protocol, Protocol):
        protocol = load_protocol(protocol)
    check_joints(protocol, session, path)  # before the joints of absent segments are dropped
    protocol = stage_protocol(session, protocol, path)
    with in_session_file(path):
        result = calibrate_segments(session, protocol)
    result.protocol_path = str(protocol.path)
    session.results.calibration = result
    session.lineage.record(session.results, "calibration", protocol)
    _recorded(session, record, "calibrate", protocol=str(protocol.path))
    return result


def angles(
    session: Session,
    protocol: Protocol | str | Path | None = None,
    *,
    method: str = "imu",
    calibrated: bool = True,
    angle_lowpass_hz: float | None = None,
    force: bool = False,
    path: Any = None,
    record: bool = True,
) -> AngleTable:
    """The joint angle table (degrees), stored in ``results.angles`` (with its ``method``, its
    low-pass and the calibration steps as events) and each joint's heading correction in
    ``results.heading``.

    ``protocol`` defaults to the calibration's. ``method``: ``imu`` (fused orientations) or
    ``accel-only`` (elbow from accelerometers, Lee 2012). ``calibrated=False`` takes sensor
    frames as segment frames. ``angle_lowpass_hz``: the angles' zero-phase low-pass (Hz; 0: as
    computed; ``None``: the protocol's ``angle_lowpass_hz``, else 6;
    :mod:`motionlab.kinematics.angle_filter`: a sensor's wobble on the skin after heel strikes
    is not the joint moving).
    """
    check_session(session)
    if angle_lowpass_hz is not None and not (
        isinstance(angle_lowpass_hz, numbers.Real)
        and not isinstance(angle_lowpass_hz, bool)
        and angle_lowpass_hz >= 0
    ):
        raise InputError(
            f"angle_lowpass_hz={angle_lowpass_hz!r} is not a cut-off",
            remedy="give a frequency in Hz, or 0 to keep the angles as computed",
            argument="angle_lowpass_hz",
        )
    from motionlab.kinematics.session_angles import session_angles
    from motionlab.results import HeadingCorrection

    cal = session.results.calibration
    if cal is None and calibrated:
        raise InputError(
            "not calibrated",
            path,
            "results/calibration",
            "run motionlab calibrate first, or pass calibrated=False",
            argument="calibrated",
        )
    refuse_to_redo(session.results.angles is not None, "angles", "angles", force, path)
    read = ("fusion", "calibration") if calibrated else ("fusion",)
    if method == "accel-only":  # the accelerometers (on the synchronised clock), calibration
        read = ("clock_sync", "calibration")
    refuse_stale(session, read, path)
    protocol = stage_protocol(session, protocol, path)
    if angle_lowpass_hz is None:
        angle_lowpass_hz = protocol.angle_lowpass_hz
    if angle_lowpass_hz is None:
        angle_lowpass_hz = ANGLES_LOWPASS_HZ
    corrections: dict[str, HeadingCorrection] = {}
    if method == "imu":
        with in_session_file(path):
            table = session_angles(
                session, protocol, cal if calibrated else None, corrections=corrections
            )
    elif method == "accel-only":
        from motionlab.kinematics.accel_only import session_elbow_angles

        with in_session_file(path):
            table = session_elbow_angles(session, protocol)
    else:
        raise InputError(
            f"unknown angle method {method!r}", remedy="use imu or accel-only", argument="method"
        )
    steps = cal.steps if cal is not None else {}
    events = {k: (float(v[0]), float(v[1])) for k, v in steps.items() if v is not None}
    if angle_lowpass_hz > 0:
        table = smoothed_table(table, float(angle_lowpass_hz))
    result = AngleTable.from_columns(table, method, events, angle_lowpass_hz)
    session.results.angles = result
    session.results.heading = corrections
    session.lineage.record(session.results, "angles", protocol, read)
    _recorded(session, record, "angles", method=method, angle_lowpass_hz=angle_lowpass_hz)
    return result


def metrics(
    session: Session,
    protocol: Protocol | str | Path | None = None,
    tasks: dict[str, tuple[float, float]] | None = None,
    *,
    gait: bool = True,
    force: bool = False,
    path: Any = None,
    record: bool = True,
) -> Metrics:
    """Per task, joint and plane metrics (:func:`motionlab.kinematics.metrics.session_metrics`)
    in ``results.metrics`` (their task blocks added to the angle table's events); with ``gait``
    and a gait task in the protocol, the gait analysis
    (:func:`motionlab.kinematics.gait.analyse_gait`) in ``results.gait``.

    ``protocol`` defaults to the calibration's; ``tasks`` ``{name: (start_s, end_s)}`` (default:
    found in the recording).
    """
    check_session(session)
    from motionlab.kinematics.metrics import session_metrics

    _calibration(session, path)
    refuse_to_redo(session.results.metrics is not None, "metrics", "metrics", force, path)
    refuse_stale(session, ("fusion", "calibration", "angles"), path)
    protocol = stage_protocol(session, protocol, path)
    names = {t.name for t in protocol.tasks}
    unknown = [n for n in tasks or {} if n not in names]
    if unknown:
        raise InputError(
            f"the protocol has no task {', '.join(unknown)}",
            protocol.path,
            "tasks",
            f"tasks are {', '.join(t.name for t in protocol.tasks)}",
        )
    with in_session_file(path):
        result = session_metrics(session, protocol, tasks)
    session.results.metrics = result
    if session.results.angles is not None:
        session.results.angles.events.update(result.spans())
    if gait:
        gait_stage(session, protocol)
    session.lineage.record(session.results, "metrics", protocol)
    _recorded(session, record, "metrics", protocol=str(protocol.path))
    return result


def gait_stage(session: Session, protocol: Protocol | str | Path | None = None) -> Gait | None:
    """The gait analysis in ``results.gait`` when the protocol has a gait task (else none)."""
    from motionlab.kinematics.gait import analyse_gait

    protocol = stage_protocol(session, protocol, None)
    if not any(t.is_gait for t in protocol.tasks):
        return None
    session.results.gait = analyse_gait(session, protocol)
    return session.results.gait


def validation_mode(session: Session) -> str:
    """Alignment mode for the session's fusion: ``full`` when every sensor was fused with its
    magnetometer (one earth frame), else ``heading`` (each sensor its own heading). A session
    with no fusion result reads ``full`` (``all`` of nothing); the validation refuses a sensor
    that was not fused, so the mode is then never used."""
    entries = session.results.fusion.values()
    return "full" if all(e.magnetometer for e in entries) else "heading"


def validate(
    session: Session,
    protocol: Protocol | str | Path | None = None,
    reference: MarkerSet | str | Path | None = None,
    *,
    marker_map: MarkerMap | None = None,
    static: MarkerSet | None = None,
    mode: str | None = None,
    clock: bool = True,
    movement_only: bool = False,
    seed: int = 0,
    keep_reference: bool = True,
    force: bool = False,
    path: Any = None,
    reference_kind: str = "markers",
    frames: str = "anatomical",
    angle_map: dict | None = None,
    sync_on: str = "gyroscope",
    record: bool = True,
) -> Validation:
    """Validation against an optical reference (:func:`motionlab.validation.validate`), stored
    in ``results.validation``.

    ``reference_kind`` (:func:`motionlab.validation.reference_kinds.load_reference` tells it):
    ``markers``; ``segments`` (segment quaternions, :mod:`motionlab.validation.segment_csv`;
    ``frames`` ``anatomical`` or ``body``); ``angles`` (model joint angles,
    :func:`motionlab.validation.model_angles.validate_model_angles` with ``angle_map``, default
    Plug-in Gait's). ``sync_on``: the IMU signal of the clock sync (``gyroscope``, as interval
    averages, or ``orientation``).

    ``reference``: a marker set, or a file read as ``motionlab validate --reference`` reads it
    (its kind told by the file unless ``reference_kind`` says ``segments`` or ``angles``);
    default the session's own markers. With ``keep_reference`` a reference
    from elsewhere is added to ``session.markers`` (renamed if the name is taken) so that the
    report shows it. ``mode`` defaults to :func:`validation_mode`. ``clock``: estimate the
    optical-to-IMU clock model (``False``: one clock). ``protocol`` defaults to the
    calibration's (orientations only without one).
    """
    check_session(session)
    from motionlab.validation import validate as validate_session
    from motionlab.validation.reference_kinds import REFERENCE_KINDS, kind_of, load_reference
    from motionlab.validation.segment_csv import FRAMES

    done = session.results.validation is not None
    refuse_to_redo(done, "validation", "validation results", force, path)
    for arg, value, allowed in (("reference_kind", reference_kind, REFERENCE_KINDS),
                                ("frames", frames, FRAMES)):  # fmt: skip
        if value not in allowed:  # a typo was taken as the default's other choice
            raise InputError(
                f"{arg}={value!r} is unknown", path, remedy=f"use {', '.join(allowed)}",
                argument=arg,
            )  # fmt: skip
    if isinstance(reference, (str, Path)):  # a file, read as 'motionlab validate' reads it
        name = marker_map.marker_set if marker_map is not None else None
        kind = "auto" if reference_kind == "markers" else reference_kind
        kind = "angles" if angle_map is not None and kind == "auto" else kind  # as the CLI
        reference, reference_kind = load_reference(reference, kind, name)
    elif reference_kind == "auto":  # as a file's: model angles alone are an angle reference
        reference_kind = kind_of(reference) if reference is not None else "markers"
    if angle_map is not None and reference_kind != "angles":  # a mix-up: refused before any work
        raise InputError(
            "an angle map applies to a reference of model joint angles",
            path,
            remedy="pass reference_kind='angles', or leave out angle_map=",
            argument=("reference_kind", "angle_map"),
        )
    refuse_stale(session, ("fusion", "calibration", "angles"), path)
    if protocol is None and session.results.calibration is None:
        proto = None
    else:
        proto = stage_protocol(session, protocol, path)
    kept = any(m is reference for m in session.markers.values())
    if reference is not None and keep_reference and not kept:
        name, n = reference.name, 2
        while name in session.markers:
            name, n = f"{reference.name}_{n}", n + 1
        reference = dataclasses.replace(reference, name=name)
        session.markers[name] = reference
    if reference_kind == "angles":
        from motionlab.validation.model_angles import validate_model_angles

        with in_session_file(path):
            result = validate_model_angles(
                session, reference, proto, mapping=angle_map, sync=clock,
                movement_only=movement_only, seed=seed,
            )  # fmt: skip
        session.results.validation = result
        session.lineage.record(session.results, "validation", proto)
        _recorded(session, record, "validate", reference_kind=reference_kind, seed=seed)
        return result
    if reference_kind == "segments" and marker_map is None:
        from motionlab.validation.segment_csv import segment_map

        segs = list(proto.segments) if proto is not None else []
        marker_map = segment_map(reference, segs, list(session.sensors), frames)
    with in_session_file(path):
        result = validate_session(
            session,
            reference,
            marker_map,
            proto,
            mode or validation_mode(session),
            sync=clock,
            movement_only=movement_only,
            seed=seed,
            static=static,
            sync_on=sync_on,
        )
    result.reference = ValidationReference(
        kind=reference_kind, frames=frames if reference_kind == "segments" else None
    )
    from motionlab.validation.model_angles import has_model_angles

    if reference is not None and has_model_angles(reference):  # say what else it holds
        result.notes.append(
            "the reference also holds another model's joint angles (POINT:ANGLES): the "
            "reference kind 'angles' compares against those"
        )
    session.results.validation = result
    session.lineage.record(session.results, "validation", proto)
    _recorded(session, record, "validate", reference_kind=reference_kind, mode=result.mode,
              sync=clock, sync_on=sync_on, movement_only=movement_only, seed=seed)  # fmt: skip
    return result
