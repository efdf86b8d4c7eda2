"""Marker maps: which optical markers form which segment's cluster, and which are landmarks.

A marker map is a YAML file; every error names the key and its line. Schema::

    marker_set: optical          # optional: the marker set to use when a file holds several
    max_gap_s: 0.1               # optional: longest cluster gap filled by interpolation (s)
    lowpass_hz: 6                # optional: low-pass of the cluster poses (Hz; 0 = raw)
    static_time_s: [3.0, 8.0]    # optional: where landmarks are read (reference clock, s);
                                 # default: the longest still window showing landmarks
                                 # (validation/cast.py); a static trial (--static) wins
    segments:
      thigh_r:
        cluster: [RTH1, RTH2, RTH3, RTH4]   # three or more markers on one rigid plate
        landmarks: [RGT, RLE, RME]          # optional; default: the protocol's landmarks
        sensor: thigh_r                     # optional IMU label; default: the session's
                                            # sensor on the segment
        frame:                              # optional: the anatomical frame, when the default
          primary: {axis: z, from: [RME], to: [RLE]}        # recipe for the segment kind
          secondary: {axis: y, from: [RLE, RME], to: [RGT]} # (validation/anatomy.py) does not fit
      pelvis:
        rigid_body: pelvis                  # a rigid body of the file, taken as it is
        segment_frame: true                 # optional: its frame is the anatomical segment
                                            # frame (ISB: x anterior, y up, z right); default
                                            # false: an arbitrary body frame, carried to the
                                            # segment through the IMU's calibration

Without a map, :func:`default_marker_map` builds one: a rigid body named after a segment or
sensor, else the markers whose labels start with ``<segment>_`` form its cluster.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.protocol import AXES, Protocol
from motionlab.session import MarkerSet
from motionlab.validation.anatomy import Direction, FrameRecipe
from motionlab.validation.optical import DEFAULT_LOWPASS_HZ, DEFAULT_MAX_GAP_S, MIN_MARKERS
from motionlab.yamlsafe import LineLoader, load_yaml


@dataclass
class SegmentMap:
    """Optical data of one segment: a marker cluster or a rigid body, and its landmarks.

    ``landmarks`` ``None`` means "the protocol's"; ``frame`` an explicit anatomical recipe
    naming markers directly; ``line`` the segment's line in the map file (0: built in code).
    """

    name: str
    cluster: list[str] = field(default_factory=list)
    rigid_body: str | None = None
    landmarks: list[str] | None = None
    sensor: str | None = None
    frame: FrameRecipe | None = None
    line: int = 0
    segment_frame: bool = False


@dataclass
class MarkerMap:
    segments: dict[str, SegmentMap]
    marker_set: str | None = None
    max_gap_s: float = DEFAULT_MAX_GAP_S
    lowpass_hz: float = DEFAULT_LOWPASS_HZ
    static_time_s: tuple[float, float] | None = None
    path: Path | None = None


class _Checker:
    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, line: int | None, message: str, remedy: str) -> None:
        where = f"line {line}, key {key}" if line else f"key {key}"
        raise InputError(message, self.path, where, remedy)

    def number(self, doc: dict, key: str, default: float, remedy: str) -> float:
        value = doc.get(key, default)
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not np.isfinite(value)  # .nan or .inf: no cut-off, no gap length
            or value < 0
        ):
            self.fail(key, doc.lines.get(key), f"is {value!r}", remedy)
        return float(value)

    def names(self, value: Any, key: str, line: int | None) -> list[str]:
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            self.fail(key, line, f"is {value!r}, expected a list of marker names", "e.g. [A, B]")
        return [v.strip() for v in value]

    def direction(self, spec: Any, key: str, line: int | None) -> Direction:
        if not isinstance(spec, dict) or set(spec) != {"axis", "from", "to"}:
            self.fail(
                key, line, "needs exactly axis, from and to", "e.g. {axis: z, from: [A], to: [B]}"
            )
        lines = getattr(spec, "lines", {})
        axis = spec["axis"]
        if axis not in AXES:
            self.fail(f"{key}.axis", lines.get("axis", line), f"axis {axis!r}", "x, y or z")
        start = self.names(spec["from"], f"{key}.from", lines.get("from", line))
        end = self.names(spec["to"], f"{key}.to", lines.get("to", line))
        return Direction(axis, [start], [end])


def load_marker_map(path: str | Path) -> MarkerMap:
    """Load and validate a marker map YAML file (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such marker map", path, remedy="check the path")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError("not a text file", path, remedy="give a marker map YAML file") from None
    doc = load_yaml(text, LineLoader, path, "check indentation and colons")
    c = _Checker(path)
    if not isinstance(doc, dict):
        c.fail("(top level)", 1, "is not a mapping", "start from the example in the docs")
    lines = doc.lines
    known = {"marker_set", "max_gap_s", "lowpass_hz", "static_time_s", "segments"}
    for key in doc:
        if key not in known:
            c.fail(str(key), lines.get(key), "unknown key", f"use {', '.join(sorted(known))}")
    segs = doc.get("segments")
    if not isinstance(segs, dict) or not segs:
        c.fail("segments", lines.get("segments", 1), "missing or empty", "map at least one segment")
    gap = c.number(doc, "max_gap_s", DEFAULT_MAX_GAP_S, "give seconds ≥ 0, e.g. 0.1")
    lowpass = c.number(doc, "lowpass_hz", DEFAULT_LOWPASS_HZ, "give Hz ≥ 0, e.g. 10 (0: off)")
    static = doc.get("static_time_s")
    if static is not None and not _is_range(static):
        c.fail(
            "static_time_s", lines.get("static_time_s"), f"is {static!r}", "give [start_s, end_s]"
        )
    marker_set = doc.get("marker_set")
    if marker_set is not None and not isinstance(marker_set, str):
        c.fail("marker_set", lines.get("marker_set"), f"is {marker_set!r}", "give a name")
    segments = {
        str(name): _segment(c, str(name), spec, segs.lines.get(name)) for name, spec in segs.items()
    }
    return MarkerMap(
        segments=segments,
        marker_set=marker_set,
        max_gap_s=gap,
        lowpass_hz=lowpass,
        static_time_s=tuple(float(v) for v in static) if static else None,
        path=path,
    )


def _is_range(value: Any) -> bool:
    if not isinstance(value, list) or len(value) != 2:
        return False
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    return numbers and value[0] < value[1]


def _segment(c: _Checker, name: str, spec: Any, line: int | None) -> SegmentMap:
    key = f"segments.{name}"
    if not isinstance(spec, dict):
        c.fail(key, line, "is not a mapping", "give cluster: [...] or rigid_body: NAME")
    lines = spec.lines
    allowed = {"cluster", "rigid_body", "landmarks", "sensor", "frame", "segment_frame"}
    for k in spec:
        if k not in allowed:
            c.fail(f"{key}.{k}", lines.get(k), "unknown key", f"use {', '.join(sorted(allowed))}")
    has_cluster, has_body = "cluster" in spec, "rigid_body" in spec
    if has_cluster == has_body:
        c.fail(key, line, "needs either cluster or rigid_body", "give one of the two")
    cluster = []
    if has_cluster:
        cluster = c.names(spec["cluster"], f"{key}.cluster", lines.get("cluster"))
        if len(set(cluster)) < MIN_MARKERS:
            c.fail(
                f"{key}.cluster",
                lines.get("cluster"),
                f"has {len(set(cluster))} distinct markers",
                f"a cluster needs at least {MIN_MARKERS}",
            )
    body = spec.get("rigid_body")
    if has_body and (not isinstance(body, str) or not body):
        c.fail(f"{key}.rigid_body", lines.get("rigid_body"), f"is {body!r}", "give a name")
    landmarks = None
    if "landmarks" in spec:
        landmarks = c.names(spec["landmarks"], f"{key}.landmarks", lines.get("landmarks"))
    sensor = spec.get("sensor")
    if sensor is not None and not isinstance(sensor, str):
        c.fail(f"{key}.sensor", lines.get("sensor"), f"is {sensor!r}", "give a sensor label")
    frame = None
    if "frame" in spec:
        f = spec["frame"]
        fline = lines.get("frame")
        if not isinstance(f, dict) or set(f) != {"primary", "secondary"}:
            c.fail(f"{key}.frame", fline, "needs primary and secondary", "see the marker map docs")
        flines = f.lines
        first = c.direction(f["primary"], f"{key}.frame.primary", flines.get("primary"))
        second = c.direction(f["secondary"], f"{key}.frame.secondary", flines.get("secondary"))
        if first.axis == second.axis:
            c.fail(f"{key}.frame", fline, "primary and secondary share an axis", "use two axes")
        frame = FrameRecipe(first, second)
    segment_frame = spec.get("segment_frame", False)
    if not isinstance(segment_frame, bool) or (segment_frame and not has_body):
        c.fail(f"{key}.segment_frame", lines.get("segment_frame"), f"is {segment_frame!r}",
               "true or false, for a rigid_body")  # fmt: skip
    return SegmentMap(name, cluster, body, landmarks, sensor, frame, line or 0, segment_frame)


def check_marker_map(mmap: MarkerMap, markers: MarkerSet) -> None:
    """Raise :class:`InputError` (map key and line) when a cluster marker or rigid body is not
    in ``markers``."""
    labels = set(markers.labels)
    for seg in mmap.segments.values():
        where = f"line {seg.line}, key segments.{seg.name}" if seg.line else f"segment {seg.name}"
        missing = [m for m in seg.cluster if m not in labels]
        if missing:
            raise InputError(
                f"marker {', '.join(missing)} is not in marker set '{markers.name}'",
                mmap.path,
                where,
                f"its labels are {', '.join(markers.labels[:12])}"
                + (" …" if len(markers.labels) > 12 else ""),
            )
        if seg.rigid_body and seg.rigid_body not in markers.rigid_bodies:
            raise InputError(
                f"rigid body '{seg.rigid_body}' is not in marker set '{markers.name}'",
                mmap.path,
                where,
                f"its rigid bodies are {', '.join(markers.rigid_bodies) or 'none'}",
            )


def default_marker_map(
    markers: MarkerSet, protocol: Protocol | None = None, sensors: list[str] = ()
) -> MarkerMap:
    """A map from names alone: for each protocol segment (else each sensor label) a rigid body
    of the same name, else the markers labelled ``<segment>_…`` (three or more), with the
    protocol's landmarks. Raises :class:`InputError` when nothing matches."""
    names = list(protocol.segments) if protocol is not None else list(sensors)
    if not names:
        names = list(markers.rigid_bodies)
    landmark_names = set()
    if protocol is not None:
        landmark_names = {lm for s in protocol.segments.values() for lm in s.landmarks}
    segments = {}
    for name in names:
        if name in markers.rigid_bodies:
            segments[name] = SegmentMap(name, rigid_body=name)
            continue
        cluster = [
            lab
            for lab in dict.fromkeys(markers.labels)
            if lab.startswith(f"{name}_") and lab not in landmark_names
        ]
        if len(cluster) >= MIN_MARKERS:
            segments[name] = SegmentMap(name, cluster=cluster)
    if not segments and len(names) == 1 and len(markers.rigid_bodies) == 1:
        body = next(iter(markers.rigid_bodies))
        segments[names[0]] = SegmentMap(names[0], rigid_body=body)
    if not segments:  # the reference lacks them: named, not the session being validated
        looked = ", ".join(names[:6]) + (" …" if len(names) > 6 else "")
        raise InputError(
            f"no segment found in marker set '{markers.name}' by name (a rigid body, or 3+ "
            f"markers <segment>_…, for {looked})",
            markers.attrs.get("source_file"),
            remedy="give marker_map=map.yaml naming each segment's cluster markers",
            argument="marker_map",
        )
    return MarkerMap(segments=segments, marker_set=markers.name)
