"""The optical reference: reading it, and one orientation stream per mapped segment.

Each segment of the marker map becomes an :class:`OpticalSegment`: the orientation of its marker
cluster (:func:`~motionlab.validation.optical.track_cluster`) or of its rigid body (taken as it
is), on the reference clock, in the lab frame; and, when its landmarks define one
(:mod:`~motionlab.validation.anatomy`), the constant rotation from the anatomical segment frame
to the cluster frame. The landmarks are fixed in the cluster frame by CAST
(:mod:`~motionlab.validation.cast`): in a separate static trial, in the map's
``static_time_s``, or else in the longest still window in which landmarks are seen; a label
recorded on two segments goes to each by the landmark lists, and a landmark that moves more
than ``MAX_LANDMARK_SPREAD_M`` in the cluster frame during the static window is left out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.io import read_any
from motionlab.protocol import Protocol
from motionlab.results import OpticalSegmentInfo
from motionlab.session import MarkerSet, is_session_file, load_session
from motionlab.validation.anatomy import anatomical_frame, recipe_for
from motionlab.validation.cast import (
    MAX_LANDMARK_SPREAD_M,
    assign_landmarks,
    calibrate_landmarks,
    reconstruct,
    static_window,
)
from motionlab.validation.markermap import MarkerMap, SegmentMap
from motionlab.validation.optical import rigid_fit, track_cluster


@dataclass
class OpticalSegment:
    """One segment seen by the optical system (see the module docstring).

    ``quat`` (N, 4) maps the cluster (or rigid body) frame into the lab frame at ``time``
    (reference clock) and ``origin`` (N, 3, m) is the cluster origin there (``None`` for a rigid
    body); ``local`` holds the landmarks fixed in the cluster frame (label → (3,), m);
    ``anatomical`` (4,) maps the anatomical segment frame into the cluster frame, ``None`` when
    the landmarks do not define it, and ``landmarks`` names those it was built from; ``info``:
    what the tracking and the landmarks gave (stored in :attr:`Validation.optical
    <motionlab.results.Validation.optical>` with ``source``, ``landmarks`` and the frame used).
    """

    name: str
    time: np.ndarray
    quat: np.ndarray
    source: str
    origin: np.ndarray | None = None
    anatomical: np.ndarray | None = None
    landmarks: list[str] = field(default_factory=list)
    local: dict[str, np.ndarray] = field(default_factory=dict)
    info: OpticalSegmentInfo = field(default_factory=OpticalSegmentInfo)

    def segment_quat(self) -> np.ndarray | None:
        """Anatomical segment → lab orientation (N, 4), or ``None`` without landmarks."""
        if self.anatomical is None:
            return None
        return rot.mul(self.quat, self.anatomical)

    def landmark_trajectories(self) -> dict[str, np.ndarray]:
        """The landmarks reconstructed in every frame through the cluster pose (CAST): label →
        (N, 3) lab positions (m), NaN where the cluster pose is unknown."""
        if self.origin is None or not self.local:
            return {}
        points = reconstruct(self.quat, self.origin, np.array(list(self.local.values())))
        return {label: points[:, i] for i, label in enumerate(self.local)}


#: what a reference can be, for a file of no format the readers know
REFERENCE_FORMATS = (
    "give markers as C3D or TRC (Motive, Nexus and QTM export them), a session with markers, "
    "or a CSV of segment quaternions: time, <segment>_qw, _qx, _qy, _qz (README, 'Validate')"
)


def _unknown_reference(path: Path) -> str:
    """What a reference file of no known format is, in one phrase (an OptiTrack Motive CSV
    export by its first line)."""
    try:
        with path.open(encoding="utf-8", errors="replace") as f:
            first = f.readline(200)
    except OSError:
        first = ""
    if first.lstrip("\ufeff").startswith("Format Version,"):
        return "an OptiTrack Motive CSV export, which motionlab does not read as a reference"
    return "unknown reference format"


def read_reference(path: str | Path, model_outputs_ok: bool = False) -> list[MarkerSet]:
    """Marker sets of a reference file: a motionlab session, or any file the readers know
    (``model_outputs_ok``: a C3D of model outputs only is fine: joint angles as reference)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such reference file", path, remedy="check the path")
    if is_session_file(path):
        sets = list(load_session(path).markers.values())
    else:
        try:
            sets = read_any(path).markers
        except InputError as exc:  # its remedy is a sensor map's column map: no reference
            if not exc.message.startswith("unknown file format"):
                raise
            raise InputError(_unknown_reference(path), path, remedy=REFERENCE_FORMATS) from None
    if not sets:
        raise InputError(
            "holds no optical data", path, remedy="give a C3D/TRC file or a session with markers"
        )
    if not any(m.n_markers or m.rigid_bodies for m in sets):
        kinds = sorted({o.kind for m in sets for o in m.model_outputs.values()})
        if (
            kinds and not model_outputs_ok
        ):  # a C3D of model outputs only (Plug-in Gait angles…): no marker to track
            raise InputError(
                f"holds model outputs ({', '.join(kinds)}) but no markers or rigid bodies",
                path,
                remedy="give the C3D with the marker trajectories, or validate against its "
                "joint angles with reference_kind=angles",
                argument="reference_kind",
            )
    return sets


