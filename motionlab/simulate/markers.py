"""Optical markers: rigid clusters and anatomical landmarks, sampled by a camera system.

Each protocol segment carries a cluster of four non-collinear markers on a plate 2 cm off the
skin, plus the landmarks the protocol names (:meth:`Body.landmark`). The camera system has its
own clock (``offset + (1 + drift) t``, defaults 0.137 s and 100 ppm) and rate (default 120 Hz)
and reports positions in a lab frame: ``p_lab = R_labᵀ (p_ENU − origin)`` with ``R_lab`` (lab →
ENU) by default a rotation about the vertical. Noise is white (σ per coordinate) and markers
disappear (NaN) for exponentially distributed stretches. :func:`write_c3d` writes mm.

A landmark that two segments list (the femoral epicondyles ``RLE``, ``RME`` in the thigh's and
the shank's lists) is simulated once on each, a copy that rides on that segment, and both
copies carry its name in the marker set (the validation gives the i-th copy to the i-th segment
naming it). A C3D file names its points uniquely (:func:`c3d_labels`): the first copy keeps the
name, the others are named after their segment (``RLE_shank_r``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import ezc3d
import numpy as np

from motionlab import rotations as rot
from motionlab.atomic import atomic_path
from motionlab.protocol import Protocol
from motionlab.session import MarkerSet
from motionlab.simulate.body import Body
from motionlab.simulate.chain import segment_poses
from motionlab.simulate.timeline import Timeline


@dataclass
class MarkerLayout:
    """Marker labels, the segment each is fixed to, and its position there (m, segment frame)."""

    labels: list[str]
    segments: list[str]
    local: np.ndarray  # (M, 3)
    kinds: list[str]  # "cluster" or "landmark"
    known: list[bool]  # landmark found in the anatomical table (clusters: True)


def layout(body: Body, protocol: Protocol, rng: np.random.Generator) -> MarkerLayout:
    """Clusters on every protocol segment and the protocol's landmarks: per segment, in the
    protocol's order, its cluster markers ``<segment>_C1`` … ``_C4``, then its landmarks (the
    order :func:`marker_segments` reads)."""
    labels, segs, local, kinds, known = [], [], [], [], []
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.2, 0.8]]) * [0.04, 0.03]
    for name, seg in protocol.segments.items():
        centre, normal = body.cluster_site(name)
        u = np.cross(normal, [0.0, 1.0, 0.0])
        u = u if np.linalg.norm(u) > 0.5 else np.cross(normal, [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(normal, u)
        plate = square + rng.uniform(-0.008, 0.008, square.shape)
        for i, (a, b) in enumerate(plate):
            labels.append(f"{name}_C{i + 1}")
            segs.append(name)
            local.append(centre + 0.02 * normal + a * u + b * v)
            kinds.append("cluster")
            known.append(True)
        for lm in seg.landmarks:
            pos, found = body.landmark(name, lm)
            labels.append(lm)
            segs.append(name)
            local.append(pos)
            kinds.append("landmark")
            known.append(found)
    return MarkerLayout(labels, segs, np.array(local).reshape(-1, 3), kinds, known)


def positions(body: Body, timeline: Timeline, lay: MarkerLayout, t: np.ndarray) -> np.ndarray:
    """True marker positions (N, M, 3) in ENU (m) at true times ``t``."""
    poses = segment_poses(body, timeline.channels(t), sorted(set(lay.segments)))
    out = np.empty((len(t), len(lay.labels), 3))
    for j, seg in enumerate(lay.segments):
        q, p = poses[seg]
        out[:, j] = p + rot.rotate(q, lay.local[j])
    return out


@dataclass
class OpticalSystem:
    """Camera rate, clock, lab frame and measurement errors."""

    rate_hz: float = 120.0
    offset_s: float = 0.137
    drift: float = 100e-6
    lab_rotation: np.ndarray = None  # (4,) lab → ENU; default 35° about the vertical
    lab_origin: np.ndarray = None  # (3,) m, ENU
    noise_m: float = 0.001
    occlusions_per_min: float = 2.0
    occlusion_mean_s: float = 0.2

    def __post_init__(self) -> None:
        if self.lab_rotation is None:
            self.lab_rotation = rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(35.0))
        if self.lab_origin is None:
            self.lab_origin = np.array([1.5, -2.0, 0.0])


def record(
    body: Body,
    timeline: Timeline,
    lay: MarkerLayout,
    system: OpticalSystem,
    duration: float,
    rng: np.random.Generator,
) -> tuple[MarkerSet, np.ndarray]:
    """The optical recording (lab frame, camera clock) and the true time of each frame."""
    n = int(np.floor((system.offset_s + (1 + system.drift) * duration) * system.rate_hz)) + 1
    stamps = np.arange(n) / system.rate_hz
    t_true = (stamps - system.offset_s) / (1 + system.drift)
    p = positions(body, timeline, lay, t_true)
    lab = rot.rotate(rot.conj(system.lab_rotation), p - system.lab_origin)
    lab = lab + rng.normal(0.0, 1.0, lab.shape) * system.noise_m
    for j in range(len(lay.labels)):  # a loop over markers and gaps, not samples
        n_gaps = rng.poisson(system.occlusions_per_min * duration / 60.0)
        starts = rng.uniform(0, stamps[-1], n_gaps)
        lengths = rng.exponential(system.occlusion_mean_s, n_gaps)
        for s, d in zip(starts, lengths, strict=True):
            lab[(stamps >= s) & (stamps <= s + d), j] = np.nan
    residuals = np.where(np.isnan(lab[..., 0]), np.nan, system.noise_m)
    markers = MarkerSet(
        name="optical",
        time=stamps,
        labels=list(lay.labels),
        positions=lab,
        residuals=residuals,
        source_units={"positions": "m"},
        attrs={"simulated": True, "frame": "lab"},
    )
    return markers, t_true


def marker_segments(labels: list[str]) -> list[str]:
    """The segment each marker of a simulated marker set rides on, from :func:`layout`'s order:
    a cluster marker ``<segment>_C<k>`` names it, the landmarks after it are on the same
    segment ("" before any cluster)."""
    out, segment = [], ""
    for label in labels:
        cluster = re.fullmatch(r"(.+)_C\d+", label)
        segment = cluster.group(1) if cluster else segment
        out.append(segment)
    return out


def c3d_labels(labels: list[str], segments: list[str]) -> list[str]:
    """Unique point labels for a C3D file, which tools look points up by. The first copy of a
    landmark (the first segment naming it in the protocol: the thigh for the femoral
    epicondyles, the upper arm for the humeral ones) keeps its name, which the protocol's
    landmark lists and the validation read; a copy on a later segment is named after that
    segment, ``RLE`` on ``shank_r`` → ``RLE_shank_r`` (``_`` added while a name is taken)."""
    taken, seen, out = set(labels), set(), []
    for label, segment in zip(labels, segments, strict=True):
        name = label
        if label in seen:
            name = f"{label}_{segment}" if segment else f"{label}_2"
            while name in taken:
                name += "_"
        seen.add(label)
        taken.add(name)
        out.append(name)
    return out


def write_c3d(markers: MarkerSet, path: str | Path, force: bool = False) -> None:
    """Write marker positions as a C3D file (mm; NaN = not seen; residual −1 when missing), its
    point labels unique (:func:`c3d_labels`: a landmark's copy on a later segment named after
    it, ``RLE_shank_r``)."""
    c3d = ezc3d.c3d()
    rate = float(np.round(markers.rate_hz, 6))
    labels = c3d_labels(list(markers.labels), marker_segments(list(markers.labels)))
    c3d["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = labels
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, len(markers.labels), len(markers.time)))
    pts[:3] = np.transpose(markers.positions, (2, 1, 0)) * 1000.0
    c3d["data"]["points"] = pts
    with atomic_path(path, force=force) as tmp:
        c3d.write(str(tmp.with_suffix(".c3d")))
        tmp.with_suffix(".c3d").replace(tmp)
