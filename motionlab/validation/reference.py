"""The optical reference: reading it, and one orientation stream per mapped segment.

Each segment of the marker map becomes an :class:`OpticalSegment`: the orientation of its marker
cluster (:func:`~motionlab.validation.optical.track_cluster`) or of its rigid body (taken as it
is), on the reference clock, in the lab frame; and, when its landmarks define one
(:mod:`~motionlab.validation.anatomy`), the constant rotation from the anatomical segment frame
to the cluster frame. Landmarks are expressed in the cluster frame in every directly fitted
frame (of the static window, if the map gives one) and their median is kept; when a label occurs
more than once (a landmark recorded on two segments), the occurrence that moves least relative
to this cluster is used, and a landmark that moves more than ``MAX_LANDMARK_SPREAD_M`` is left
out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.protocol import Protocol
from motionlab.session import FORMAT_NAME, MarkerSet, load_session
from motionlab.validation.anatomy import anatomical_frame, recipe_for
from motionlab.validation.markermap import MarkerMap, SegmentMap
from motionlab.validation.optical import local_coordinates, track_cluster

MAX_LANDMARK_SPREAD_M = 0.01


@dataclass
class OpticalSegment:
    """One segment seen by the optical system (see the module docstring).

    ``quat`` (N, 4) maps the cluster (or rigid body) frame into the lab frame at ``time``
    (reference clock); ``anatomical`` (4,) maps the anatomical segment frame into the cluster
    frame, ``None`` when the landmarks do not define it.
    """

    name: str
    time: np.ndarray
    quat: np.ndarray
    source: str
    anatomical: np.ndarray | None = None
    landmarks: list[str] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)

    def segment_quat(self) -> np.ndarray | None:
        """Anatomical segment → lab orientation (N, 4), or ``None`` without landmarks."""
        if self.anatomical is None:
            return None
        return rot.mul(self.quat, self.anatomical)


def read_reference(path: str | Path) -> list[MarkerSet]:
    """Marker sets of a reference file: a motionlab session, or any file the readers know."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such reference file", path, remedy="check the path")
    try:
        with h5py.File(path, "r") as f:
            is_session = f.attrs.get("format") == FORMAT_NAME
    except OSError:
        is_session = False
    if is_session:
        sets = list(load_session(path).markers.values())
    else:
        from motionlab.io import read_any

        sets = read_any(path).markers
    if not sets:
        raise InputError(
            "holds no optical data", path, remedy="give a C3D/TRC file or a session with markers"
        )
    return sets


def choose_marker_set(sets: list[MarkerSet], name: str | None, path: str | Path | None = None):
    """The marker set called ``name``, or the only one."""
    if not sets:
        raise InputError("holds no optical data", path, remedy="give --reference FILE.c3d")
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


def _landmark_positions(
    markers: MarkerSet, names: list[str], quat: np.ndarray, origin: np.ndarray, use: np.ndarray
) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """Median local position of each landmark and its spread (m) in the cluster frame."""
    positions, spread = {}, {}
    for name in names:
        best = None
        for j in (i for i, lab in enumerate(markers.labels) if lab == name):
            local = local_coordinates(quat[use], origin[use], markers.positions[use, j][:, None])
            local = local[:, 0]
            local = local[np.isfinite(local).all(axis=1)]
            if len(local) < 3:
                continue
            med = np.median(local, axis=0)
            s = float(np.median(np.linalg.norm(local - med, axis=1)))
            if best is None or s < best[1]:
                best = (med, s)
        if best is not None:
            spread[name] = best[1]
            if best[1] <= MAX_LANDMARK_SPREAD_M:
                positions[name] = best[0]
    return positions, spread


def optical_segment(
    markers: MarkerSet, seg: SegmentMap, mmap: MarkerMap, protocol: Protocol | None
) -> OpticalSegment:
    """The :class:`OpticalSegment` of one marker-map entry."""
    if seg.rigid_body:
        q = np.asarray(markers.rigid_bodies[seg.rigid_body], dtype=float)
        ok = np.isfinite(q).all(axis=1)
        info = {"fitted_fraction": float(ok.mean()), "rigid_body": seg.rigid_body}
        return OpticalSegment(seg.name, markers.time, q, "rigid_body", info=info)
    idx = [markers.labels.index(m) for m in seg.cluster]
    track = track_cluster(
        markers.time, markers.positions[:, idx], seg.cluster, mmap.max_gap_s, mmap.lowpass_hz
    )
    info: dict[str, Any] = track.summary() | {"shape_m": track.shape}
    names = seg.landmarks
    if names is None:
        names = (
            protocol.segments[seg.name].landmarks
            if protocol and seg.name in protocol.segments
            else []
        )
    use = np.isfinite(track.residual)
    if mmap.static_time_s is not None:
        use &= (markers.time >= mmap.static_time_s[0]) & (markers.time <= mmap.static_time_s[1])
    positions, spread = _landmark_positions(markers, names, track.quat, track.origin, use)
    info["landmark_spread_mm"] = {k: v * 1e3 for k, v in spread.items()}
    out = OpticalSegment(seg.name, markers.time, track.quat, "cluster", info=info)
    recipe = seg.frame or recipe_for(seg.name)
    if recipe is not None and positions:
        found = anatomical_frame(recipe, positions, _side(seg.name, protocol), seg.frame is None)
        if found is not None:
            out.anatomical = rot.from_matrix(found[0])
            out.landmarks = found[1]
    return out


def optical_segments(
    markers: MarkerSet, mmap: MarkerMap, protocol: Protocol | None = None
) -> dict[str, OpticalSegment]:
    """One :class:`OpticalSegment` per marker-map segment."""
    return {
        name: optical_segment(markers, seg, mmap, protocol) for name, seg in mmap.segments.items()
    }