def choose_marker_set(sets: list[MarkerSet], name: str | None, path: str | Path | None = None):
    """The marker set called ``name``, or the only one."""
    if not sets:
        raise InputError(
            "holds no optical data", path, remedy="give reference=FILE.c3d", argument="reference"
        )
    if name is not None:
        for m in sets:
            if m.name == name:
                return m
        raise InputError(
            f"no marker set '{name}'",
            path,
            "marker_set",
            f"the file holds {', '.join(m.name for m in sets)}",
        )
    if len(sets) > 1:
        raise InputError(
            f"holds {len(sets)} marker sets", path, remedy="name one with marker_set: in the map"
        )
    return sets[0]


def _side(name: str, protocol: Protocol | None) -> str:
    if protocol is not None and name in protocol.segments:
        return protocol.segments[name].side
    return name[-1] if name[-2:] in ("_l", "_r") else ""


def _landmark_lists(mmap: MarkerMap, protocol: Protocol | None) -> dict[str, list[str]]:
    """Each segment's landmark labels (the map's, else the protocol's), in the protocol's
    segment order, then the map's other segments."""
    order = list(protocol.segments) if protocol is not None else []
    order += [name for name in mmap.segments if name not in order]
    out = {}
    for name in order:
        seg = mmap.segments.get(name)
        if seg is not None and seg.landmarks is not None:
            out[name] = seg.landmarks
        elif protocol is not None and name in protocol.segments:
            out[name] = protocol.segments[name].landmarks
    return out


def _cluster_segment(markers: MarkerSet, seg: SegmentMap, mmap: MarkerMap) -> OpticalSegment:
    idx = [markers.labels.index(m) for m in seg.cluster]
    track = track_cluster(
        markers.time, markers.positions[:, idx], seg.cluster, mmap.max_gap_s, mmap.lowpass_hz
    )
    info = OpticalSegmentInfo(**track.summary(), shape_m=track.shape)
    return OpticalSegment(seg.name, markers.time, track.quat, "cluster", track.origin, info=info)


def _static_pose(static: MarkerSet, seg: SegmentMap, o: OpticalSegment) -> tuple:
    """Cluster pose (quat, origin) in the frames of a static trial, in the cluster frame of the
    movement trial (its shape fitted onto the static trial's cluster markers)."""
    missing = [m for m in seg.cluster if m not in static.labels]
    if missing:
        raise InputError(
            f"cluster marker {', '.join(missing)} of segment {seg.name} is not in the static trial",
            where=f"static trial '{static.name}'",
            remedy="record the static trial with the same cluster labels",
        )
    idx = [static.labels.index(m) for m in seg.cluster]
    quat, origin, _ = rigid_fit(o.info.shape_m, static.positions[:, idx], residual=False)
    return quat, origin


def _landmark_rms(o: OpticalSegment, points: np.ndarray, labels: list[str], window) -> dict:
    """RMS distance (mm) between reconstructed and measured landmarks outside the static window,
    for the landmarks seen there in three frames or more."""
    outside = (o.time < window[0]) | (o.time > window[1])
    rebuilt = o.landmark_trajectories()
    out = {}
    for j, label in enumerate(labels):
        if label not in rebuilt:
            continue
        d = np.linalg.norm(rebuilt[label][outside] - points[outside, j], axis=1)
        d = d[np.isfinite(d)]
        if len(d) >= 3:
            out[label] = float(np.sqrt(np.mean(d**2)) * 1e3)
    return out


