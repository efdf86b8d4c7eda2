"""Anatomical landmarks fixed in the marker-cluster frames (CAST).

The calibrated anatomical systems technique (Cappozzo, Catani, Della Croce & Leardini 1995,
Clin Biomech 10:171) records the anatomical landmarks in a static pose only, often in a separate
static trial, and fixes each one in the frame of its segment's marker cluster: with the cluster
pose ``(R_k, o_k)`` (cluster → lab) of the static frames ``k``, the landmark's local position is
the median of ``l_k = R_kᵀ (p_k − o_k)``. In every other frame it is reconstructed through the
cluster pose, ``p(t) = R(t) l + o(t)``, so the anatomical frame built from the landmarks is a
constant rotation of the cluster frame.

Which marker column is a segment's landmark comes from the landmark lists (the protocol's, or
the marker map's), in the protocol's segment order (:func:`assign_landmarks`); never from how
little the marker moves, which cannot tell two copies of a label apart in a still window.

The static window, unless a static trial or ``static_time_s`` gives it, is the longest run of
frames in which every cluster is still and landmarks are seen (:func:`static_window`).
"""

from __future__ import annotations

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.timebase import runs
from motionlab.validation.optical import local_coordinates

MAX_LANDMARK_SPREAD_M = 0.01  # a landmark moving more than this in the cluster frame is left out
STILL_HALF_WINDOW_S = 0.5  # a cluster is still when its mean orientations over this time
STILL_DEG = 3.0  # before and after a frame differ by less than this (about 6°/s)
MIN_STATIC_S = 1.0  # shortest automatic static window


def assign_landmarks(
    labels: list[str], wanted: dict[str, list[str]], where: str = "marker set"
) -> dict[str, dict[str, int]]:
    """Marker column of each segment's landmarks: ``{segment: {label: column of labels}}``.

    ``wanted`` lists each segment's landmark labels, segments in the protocol's order. A label
    that occurs once in ``labels`` serves every segment naming it (one physical point: the
    humeral epicondyles define the upper arm's and the forearm's frames); a label that occurs
    once per segment naming it (a copy recorded on each segment) gives its i-th occurrence to
    the i-th of those segments. Labels not in ``labels`` are left out. Raises
    :class:`InputError` for any other number of occurrences.
    """
    columns: dict[str, list[int]] = {}
    for j, label in enumerate(labels):
        columns.setdefault(label, []).append(j)
    owners: dict[str, list[str]] = {}
    for seg, names in wanted.items():
        for name in dict.fromkeys(names):
            owners.setdefault(name, []).append(seg)
    out: dict[str, dict[str, int]] = {seg: {} for seg in wanted}
    for name, segs in owners.items():
        cols = columns.get(name, [])
        if len(cols) == 1:
            cols = cols * len(segs)
        elif cols and len(cols) != len(segs):
            raise InputError(
                f"landmark {name} occurs {len(cols)} times but {len(segs)} segment(s) name it "
                f"({', '.join(segs)})",
                where=where,
                remedy="label each copy differently and list it under its segment's landmarks "
                "in the marker map",
            )
        for seg, col in zip(segs, cols, strict=False):
            out[seg][name] = col
    return out


def _window_turn(q: np.ndarray, h: int) -> np.ndarray:
    """Angle (rad, (N,)) between the mean orientations of the ``h`` frames before and the ``h``
    frames from each frame on; NaN where either window has an unknown frame."""
    q = rot.make_continuous(np.asarray(q, dtype=float))
    finite = np.isfinite(q).all(axis=1)
    total = np.vstack([np.zeros((1, 4)), np.cumsum(np.where(finite[:, None], q, 0.0), axis=0)])
    count = np.r_[0, np.cumsum(finite)]
    n = len(q)
    turn = np.full(n, np.nan)
    k = np.arange(h, n - h + 1)
    k = k[(count[k] - count[k - h] == h) & (count[k + h] - count[k] == h)]
    before = rot.normalize(total[k] - total[k - h])
    after = rot.normalize(total[k + h] - total[k])
    turn[k] = rot.angle_between(before, after)
    return turn


def still_frames(
    time: np.ndarray,
    quats: list[np.ndarray],
    half_window_s: float = STILL_HALF_WINDOW_S,
    max_deg: float = STILL_DEG,
) -> np.ndarray:
    """Frames (N,) in which no cluster (quaternions (N, 4), NaN when unknown) turns more than
    ``max_deg`` between its mean orientations over ``half_window_s`` before and after (window
    means, so that marker noise averages out); clusters unknown there are ignored, frames where
    none is known are not still."""
    time = np.asarray(time, dtype=float)
    rate = 1.0 / np.median(np.diff(time)) if len(time) > 1 else 1.0
    h = max(2, int(round(half_window_s * rate)))
    worst = np.full(len(time), np.nan)
    for q in quats:  # a loop over clusters, vectorised over frames
        worst = np.fmax(worst, _window_turn(q, h))
    return np.nan_to_num(worst, nan=np.inf) < np.radians(max_deg)


def longest_run(time: np.ndarray, mask: np.ndarray, min_s: float = MIN_STATIC_S) -> tuple | None:
    """``(start_s, end_s)`` of the longest run of ``mask`` lasting at least ``min_s``, or None."""
    found = runs(mask)
    if len(found) == 0:
        return None
    starts, ends = found[:, 0], found[:, 1] - 1
    span = time[ends] - time[starts]
    best = int(np.argmax(span))
    if span[best] < min_s:
        return None
    return float(time[starts[best]]), float(time[ends[best]])


def static_window(
    time: np.ndarray, quats: list[np.ndarray], seen: np.ndarray
) -> tuple[float, float] | None:
    """The automatic static window ``(start_s, end_s)``: the longest run (≥ ``MIN_STATIC_S``) of
    frames where every cluster is still (:func:`still_frames`) and a landmark is ``seen`` (N,)."""
    return longest_run(time, still_frames(time, quats) & seen)


def calibrate_landmarks(
    points: np.ndarray, quat: np.ndarray, origin: np.ndarray, use: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Local positions (L, 3) in the cluster frame of landmark ``points`` (N, L, 3) over the frames
    ``use`` (N,), and their spread (L,): the median distance (m) from that position. NaN for a
    landmark seen in fewer than three of those frames."""
    local = local_coordinates(quat[use], origin[use], points[use])
    n_seen = np.isfinite(local).all(axis=-1).sum(axis=0)
    out = np.full((points.shape[1], 3), np.nan)
    spread = np.full(points.shape[1], np.nan)
    ok = n_seen >= 3
    if ok.any():
        out[ok] = np.nanmedian(local[:, ok], axis=0)
        spread[ok] = np.nanmedian(np.linalg.norm(local[:, ok] - out[ok], axis=-1), axis=0)
    return out, spread


def reconstruct(quat: np.ndarray, origin: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Landmark positions (N, L, 3) in the lab frame, ``R(t) l + o(t)``, from local positions
    (L, 3) and the cluster pose (``quat`` (N, 4), ``origin`` (N, 3)); NaN where the pose is."""
    q = np.asarray(quat, dtype=float)[:, None, :]
    return rot.rotate(q, np.asarray(local, float)[None]) + np.asarray(origin, float)[:, None]
