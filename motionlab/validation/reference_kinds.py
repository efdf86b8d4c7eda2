"""What a validation reference file holds, and reading it as that kind.

Kinds (``--reference-kind``; ``auto`` picks the first that fits):

- ``segments``: a CSV of segment quaternions (:mod:`.segment_csv`);
- ``markers``: marker trajectories or rigid bodies (C3D, TRC, BROAD, a session; the marker path
  of :func:`motionlab.validation.validate`);
- ``angles``: joint angles computed by another model, C3D ``POINT:ANGLES`` outputs
  (:mod:`.model_angles`); ``auto`` picks it for a file with angle outputs and no markers.
"""

from __future__ import annotations

from pathlib import Path

from motionlab.errors import InputError
from motionlab.session import MarkerSet, Session
from motionlab.validation.model_angles import has_model_angles
from motionlab.validation.reference import choose_marker_set, read_reference
from motionlab.validation.segment_csv import is_segment_csv, read_segment_csv

REFERENCE_KINDS = ("auto", "markers", "segments", "angles")


def load_reference(
    path: str | Path, kind: str = "auto", name: str | None = None
) -> tuple[MarkerSet, str]:
    """The reference of ``path`` and its kind (``markers``, ``segments`` or ``angles``);
    ``name`` chooses a marker set when the file holds several."""
    if kind not in REFERENCE_KINDS:
        raise InputError(
            f"unknown reference kind '{kind}'", path, remedy=f"use {', '.join(REFERENCE_KINDS)}"
        )
    if kind == "segments" or (kind == "auto" and is_segment_csv(path)):
        return read_segment_csv(path), "segments"
    ref = choose_marker_set(read_reference(path, model_outputs_ok=True), name, path)
    ref.attrs.setdefault("source_file", str(path))
    markers = bool(ref.n_markers or ref.rigid_bodies)
    kind = kind_of(ref) if kind == "auto" else kind
    if kind == "angles" and not has_model_angles(ref):
        raise InputError(
            "holds no joint angles (POINT:ANGLES)",
            path,
            remedy="give a C3D with model angles, or pass reference_kind=markers",
            argument="reference_kind",
        )
    if kind == "markers" and not markers:
        raise InputError(
            "holds no markers or rigid bodies",
            path,
            remedy="give the C3D with the marker trajectories",
        )
    return ref, kind


def session_reference(
    session: Session, kind: str = "auto", name: str | None = None, path: str | Path | None = None
) -> tuple[MarkerSet, str]:
    """The session's own reference (its marker set ``name``, or the only one) and its kind
    (``auto``: as for a file, :func:`load_reference`); ``path`` names the session in errors.
    ``motionlab validate`` without a reference file and ``motionlab run`` on inputs that hold
    markers both take it from here."""
    if not session.markers:
        raise InputError(
            "has no optical data",
            path,
            remedy="give reference=FILE.c3d or a session",
            argument="reference",
        )
    ref = choose_marker_set(list(session.markers.values()), name, path)
    return ref, kind_of(ref) if kind == "auto" else kind


def kind_of(ref: MarkerSet) -> str:
    """``angles`` for model joint angles without markers or rigid bodies, else ``markers``."""
    return (
        "angles" if has_model_angles(ref) and not (ref.n_markers or ref.rigid_bodies) else "markers"
    )