def _calibrate(
    segments: dict[str, OpticalSegment],
    markers: MarkerSet,
    mmap: MarkerMap,
    protocol: Protocol | None,
    static: MarkerSet | None,
) -> None:
    """Fix each cluster segment's landmarks in its cluster frame (:mod:`.cast`) and build its
    anatomical frame from them. Adds to each segment's ``info``: ``static_source`` and
    ``static_s`` (where the landmarks were read, on the clock of that recording),
    ``landmark_spread_mm`` (per landmark, in that window) and, without a static trial,
    ``landmark_rms_mm`` (reconstructed vs measured, where the landmark is seen outside it)."""
    wanted = _landmark_lists(mmap, protocol)
    if static is not None:
        if static.positions is None:
            raise InputError(
                "holds no marker trajectories",
                where=f"static trial '{static.name}'",
                remedy="give a static trial with the cluster markers and the landmarks",
            )
        ref, source = static, "static trial"
        columns = assign_landmarks(static.labels, wanted, f"static trial '{static.name}'")
        if not any(columns.get(k) for k in segments):
            names = sorted({lm for k in segments for lm in wanted.get(k, [])})
            raise InputError(
                f"holds none of the landmarks {', '.join(names[:8])}",
                where=f"static trial '{static.name}'",
                remedy="label the landmarks as the protocol or the marker map names them",
            )
        window = (float(static.time[0]), float(static.time[-1]))
    else:
        ref = markers
        columns = assign_landmarks(markers.labels, wanted, f"marker set '{markers.name}'")
        window, source = mmap.static_time_s, "static_time_s"
        if window is None:
            cols = sorted({c for k in segments for c in columns.get(k, {}).values()})
            seen = np.isfinite(markers.positions[:, cols]).all(axis=-1).any(axis=1)
            quats = [o.quat for o in segments.values()]
            window, source = static_window(markers.time, quats, seen), "still window"
        if window is None:
            window, source = (float(markers.time[0]), float(markers.time[-1])), "whole recording"
    for name, o in segments.items():
        cols = columns.get(name, {})
        if not cols:
            continue
        seg = mmap.segments[name]
        quat, origin = (o.quat, o.origin) if static is None else _static_pose(static, seg, o)
        use = np.isfinite(quat).all(axis=1) & (ref.time >= window[0]) & (ref.time <= window[1])
        points = ref.positions[:, list(cols.values())]
        local, spread = calibrate_landmarks(points, quat, origin, use)
        ok = spread <= MAX_LANDMARK_SPREAD_M
        o.local = {label: local[i] for i, label in enumerate(cols) if ok[i]}
        o.info.static_source = source
        o.info.static_s = [float(window[0]), float(window[1])]
        o.info.landmark_spread_mm = {
            label: float(spread[i] * 1e3) for i, label in enumerate(cols) if np.isfinite(spread[i])
        }
        if static is None:
            o.info.landmark_rms_mm = _landmark_rms(o, points, list(cols), window)
        recipe = seg.frame or recipe_for(name)
        if recipe is not None and o.local:
            found = anatomical_frame(recipe, o.local, _side(name, protocol), seg.frame is None)
            if found is not None:
                o.anatomical = rot.from_matrix(found[0])
                o.landmarks = found[1]


def optical_segments(
    markers: MarkerSet,
    mmap: MarkerMap,
    protocol: Protocol | None = None,
    static: MarkerSet | None = None,
) -> dict[str, OpticalSegment]:
    """One :class:`OpticalSegment` per marker-map segment; landmarks from ``markers`` (in the
    static window) or from a separate ``static`` trial."""
    out = {}
    for name, seg in mmap.segments.items():
        if seg.rigid_body:
            q = np.asarray(markers.rigid_bodies[seg.rigid_body], dtype=float)
            ok = np.isfinite(q).all(axis=1)
            info = OpticalSegmentInfo(fitted_fraction=float(ok.mean()), rigid_body=seg.rigid_body)
            out[name] = OpticalSegment(name, markers.time, q, "rigid_body", info=info)
            if seg.segment_frame:  # the body frame is the anatomical one (segment_frame: true)
                out[name].anatomical = rot.IDENTITY.copy()
                info.segment_frame = True
        else:
            out[name] = _cluster_segment(markers, seg, mmap)
    clusters = {k: o for k, o in out.items() if o.source == "cluster"}
    if clusters:
        _calibrate(clusters, markers, mmap, protocol, static)
    return out
