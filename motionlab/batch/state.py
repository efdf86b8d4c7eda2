"""What a study folder remembers between runs: which sessions are finished, which are running.

Layout of a study output folder::

    OUTDIR/.motionlab-batch           marks the folder as written by motionlab batch, for which
                                      manifest (another manifest's study needs force)
    OUTDIR/<subject>/<visit>/         the session's outputs (as motionlab run writes them)
        batch_metrics.csv             the session's metric table (one row per joint metric)
        batch_gait.csv                a walk's gait summary (spatiotemporal_summary.csv's rows)
        batch_stamp.json              written last, atomically: the session finished
        .batch_running                exists while a worker processes the session (its pid)

A session is *current* when its stamp holds the key of its present inputs — the SHA-256 of every
input file (with its name), of the protocol, map and reference files, and the motionlab version —
and its metric table (and gait table, or its absence) still has the hash the stamp recorded.
Current sessions are skipped; so is no session whose stamp is of older tables (:data:`TABLES`).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any

from motionlab import __version__
from motionlab.atomic import atomic_path
from motionlab.errors import InputError
from motionlab.session import sha256_file

MARKER = ".motionlab-batch"
STAMP = "batch_stamp.json"
METRICS = "batch_metrics.csv"
GAIT = "batch_gait.csv"
CLAIM = ".batch_running"
#: the layout of the session tables a stamp vouches for, raised when their columns or their
#: meaning change: a study resumed by a newer motionlab (whose version may be the same) re-runs
#: its sessions rather than gathering old tables with new ones. 2: the metric rows' normal
#: range, comparison and note, the rows of joints not measured, the gait counts of strides
#: with a value
TABLES = 2


class FileHashes:
    """SHA-256 of files, each read once per run (the protocol and map are shared by sessions)."""

    def __init__(self) -> None:
        self._cache: dict[Path, str] = {}

    def __call__(self, path: Path | None) -> str | None:
        if path is None:
            return None
        path = Path(path).resolve()
        if path not in self._cache:
            self._cache[path] = sha256_file(path)
        return self._cache[path]


def _file_entries(path: Path, hashes: FileHashes) -> list[list[str | None]]:
    """``[[name, sha256]]`` of an input: the file itself, or for an x-IMU3 export folder each
    file the reader reads in it (named relative to the folder's parent)."""
    if not path.is_dir():
        return [[path.name, hashes(path)]]
    from motionlab.io.ximu3 import input_files

    return [[str(p.relative_to(path.parent)), hashes(p)] for p in input_files(path)]


def session_key(
    files: list[Path],
    protocol: Path,
    map_path: Path | None,
    reference: Path | None,
    hashes: FileHashes,
    version: str = __version__,
    options: dict[str, Any] | None = None,
    markers: Path | None = None,
) -> str:
    """SHA-256 over the inputs' names and contents, the protocol, map, reference and version,
    and the run ``options`` that differ from the defaults
    (:meth:`~motionlab.pipeline.PipelineOptions.analysis`; a calibration folder by the names and
    contents of its files), and the reference's marker map. Without such options or a marker
    map the key is the one of earlier versions."""
    doc: dict[str, Any] = {
        "motionlab": version,
        "files": [entry for f in files for entry in _file_entries(Path(f), hashes)],
        "protocol": hashes(protocol),
        "map": hashes(map_path),
        "reference": hashes(reference),
    }
    if markers is not None:
        doc["markers"] = hashes(markers)
    if options:
        doc["options"] = dict(options)
        if "calibration_dir" in options:
            folder = Path(options["calibration_dir"])
            files_in = sorted(p for p in folder.rglob("*") if p.is_file())
            doc["options"]["calibration_dir"] = [
                [str(p.relative_to(folder)), hashes(p)] for p in files_in
            ]
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def _marked_manifest(outdir: Path) -> str | None:
    """The manifest the study folder's marker names, or None (no marker, or none readable)."""
    try:
        doc = json.loads((outdir / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    name = doc.get("manifest") if isinstance(doc, dict) else None
    return name if isinstance(name, str) else None


def prepare_outdir(outdir: Path, manifest: Path, force: bool) -> None:
    """Create the study folder, or accept one that motionlab batch wrote for this manifest (any
    folder with force: the marker then names this manifest)."""
    if outdir.exists() and not outdir.is_dir():
        raise InputError(
            "is not a folder",
            outdir,
            "argument outdir",
            "give a folder for the study outputs",
            argument="outdir",
        )
    if outdir.is_dir() and any(outdir.iterdir()) and not (outdir / MARKER).is_file() and not force:
        raise InputError(
            "folder holds files not written by motionlab batch",
            outdir,
            "argument outdir",
            "choose another folder, or add force=True to write into it",
            argument=("outdir", "force"),
        )
    other = _marked_manifest(outdir) if outdir.is_dir() else None
    if other is not None and other != str(manifest.resolve()) and not force:
        raise InputError(
            f"holds the study of another manifest ({other}), whose study tables this one would "
            "replace",
            outdir,
            "argument outdir",
            "choose another folder, or add force=True to write this study into it",
            argument=("outdir", "force"),
        )
    if not outdir.parent.is_dir():
        raise InputError("parent folder does not exist", outdir, "-o", f"create {outdir.parent}")
    try:
        outdir.mkdir(exist_ok=True)
    except OSError as exc:  # a read-only file system, no permission
        raise InputError(
            f"cannot create the folder ({exc.strerror or exc})", outdir, "-o",
            "choose a folder you can write to",
        ) from None  # fmt: skip
    if not os.access(outdir, os.W_OK):
        raise InputError("folder is not writable", outdir, "-o", "choose another folder")
    if _marked_manifest(outdir) != str(manifest.resolve()):
        write_json(outdir / MARKER, {"manifest": str(manifest.resolve()), "motionlab": __version__})


def write_json(path: Path, doc: dict[str, Any]) -> None:
    """Write a small JSON file atomically (temporary file, then rename)."""
    with atomic_path(path, force=True) as tmp:
        tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n", encoding="utf-8")


def read_stamp(folder: Path) -> dict[str, Any] | None:
    """The session's stamp, or None when there is none (or it is unreadable)."""
    try:
        doc = json.loads((folder / STAMP).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def is_current(folder: Path, key: str) -> bool:
    """True if the session in ``folder`` finished with inputs of this key, outputs intact."""
    stamp = read_stamp(folder)
    metrics = folder / METRICS
    return (
        stamp is not None
        and stamp.get("key") == key
        and metrics.is_file()
        and stamp.get("metrics_sha256") == sha256_file(metrics)
        and stamp.get("tables") == TABLES  # a stamp of older tables: run it again
        and stamp.get("gait_sha256") == _sha256_or_none(folder / GAIT)
    )


def _sha256_or_none(path: Path) -> str | None:
    return sha256_file(path) if path.is_file() else None


def write_stamp(folder: Path, key: str, seconds: float) -> None:
    """Record that the session in ``folder`` finished: written last, atomically."""
    write_json(
        folder / STAMP,
        {
            "key": key,
            "metrics_sha256": sha256_file(folder / METRICS),
            "gait_sha256": _sha256_or_none(folder / GAIT),
            "tables": TABLES,
            "motionlab": __version__,
            "seconds": round(seconds, 3),
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        },
    )


def claim(folder: Path) -> None:
    """Mark the session as being processed by this process."""
    (folder / CLAIM).write_text(f"{os.getpid()}\n", encoding="utf-8")


def release(folder: Path) -> None:
    """Remove the mark of :func:`claim` (no error if it is gone)."""
    (folder / CLAIM).unlink(missing_ok=True)


def claimed(folder: Path) -> bool:
    return (folder / CLAIM).is_file()


def sweep_temp(folder: Path) -> list[Path]:
    """Delete temporary files a killed writer left in ``folder`` (``.<name>.<random>.tmp``)."""
    if not folder.is_dir():
        return []
    stale = [p for p in folder.rglob(".*.tmp") if p.is_file()]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale
