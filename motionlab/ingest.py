"""Ingest: several recording files → one :class:`~motionlab.session.Session`.

Steps, for files read by :func:`motionlab.io.read_any` (one file per sensor, one file with many
sensors, or optical files that become marker sets):

0. each reader marks sensors it knows share one clock (one time column for several sensors, the
   vendor's synchronisation; across files, :func:`motionlab.io.xsens.mark_one_recording`);
1. the sensor map (:mod:`motionlab.sensor_map`) names each sensor's segment, side and label and
   gives subject/session metadata; a map key that matches no sensor is an error;
2. every stream's clock is repaired (:func:`motionlab.timebase.repair_clock`);
3. a common time origin: the earliest first stamp over all streams and marker sets becomes 0;
   the absolute origin is kept in ``metadata["time_origin_s"]`` and each stream's own first
   stamp in ``attrs["start_s"]``; starts more than a day apart set
   ``metadata["clocks_unrelated"]`` (the files do not share a clock);
4. quality checks (:mod:`motionlab.qc`) on the data as recorded, then gaps up to ``gap_max`` s
   are filled and longer ones kept as missing (:func:`motionlab.timebase.fill_short_gaps`), one
   stream at a time by :func:`check_and_fill` (``motionlab run`` applies it to session files
   that have not been through ingest);
5. with ``rate``, every sensor stream and marker set goes onto the clock ``k / rate``;
6. provenance: software version, command, parameters and the SHA-256 of every input.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from motionlab import timebase
from motionlab.binding import segment_name
from motionlab.errors import InputError, shorten
from motionlab.io import read_any
from motionlab.qc import (
    IMPLAUSIBLE,
    acc_unit_problem,
    check_stream,
    damage_checked,
    gyr_unit_problem,
    mark_identical_streams,
    swapped_problem,
)
from motionlab.sensor_map import SensorMap, load_sensor_map, unmatched_place
from motionlab.session import MarkerSet, SensorStream, Session

DEFAULT_GAP_MAX = 0.1  # s
UNRELATED_CLOCKS_S = 86400.0
#: sampling rates (Hz) and time stamps (s) taken as real; beyond them the clock is damaged
RATE_RANGE_HZ = (0.01, 1e6)
TIME_MAX_S = 1e11  # about 3000 years: Unix time in s fits, a stamp near 1e300 does not
#: ``rate`` may be at most this many times the highest native rate
UPSAMPLE_MAX = 10.0
#: a gyroscope that reads one value on this many samples or more while the sensor turns by
#: more than FLAT_TILT_DEG (deg, the accelerometer's gravity) is off
FLAT_MIN_SAMPLES = 100
FLAT_TILT_DEG = 30.0
FLAT_MEAN_S = 0.5  # s: gravity from the accelerometer's mean over stretches this long
FLAT_STRETCHES = 2000  # ... and no more of them (a long recording's stretches grow)
#: a quaternion whose norm is outside this range is not an orientation (e.g. all zero)
QUAT_NORM_RANGE = (0.5, 1.5)


def _match(stream: SensorStream, smap: SensorMap) -> str | None:
    """The map key naming ``stream`` by serial or label (case-insensitive), if any."""
    names = {n.lower() for n in (stream.serial, stream.label) if n}
    hits = [k for k in smap.sensors if k.lower() in names]
    return hits[0] if hits else None


def _origin(stream: SensorStream, path: Path) -> str:
    """Where ``stream`` came from, for a message: its device folder (x-IMU3) or its file."""
    folder = stream.attrs.get("device_folder")
    return f"'{Path(folder).name}'" if folder else path.name


def _apply_map(
    streams: list[tuple[SensorStream, Path]], smap: SensorMap
) -> tuple[list[tuple[SensorStream, Path]], list[dict[str, Any]]]:
    """The streams with the map's segment, side and label applied, and the map's keys that name
    no sensor here (``key``, ``line``, ``segment``): a study's map names a device one recording
    may lack (an optional chair sensor whose battery ran out). A map none of whose keys names a
    sensor is the wrong map: an :class:`InputError` naming its first key."""
    used: dict[str, tuple[str, str]] = {}
    out = []
    for stream, path in streams:
        key = _match(stream, smap)
        if key is not None:
            if key in used:
                origin, serial = used[key]
                same = bool(serial) and serial == stream.serial
                raise smap.fail(
                    f"sensors.{key}",
                    f"names {'device ' + serial if same else 'a sensor'} in both {origin} and "
                    f"{_origin(stream, path)}",
                    SAME_DEVICE
                    if same
                    else "key the sensors by serial, or give each file's sensor its own key",
                    smap.sensors[key].line,
                )
            used[key] = (_origin(stream, path), stream.serial)
            place = smap.sensors[key]
            stream = dataclasses.replace(
                stream,
                segment=place.segment or stream.segment,
                side=place.side or stream.side,
                label=place.label or stream.label,
                # the file's own name for it: a serial-less sensor's calibration is filed by it
                attrs={**stream.attrs, "map_key": key, "file_label": stream.label},
            )
        out.append((stream, path))
    missing = [k for k in smap.sensors if k not in used]
    if missing and not used:
        present = ", ".join(sorted({n for s, _ in streams for n in (s.serial, s.label) if n}))
        key = missing[0]
        raise smap.fail(
            f"sensors.{key}",
            f"no sensor '{key}' in the input files (no key of the map names one)",
            f"present: {present or 'none'}; fix the keys or give the map of these files",
            smap.sensors[key].line,
        )
    unmatched = [
        {"key": k, "line": smap.sensors[k].line,
         "segment": segment_name(smap.sensors[k].segment or "", smap.sensors[k].side or "")}
        for k in missing
    ]  # fmt: skip
    return out, unmatched


def unmatched_keys(session: Session) -> list[str]:
    """One line per sensor-map key that named no sensor in the ingested files
    (``metadata["map_unmatched"]``): ``"sensor map key 'Chair' (line 8, chair) names no sensor in
    the input files (present: Back, Chest)"``."""
    present = ", ".join(
        sorted({n for s in session.sensors.values() for n in (s.serial, s.label) if n})
    )
    out = []
    for entry in session.metadata.get("map_unmatched", []):
        where = unmatched_place(entry)
        out.append(f"sensor map key '{entry['key']}'{f' ({where})' if where else ''} names no "
                   f"sensor in the input files (present: {present or 'none'})")  # fmt: skip
    return out


def _check_channels(stream: SensorStream, path: Path) -> None:
    where = f"sensor {stream.label}"
    if stream.n_samples < 2:
        raise InputError(
            f"{stream.n_samples} samples",
            path,
            where,
            "the file holds no data rows; export it again",
        )
    for ch, a in damage_checked(stream).items():
        if len(a) != stream.n_samples:
            raise InputError(f"channel {ch} has {len(a)} samples, time has {stream.n_samples}",
                             path, where, "export the file again")  # fmt: skip
        b = np.asarray(a, dtype=float).reshape(len(a), -1)
        with np.errstate(invalid="ignore"):  # per axis: one of ±inf or 1e308 only passed
            usable = (np.abs(b) <= IMPLAUSIBLE.get(ch, np.inf)).any(axis=0)
        if not usable.all():
            axes = "wxyz" if len(usable) == 4 else "xyz"
            axis = f" in axis {axes[int(np.argmin(usable))]}" if len(usable) > 1 else ""
            raise InputError(
                f"channel {ch} holds no usable numbers{axis} (all NaN, ±inf or beyond what a "
                f"sensor measures, as 1e308)",
                path,
                f"{where}, channel {ch}",
                "export the channel again or leave it out of the export",
            )
    _check_flat(stream, path)


def _check_flat(stream: SensorStream, path: Path) -> None:
    """Refuse a gyroscope that reads one value throughout while the accelerometer sees gravity
    turn by more than :data:`FLAT_TILT_DEG`: the sensor turned, which no gyroscope misses (noise
    alone moves it), so it was off or not recorded (a dead gyroscope read as zeros made a
    walking shank look still beside its thigh)."""
    if stream.gyr is None or stream.acc is None:
        return
    gyr, acc = (np.asarray(a, dtype=float) for a in (stream.gyr, stream.acc))
    finite = gyr[np.isfinite(gyr).all(axis=1)]
    if len(finite) < FLAT_MIN_SAMPLES or np.ptp(finite, axis=0).any():
        return
    ok = acc[np.isfinite(acc).all(axis=1)]
    steps = np.diff(np.asarray(stream.time, dtype=float))
    steps = steps[np.isfinite(steps)]
    dt = float(np.median(steps)) if len(steps) else float("nan")
    if not (np.isfinite(dt) and dt > 0):  # the clock is repaired later; judged as it comes
        return
    # gravity's direction over stretches of FLAT_MEAN_S (at most FLAT_STRETCHES of them)
    n = max(1, int(round(FLAT_MEAN_S / dt)), -(-len(ok) // FLAT_STRETCHES))
    k = len(ok) // n
    if k == 0:
        return
    ups = ok[: k * n].reshape(k, n, 3).mean(axis=1)
    norm = np.linalg.norm(ups, axis=1)
    ups = ups[norm > 0] / norm[norm > 0, None]  # an accelerometer of zeros sees no gravity
    if len(ups) < 2:
        return
    turned = float(np.degrees(np.arccos(np.clip(ups @ ups.T, -1.0, 1.0))).max())
    if turned <= FLAT_TILT_DEG:
        return
    raise InputError(
        f"channel gyr reads ({', '.join(f'{v:g}' for v in finite[0])}) on every one of its "
        f"{len(finite)} samples while the accelerometer sees gravity turn by {turned:.0f}°: it "
        "was off or not recorded",
        path,
        f"sensor {stream.label}, channel gyr",
        "record with the gyroscope on, or leave it out of the export",
    )


def _check_clock(stream: SensorStream, path: Path) -> None:
    """Refuse time stamps no clock gives: beyond ±:data:`TIME_MAX_S`, or a sampling rate
    outside :data:`RATE_RANGE_HZ` (the stream's clock is repaired: finite and increasing)."""
    t = stream.time
    where = f"sensor {stream.label}"
    big = np.flatnonzero(np.abs(t) > TIME_MAX_S)
    if len(big):
        raise InputError(
            f"time stamp {t[big[0]]:.3g} s is not a time",
            path,
            f"{where}, data row {big[0] + 1}",
            "check the time column and its unit, or export the file again",
        )
    rate = stream.rate_hz
    if len(t) < 2:  # every row had the same stamp (duplicates are dropped): no rate to check
        raise InputError(
            f"{len(t)} distinct time stamp{'s' if len(t) != 1 else ''}: the time does not advance",
            path,
            where,
            "check the time column, or export the file again",
        )
    stated = float(stream.attrs.get("nominal_rate_hz") or np.nan)
    if np.isfinite(stated) and stated > 0 and max(rate / stated, stated / rate) > UNIT_FACTOR:
        raise InputError(  # a factor of 10 is no clock's error: ms read as µs, say
            f"the time stamps give {rate:.4g} Hz, the file's header says {stated:g} Hz",
            path,
            where,
            "the time column is in another unit than the format's: export the file again",
        )
    if not RATE_RANGE_HZ[0] <= rate <= RATE_RANGE_HZ[1]:
        raise InputError(
            f"sampling rate {rate:.3g} Hz from the time stamps",
            path,
            where,
            f"a sensor samples at {RATE_RANGE_HZ[0]:g} to {RATE_RANGE_HZ[1]:g} Hz: "
            "check the time column and its unit",
        )


def _check_quaternions(stream: SensorStream) -> tuple[SensorStream, dict[str, Any]]:
    """Quaternions that are no orientation (norm far from 1, e.g. all zero) become NaN
    (missing), counted in the report; a channel with none left is dropped."""
    if stream.quat is None:
        return stream, {}
    q = np.asarray(stream.quat, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        norm = np.sqrt(np.einsum("ij,ij->i", q, q))
    finite = np.isfinite(q).all(axis=1)
    bad = finite & ~((norm >= QUAT_NORM_RANGE[0]) & (norm <= QUAT_NORM_RANGE[1]))
    if not bad.any():
        return stream, {}
    report: dict[str, Any] = {"quat_invalid_samples": int(bad.sum())}
    if (bad | ~finite).all():
        report["quat_dropped"] = "no quaternion has unit norm (e.g. all zero)"
        return dataclasses.replace(stream, quat=None), report
    q = q.copy()
    q[bad] = np.nan
    return dataclasses.replace(stream, quat=q), report


def _check_rate(
    rate: float,
    streams: list[SensorStream],
    markers: list[MarkerSet],
    paths: Sequence[Path],
) -> None:
    """Refuse a ``rate`` beyond :data:`UPSAMPLE_MAX` times the highest native rate, or whose
    session would be larger than 4× the inputs + 256 MiB — before anything is allocated."""
    natives = [s.rate_hz for s in streams] + [m.rate_hz for m in markers]
    native = max((r for r in natives if np.isfinite(r)), default=float("nan"))
    if np.isfinite(native) and rate > UPSAMPLE_MAX * native:
        raise InputError(
            f"rate={rate:g} Hz is more than {UPSAMPLE_MAX:g}× the highest native rate "
            f"({native:.4g} Hz)",
            remedy=f"give rate={native:.4g} or less",
            argument="rate",
        )
    if rate < RATE_RANGE_HZ[0]:
        raise InputError(
            f"rate={rate:g} Hz", remedy=f"give at least {RATE_RANGE_HZ[0]:g} Hz", argument="rate"
        )
    columns = [
        1 + sum(np.asarray(a).reshape(len(a), -1).shape[1] for a in (s.acc, s.gyr, s.mag, s.quat)
                if a is not None) + len(s.extra)
        for s in streams
    ]  # fmt: skip
    columns += [1 + 4 * m.n_markers + 4 * len(m.rigid_bodies) for m in markers]
    durations = [s.duration_s for s in streams] + [float(m.time[-1] - m.time[0]) for m in markers]
    estimate = sum(8 * c * (d * rate + 1) for c, d in zip(columns, durations, strict=True))
    budget = 4 * sum(p.stat().st_size for p in paths) + (256 << 20)
    if estimate > budget:
        raise InputError(
            f"rate={rate:g} Hz would make a session of about {estimate / 2**20:,.0f} MiB",
            remedy="give a lower rate=",
            argument="rate",
        )
    short = [s.label for s in streams if s.duration_s * rate < 1]
    if short:
        raise InputError(
            f"rate={rate:g} Hz leaves sensor {short[0]} with fewer than 2 samples",
            remedy="give a higher rate=",
            argument="rate",
        )


#: the remedy when two files hold one device: a map cannot tell them apart (it keys by serial)
#: the time stamps' rate this many times the header's, or less than its share, is a time column
#: in another unit (a 10 % difference is a warning, :mod:`motionlab.qc`)
UNIT_FACTOR = 10.0
#: longest sensor name (characters): it titles report rows and names the session file's groups
LABEL_MAX = 100
SAME_DEVICE = "give each device's recording once (the same recording exported twice?)"


def _unique_label(
    stream: SensorStream, path: Path, seen: dict[str, tuple[Path, str]]
) -> SensorStream:
    label = stream.label.strip().replace("/", "_") or stream.serial or path.stem
    path = Path(stream.attrs.get("device_folder", path))  # a folder per device (x-IMU3)
    if label.strip(".") == "" or not label.isprintable() or len(label) > LABEL_MAX:
        what = "is only dots" if label.strip(".") == "" else (
            f"is {len(label)} characters long" if len(label) > LABEL_MAX
            else "holds control or undecodable characters")  # fmt: skip
        raise InputError(
            f"sensor name {shorten(repr(label), 40)} {what}: it cannot name a sensor",
            path,
            remedy="give the sensor a label in the sensor map (sensors: <serial or name>: "
            "{label: ...}) or rename the device",
        )
    if label in seen:
        other, serial = seen[label]
        same = bool(serial) and serial == stream.serial
        raise InputError(
            f"{'device ' + serial if same else 'sensor label ' + repr(label)} also comes from "
            f"{other.name}",
            path,
            f"sensor {label}",
            SAME_DEVICE
            if same
            else "give each sensor its own label in the sensor map "
            "(sensors: <serial>: {label: ...})",
        )
    seen[label] = (path, stream.serial)
    return dataclasses.replace(stream, label=label) if label != stream.label else stream


def _check_marker_clock(m: MarkerSet, path: Path) -> None:
    t = np.asarray(m.time, dtype=float)
    if len(t) < 2:
        raise InputError(f"{len(t)} frame{'s' if len(t) != 1 else ''}: too few to follow a "
                         "marker", path, f"marker set {m.name}",
                         "export the whole trial from the motion-capture software")  # fmt: skip
    bad = np.flatnonzero(~np.isfinite(t[1:]) | (np.diff(t) <= 0))
    if len(bad):
        raise InputError(
            "frame times are not strictly increasing",
            path,
            f"marker set {m.name}, frame {int(bad[0]) + 2 if len(bad) else 1}",
            "export the optical file again",
        )


def _resample_markers(m: MarkerSet, rate: float) -> MarkerSet:
    arrays: dict[str, np.ndarray] = {}
    if m.positions is not None:
        arrays["positions"] = m.positions
    if m.residuals is not None:
        arrays["residuals"] = m.residuals
    grid = timebase.regular_grid(m.time[0], m.time[-1], rate)
    out = timebase.interpolate_rows(m.time, arrays, grid)
    bodies = {
        k: timebase.interpolate_rows(m.time, {"quat": q}, grid)["quat"]
        for k, q in m.rigid_bodies.items()
    }
    return dataclasses.replace(
        m,
        time=grid,
        positions=out.get("positions"),
        residuals=out.get("residuals"),
        rigid_bodies=bodies,
        attrs={**m.attrs, "resampled_to_hz": float(rate)},
    )


def _check_units(stream: SensorStream, path: Path) -> None:
    """Refuse an accelerometer whose ‖a‖ at rest cannot be gravity in m/s²
    (:func:`motionlab.qc.acc_unit_problem`: rest detection, the fusion's trust in the
    accelerometer and every threshold in m/s² would be off) and a gyroscope whose rotation fits
    the accelerometer's tilt only in another unit (``qc["flags"]["gyr_unit_mismatch"]``,
    :func:`motionlab.qc.gyr_scale`): every orientation would turn 57.3 times too fast or too
    slow; then an accelerometer that varies where the gyroscope reads the sensor still (the two
    channels swapped, :func:`motionlab.qc.swapped_problem`)."""
    problem = acc_unit_problem(stream)
    if problem is None and stream.qc["flags"].get("gyr_unit_mismatch"):
        problem = gyr_unit_problem(stream)
    problem = problem or swapped_problem(stream)
    if problem:
        raise InputError(problem[0], path, f"sensor {stream.label}", problem[1])


def check_and_fill(
    stream: SensorStream, report: dict[str, Any], gap_max: float, path: Path | None = None
) -> SensorStream:
    """Step 4 for one stream whose clock is repaired: quality checks on the data as recorded,
    then runs of samples not a number in the accelerometer or gyroscope longer than the fusion
    bridges or ``gap_max`` s dropped (:func:`motionlab.timebase.drop_nan_runs`: the gap of the
    lost packets they are; ``qc["nan_rows_dropped"]``, ``qc["nan_dropped_s"]``), then gaps up
    to ``gap_max`` s filled; the stream with its ``qc``, which also holds the clock repair
    ``report`` of :func:`motionlab.timebase.repair_clock`."""
    qc = check_stream(stream, gap_max)
    if qc["flags"].get("gyr_unit_unchecked") and path is not None:  # the warning names it
        qc["gyr_unit_source"] = _origin(stream, path)
    stream, dropped, gaps = _nan_runs_as_gaps(stream, gap_max, path)
    qc.update(dropped)
    qc.update(report)
    qc.update(gaps)
    repaired = report["duplicates_dropped"] + report["reordered"] + report["restamped"]
    qc["flags"].update(
        quat_invalid=bool(report.get("quat_invalid_samples")),
        gaps=bool(gaps["gaps"]),
        dropped_samples=gaps["dropped_samples"] > 0,
        clock_repaired=bool(repaired),
    )
    return dataclasses.replace(stream, qc=qc)


def _nan_runs_as_gaps(
    stream: SensorStream, gap_max: float, path: Path | None = None
) -> tuple[SensorStream, dict[str, Any], dict[str, Any]]:
    """``stream`` without its runs of samples not a number in the accelerometer or gyroscope
    longer than the fusion bridges or ``gap_max`` s (:func:`motionlab.timebase.drop_nan_runs`:
    the gap of the lost packets they are), then its gaps up to ``gap_max`` s filled at the rate
    recorded before the drop; with ``{"nan_rows_dropped", "nan_dropped_s"}`` (empty when none
    was dropped) and the gap report of :func:`motionlab.timebase.fill_short_gaps`."""
    dt = timebase.nominal_interval(stream.time)  # the rate recorded, NaN rows and all
    out, spans = timebase.drop_nan_runs(stream, min(gap_max, timebase.NAN_BRIDGE_MAX_S), path)
    dropped = (
        {"nan_rows_dropped": stream.n_samples - out.n_samples, "nan_dropped_s": spans}
        if spans
        else {}
    )
    out, gaps = timebase.fill_short_gaps(out, gap_max, dt)
    return out, dropped, gaps


def drop_kept_nan_runs(stream: SensorStream) -> SensorStream:
    """An ingested stream (with ``qc``) without the long NaN runs of its accelerometer or
    gyroscope that its ingest kept (:func:`check_and_fill` drops them: a session ingested before
    it did, or one resampled with ``--rate``, which puts NaN inside a kept gap), filled or kept as
    the gaps they are, with ``qc["gaps"]`` the kept gaps again; the stream itself without them."""
    gap_max = float(stream.qc.get("gap_max_s", DEFAULT_GAP_MAX))
    out, dropped, gaps = _nan_runs_as_gaps(stream, gap_max)
    if not dropped:
        return stream
    qc = {**stream.qc, **dropped, "gaps": gaps["gaps"], "flags": dict(stream.qc.get("flags", {}))}
    for key in ("gaps_filled", "samples_filled", "filled_spans_s"):
        qc[key] = qc.get(key, 0 if key != "filled_spans_s" else []) + gaps[key]
    qc["flags"]["gaps"] = bool(gaps["gaps"])
    return dataclasses.replace(out, qc=qc)


def ingest(
    paths: Sequence[str | Path],
    sensor_map: SensorMap | str | Path | None = None,
    rate: float | None = None,
    gap_max: float = DEFAULT_GAP_MAX,
    command: str | None = None,
) -> Session:
    """Read ``paths`` into one session with a common clock, quality checks and provenance.

    Parameters
    ----------
    paths
        Recording files (any format :func:`motionlab.io.read_any` knows).
    sensor_map
        A :class:`~motionlab.sensor_map.SensorMap` or the path of its YAML file.
    rate
        If given (Hz), resample every stream onto the clock ``k / rate``.
    gap_max
        Gaps up to this long (s) are interpolated, longer ones kept as missing.
    command
        The command line for the provenance log (default: ``sys.argv``).
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise InputError("no input files", remedy="give one or more recording files")
    if not gap_max >= 0:  # inf: every gap interpolated; NaN: no number
        raise InputError(f"gap_max={gap_max:g} s is not a gap", remedy="give 0 s or more",
                         argument="gap_max")  # fmt: skip
    if rate is not None and not 0 < rate < np.inf:
        raise InputError(
            f"rate={rate:g} Hz is not a sampling rate",
            remedy="give a rate above 0 Hz, or leave it out to keep the recorded clock",
            argument="rate",
        )
    map_path = None
    if sensor_map is not None and not isinstance(sensor_map, SensorMap):
        sensor_map = load_sensor_map(sensor_map)
        map_path = sensor_map.path  # the installed copy of an example map outside the repository
    smap = sensor_map or SensorMap()

    streams: list[tuple[SensorStream, Path]] = []
    markers: list[tuple[MarkerSet, Path]] = []
    files: dict[str, Any] = {}
    read_files: list[Path] = []  # what was read, for the provenance (a folder: its files)
    xsens: list[tuple[SensorStream, Path]] = []  # Xsens exports, maybe of one recording
    for path in paths:
        rec = read_any(path, smap.reader or None)
        if not rec.sensors and not rec.markers:
            raise InputError("no sensors or markers found", path,
                             remedy="check that the file holds a recording")  # fmt: skip
        files[path.name] = {"format": rec.format, **rec.metadata}
        read_files += [Path(f) for f in rec.metadata.get("files", [])] or [path]
        streams += [(s, path) for s in rec.sensors]
        markers += [(m, path) for m in rec.markers]
        xsens += [(s, path) for s in rec.sensors] if rec.format == "xsens" else []
    if xsens:  # the reader (pandas, scipy) only when an Xsens file was read
        from motionlab.io.xsens import mark_one_recording

        mark_one_recording(xsens)

    streams, unmatched = _apply_map(streams, smap)
    seen: dict[str, tuple[Path, str]] = {}
    streams = [(_unique_label(s, p, seen), p) for s, p in streams]
    checked = []
    for stream, path in streams:
        stream, quat_report = _check_quaternions(stream)
        _check_channels(stream, path)
        checked.append((stream, path, quat_report))
    repaired = []
    for stream, path, quat_report in checked:
        stream, report = timebase.repair_clock(stream, path)
        _check_clock(stream, path)
        repaired.append((stream, report | quat_report, path))
    for m, path in markers:
        _check_marker_clock(m, path)
        if np.abs(m.time[[0, -1]]).max() > TIME_MAX_S:
            raise InputError(
                f"frame time {m.time[-1]:.3g} s is not a time",
                path,
                f"marker set {m.name}",
                "check the rate and the first frame, or export the file again",
            )
    if rate is not None:
        _check_rate(rate, [s for s, _, _ in repaired], [m for m, _ in markers], paths)

    starts = [float(s.time[0]) for s, _, _ in repaired] + [float(m.time[0]) for m, _ in markers]
    origin = min(starts)
    session = Session(
        metadata={
            "subject": smap.subject,
            "session": smap.session,
            "files": files,
            "time_origin_s": origin,
            "start_spread_s": max(starts) - origin,
            # starts a day or more apart: the files' clocks are unrelated (e.g. Unix time and
            # a clock that starts at 0) and the streams still need synchronising
            "clocks_unrelated": max(starts) - origin > UNRELATED_CLOCKS_S,
        }
    )
    if unmatched:
        session.metadata["map_unmatched"] = unmatched
    recorded = sorted({s.attrs["recorded"] for s, _, _ in repaired if s.attrs.get("recorded")})
    if recorded:  # the day the files say they were recorded (the earliest, if they differ)
        session.metadata["recorded"] = recorded[0]
    for stream, report, path in repaired:
        stream = dataclasses.replace(
            stream,
            time=stream.time - origin,
            attrs={**stream.attrs, "start_s": float(stream.time[0])},
        )
        stream = check_and_fill(stream, report, gap_max, path)
        _check_units(stream, path)
        if rate is not None:
            qc = stream.qc
            stream = timebase.resample(stream, rate)
            qc["resampled_to_hz"] = float(rate)
            stream.qc = qc
        session.sensors[stream.label] = stream
    mark_identical_streams(session.sensors)
    for m, _ in markers:
        m = dataclasses.replace(
            m, time=m.time - origin, attrs={**m.attrs, "start_s": float(m.time[0])}
        )
        if rate is not None:
            m = _resample_markers(m, rate)
        name = m.name
        n = 2
        while name in session.markers:
            name, n = f"{m.name}_{n}", n + 1
        session.markers[name] = dataclasses.replace(m, name=name)

    inputs: list[Path] = read_files + ([map_path] if map_path else [])
    session.add_provenance(
        command,
        parameters={
            "stage": "ingest",
            "rate_hz": rate,
            "gap_max_s": gap_max,
            "map": str(map_path) if map_path else None,
        },
        inputs=inputs,
    )
    return session
