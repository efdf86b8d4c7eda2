"""C3D marker files (Vicon, OptiTrack, Qualisys, …) read with ezc3d.

Returned: one :class:`~motionlab.session.MarkerSet` named after the file, with

- ``labels`` from ``POINT:LABELS`` (continued in ``LABELS2``, ``LABELS3``… past 255 markers),
- ``positions`` (N, M, 3) in m (``POINT:UNITS`` ``mm``, ``cm`` or ``m``; ``mm`` assumed, with a
  warning, when the parameter is absent),
- ``residuals`` (N, M) in m,
- ``time`` = frame index / ``POINT:RATE`` in s (the first frame number in ``attrs``),
- ``model_outputs``: the POINT entries the file's own parameters type as model outputs —
  ``POINT:ANGLES``, ``FORCES``, ``MOMENTS``, ``POWERS``, ``SCALARS``, ``REACTIONS`` list their
  labels, ``POINT:ANGLE_UNITS``, ``FORCE_UNITS``… their units (Plug-in Gait: deg, N, Nmm, W).
  They keep their unit (``LKneeAngles`` stays 57.86 deg; scaling it as a marker by 1/1000 made
  it 0.0579 "m") and are not markers. A missing unit parameter is assumed (deg, N, Nmm, W) and
  said in ``attrs["warnings"]``.

Labels: subject prefixes (``A22:RKNE``, Vicon's ``SUBJECTS:LABEL_PREFIXES``, or any text up to
the first ``:``) are stripped, so that marker maps and protocols name markers as usual, unless
that would merge distinct labels (OptiTrack's ``WheelchairL:Marker1`` and ``ArmL:Marker1``):
then every label keeps its prefix. ``attrs["label_prefixes"]`` keeps each stripped prefix and
``attrs["subjects"]`` their names. Labels that repeat in the file (two points ``RKNE``) are not
silent: the repeats are renamed ``RKNE_2``… and listed in ``attrs["duplicate_labels"]``,
``attrs["flags"]["duplicate_labels"]`` and ``attrs["warnings"]``.

Before ezc3d reads anything, the frames and points announced by the parameter section
(``POINT:FRAMES``, ``POINT:USED``; the header block where absent) are checked against the file's
size, so that a damaged parameter section cannot make ezc3d allocate far more than the file
holds; a truncated file is refused, a complete file with a stale header block is read. The
parameter section is then walked record by record as ezc3d reads it (:func:`_check_records`:
group ids, data types, dimensions, description lengths, each record ending where the next one
starts, the parameters ezc3d indexes while reading the frames), so that a damaged record is
refused with its byte offset instead of crashing ezc3d. ezc3d itself runs in a forked child
(:func:`motionlab.isolated.call_isolated`) as a safety net: a crash there is refused too.
A point is invalid — NaN in ``positions`` and ``residuals`` — when its residual is negative
(the C3D "not seen" flag) or all three coordinates are exactly zero (how some exporters write
a gap). Analog channels are not read; their count is kept in ``attrs["n_analog_channels"]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError, shorten
from motionlab.io import Recording
from motionlab.isolated import call_isolated
from motionlab.session import MarkerSet, ModelOutput
from motionlab.units import factor

FORMAT = "c3d"

#: model output kind → (POINT parameter listing its labels, unit parameter, unit assumed)
MODEL_KINDS = {
    "angles": ("ANGLES", "ANGLE_UNITS", "deg"),
    "forces": ("FORCES", "FORCE_UNITS", "N"),
    "moments": ("MOMENTS", "MOMENT_UNITS", "Nmm"),
    "powers": ("POWERS", "POWER_UNITS", "W"),
    "scalars": ("SCALARS", "SCALAR_UNITS", ""),
    "reactions": ("REACTIONS", "REACTION_UNITS", ""),
}


def sniff(path: Path, head: bytes) -> bool:
    """C3D: the second byte of the header block is the key 0x50, and the parameter section
    (block ``head[0]``) names a processor type 84–86 (Intel, DEC, MIPS) in its fourth byte.

    A file that ends before that byte but starts as C3D files do (parameter section in block
    2: ``02 50``) is taken as a C3D file cut short, so that reading it says so.
    """
    if len(head) < 2 or head[1] != 0x50:
        return False
    processor = (max(head[0], 1) - 1) * 512 + 3
    if processor < len(head):
        return len(head) >= 512 and head[processor] in (84, 85, 86)
    return head[0] == 2


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read the marker trajectories of a C3D file (m, NaN where not seen)."""
    path = Path(path)
    layout = _layout(path)
    expected = layout.frames
    _check_size(path, layout)
    _check_records(path, layout)
    try:
        c3d = call_isolated(_ezc3d_read, path, path=path, what="ezc3d")
    except (RuntimeError, OSError, ValueError) as exc:
        if expected > 0 and layout.size < layout.data_start + layout.frame_bytes:
            raise _truncated(path, "the file ends inside its first frame", "frame 1") from None
        raise InputError(
            f"ezc3d cannot open it ({str(exc).splitlines()[0] if str(exc) else 'damaged'})",
            path,
            remedy="export the C3D again from the capture software",
        ) from None
    point = c3d["parameters"].get("POINT", {})
    header = c3d["header"]["points"]
    points = c3d["data"]["points"]  # (4, M, N)
    n_markers, n_frames = points.shape[1], points.shape[2]
    if n_markers and n_frames < expected:
        raise InputError(
            f"truncated: the header announces {expected} frames, the file holds {n_frames}",
            path,
            f"frame {n_frames + 1}",
            "copy or export the file again",
        )
    rate = _value(point, "RATE", float(header["frame_rate"]))
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"point rate {rate} Hz", path, "parameter POINT:RATE", "fix the rate")
    warnings: list[str] = []
    unit = _value(point, "UNITS", "").strip()
    if not unit:
        unit = "mm"
        warnings.append("POINT:UNITS absent; mm assumed")
    try:
        scale = factor(unit, "length")
    except InputError as exc:
        raise InputError(exc.message, path, "parameter POINT:UNITS", exc.remedy) from None

    raw = _labels(point, n_markers)
    kinds, units = _kinds(point, raw, warnings)
    labels, prefixes = _strip_prefixes(raw, _known_prefixes(c3d["parameters"]))
    labels, duplicates = _unique(labels)
    for name, count in duplicates.items():
        warnings.append(
            f"label {name} appears {count} times; the repeats are renamed "
            + ", ".join(f"{name}_{k}" for k in range(2, count + 1))
        )
    xyz = np.transpose(points[:3], (2, 1, 0)).astype(float)  # (N, M, 3)
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"][0], dtype=float).T
    unseen = (residuals < 0) | np.isnan(xyz).any(axis=2)
    is_marker = np.array([k is None for k in kinds], dtype=bool)
    invalid = unseen | (np.all(xyz == 0.0, axis=2) & is_marker)  # zeros: a marker gap only
    xyz[invalid] = np.nan
    residuals[invalid] = np.nan
    outputs = {
        labels[j]: ModelOutput(labels[j], kinds[j], units[j], xyz[:, j].copy())
        for j in np.flatnonzero(~is_marker)
    }

    analogs = c3d["parameters"].get("ANALOG", {})
    attrs: dict[str, Any] = {
        "first_frame": int(header["first_frame"]),
        "nominal_rate_hz": rate,
        "n_analog_channels": int(c3d["header"]["analogs"]["size"]),
        "analog_rate_hz": _value(analogs, "RATE", 0.0),
    }
    if prefixes:
        attrs["label_prefixes"] = prefixes
        attrs["subjects"] = sorted({p.rstrip(":") for p in prefixes.values()})
    if duplicates:
        attrs["duplicate_labels"] = duplicates
    attrs["flags"] = {"duplicate_labels": bool(duplicates)}
    if warnings:
        attrs["warnings"] = warnings
    markers = MarkerSet(
        name=(options or {}).get("name") or path.stem,
        time=np.arange(n_frames) / rate,
        labels=[lab for lab, m in zip(labels, is_marker, strict=True) if m],
        positions=xyz[:, is_marker] * scale,
        residuals=residuals[:, is_marker] * scale,
        source_units={"positions": unit, "residuals": unit},
        attrs=attrs,
        model_outputs=outputs,
    )
    return Recording(markers=[markers], metadata={"c3d_unit": unit})


def _ezc3d_read(path: Path) -> dict[str, Any]:
    """What :func:`read` uses of ezc3d's reading, as plain picklable objects."""
    import ezc3d

    c3d = ezc3d.c3d(str(path))
    header = c3d["header"]
    return {
        "parameters": {g: dict(v) for g, v in c3d["parameters"].items()},
        "header": {"points": dict(header["points"]), "analogs": dict(header["analogs"])},
        "data": {
            "points": c3d["data"]["points"],
            "meta_points": {"residuals": c3d["data"]["meta_points"]["residuals"]},
        },
    }


@dataclass
class _Layout:
    """Where things are in a C3D file, from its header block (bytes)."""

    size: int
    start: int  # of the parameter section
    order: str  # byte order of its integers: "<" or ">"
    analogs: int  # analog samples per frame (header word 3)
    frames: int  # announced: POINT:FRAMES, else the header block
    data_start: int
    frame_bytes: int
    header_frames: int = 0
    points: int = 0  # per frame: POINT:USED, else the header block
    header_points: int = 0


def _layout(path: Path) -> _Layout:
    """The header block's frame count and data layout (ezc3d reports the frames it could
    read instead), after checking that the file reaches its first frame.

    Header words (16-bit, 1-based): 1 parameter block (low byte) and key 0x50, 2 points per
    frame, 3 analog samples per frame, 4–5 first and last frame, 7–8 the scale factor (float;
    negative: samples stored as float32, else int16), 9 the first block of the data. The
    parameter section's fourth byte is the processor type: 84 Intel, 85 DEC, 86 MIPS (the only
    big-endian one). Raises :class:`InputError` for a file cut before its first frame.
    """
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(512)
        start = (max(head[0], 1) - 1) * 512 if head else 0
        f.seek(start)
        params = f.read(4)
        f.seek(start)
        section = f.read(max(params[2], 1) * 512) if len(params) == 4 else b""
    if len(head) < 512:
        raise _truncated(path, f"the file ends inside its 512-byte header ({size} bytes)", None)
    if len(params) < 4:
        raise _truncated(path, "the file ends before its parameter section", None)
    order = ">" if params[3] == 86 else "<"
    words = np.frombuffer(head[:18], dtype=f"{order}u2").astype(int)
    frames = words[4] - words[3] + 1
    data_start = (words[8] - 1) * 512
    if size < min(start + params[2] * 512, data_start):  # some writers overstate params[2]
        raise _truncated(path, "the file ends inside its parameter section", None)
    if frames > 0 and size <= data_start:
        raise _truncated(
            path, f"the file ends before its first frame (the header announces {frames})",
            "frame 1",
        )  # fmt: skip
    sign = head[{84: 15, 85: 13, 86: 12}.get(params[3], 15)] & 0x80  # of the scale factor
    found = _parameters(section, order)
    points = int(found.get(("POINT", "USED"), [words[1]])[0])
    announced = int(found.get(("POINT", "FRAMES"), [frames])[0])
    if announced <= 0:  # some writers leave it 0 or store more than 32767 as negative
        announced = int(frames)
    frame_bytes = (4 * points + words[2]) * (4 if sign else 2)
    return _Layout(size, start, order, int(words[2]), announced, int(data_start),
                   int(frame_bytes), int(frames), points, int(words[1]))  # fmt: skip


def _check_size(path: Path, layout: _Layout) -> None:
    """Refuse, before ezc3d reads it, a file that cannot hold the frames its parameter
    section announces (truncated, or a damaged POINT:USED / POINT:FRAMES)."""
    if layout.frames <= 0 or layout.frame_bytes <= 0:
        return
    held = max(layout.size - layout.data_start, 0) // layout.frame_bytes
    if held >= layout.frames:
        return
    if layout.points != layout.header_points and held < 1:
        raise InputError(
            f"the parameter section's POINT:USED ({layout.points}) disagrees with the header "
            f"block ({layout.header_points} points) and does not fit the file",
            path,
            "parameter POINT:USED",
            "export the C3D again from the capture software",
        )
    if held < 1:
        return  # the first frame is cut short: read() says so
    source = "header" if layout.frames == layout.header_frames else "parameter POINT:FRAMES"
    raise InputError(
        f"truncated: the {source} announces {layout.frames} frames, the file holds {held}",
        path,
        f"frame {held + 1}",
        "copy or export the file again",
    )


#: C3D parameter data types: byte length of one value (-1: characters)
_TYPES = (-1, 1, 2, 4)
#: the C3D standard allows up to 7 dimensions per parameter
_MAX_DIMS = 7
#: a parameter section spans at most 255 blocks (its block count is one byte)
_MAX_SECTION = 255 * 512


def _check_records(path: Path, layout: _Layout) -> None:
    """Walk the parameter section as ezc3d reads it and refuse, naming the byte, a record it
    would read out of bounds or misread (the damage that crashes it rather than raising).

    A record: name length (int8, 0 ends the section; negative: locked), group id (int8:
    negative for a group, the owning group's id for a parameter, never 0), the name, the byte
    count to the next record (uint16, from its own position; 0 for the last record). A group
    then has a description (length int8); a parameter a data type (-1 char, 1 byte, 2 int16,
    4 float), a dimension count (0–7) and the dimensions (uint8 each), the data (the product of
    the dimensions × the type's length) and a description. Each record must end where the next
    one starts (ezc3d's own rule). Then the parameters ezc3d indexes while it reads the frames
    must hold enough values: ``POINT:SCALE`` (points), ``ANALOG:SCALE``, ``ANALOG:OFFSET`` (one
    per channel) and ``ANALOG:GEN_SCALE``.
    """
    with open(path, "rb") as f:
        f.seek(layout.start)
        buf = f.read(_MAX_SECTION)
    if len(buf) < 4:
        return  # _layout refused it already
    i16 = np.dtype(f"{layout.order}u2")

    def refuse(at: int, what: str) -> InputError:
        return InputError(
            f"damaged parameter section: {what}",
            path,
            f"byte {layout.start + at}",
            "export the C3D again from the capture software",
        )

    groups: dict[int, str] = {}
    counts: dict[tuple[int, str], int] = {}
    pos = expected = 4  # the first byte ("first parameter block") is ignored, as ezc3d does
    while True:
        if pos != expected:
            raise refuse(pos, f"a record ends at byte {layout.start + pos}, the chain says "
                         f"{layout.start + expected}")  # fmt: skip
        if pos + 2 > len(buf):
            raise refuse(pos, "the records run past the end of the section")
        nlen, gid = np.frombuffer(buf, np.int8, 2, pos).tolist()
        if nlen == 0:
            break
        if gid == 0:
            raise refuse(pos + 1, "a record with group id 0")
        end = pos + 2 + abs(nlen)
        if end + 2 > len(buf):
            raise refuse(pos, "a record runs past the end of the section")
        name = shorten(buf[pos + 2 : end].decode("latin-1").upper(), 40)
        offset = int(np.frombuffer(buf, i16, 1, end)[0])
        at = end + 2
        if gid < 0:
            groups[-gid] = name
        else:
            kind, ndims = (
                np.frombuffer(buf, np.int8, 2, at).tolist() if at + 2 <= len(buf) else (0, 0)
            )
            if kind not in _TYPES:
                raise refuse(at, f"parameter {name} has data type {kind} (expected -1, 1, 2 or 4)")
            if not 0 <= ndims <= _MAX_DIMS:
                raise refuse(at + 1, f"parameter {name} has {ndims} dimensions (at most 7)")
            dims = list(buf[at + 2 : at + 2 + ndims])
            count = int(np.prod(dims)) if ndims else (0 if kind == -1 else 1)
            at += 2 + ndims + count * abs(kind)
            counts[(gid, name)] = count // (max(dims[0], 1) if kind == -1 and ndims else 1)
        if at >= len(buf):
            raise refuse(pos, f"record {name} runs past the end of the section")
        if buf[at] > 127:  # a negative int8
            raise refuse(at, f"record {name} has a description of negative length")
        at += 1 + buf[at]
        if at > len(buf):
            raise refuse(pos, f"record {name} runs past the end of the section")
        if offset == 0:
            break
        expected = end + offset
        pos = at
    ids = {v: k for k, v in groups.items()}

    def n(group: str, name: str) -> int:
        return counts.get((ids.get(group, 0), name), -1)

    need = []
    if layout.header_points > 0:
        need.append(("POINT", "SCALE", 1))
    if layout.analogs > 0:
        need.append(("ANALOG", "GEN_SCALE", 1))
    if layout.analogs > 0:  # one scale and offset per channel (ANALOG:USED), at least one
        used = _parameters(buf, layout.order).get(("ANALOG", "USED"), [1])
        channels = int(min(max(used[0], 1), layout.analogs))
        need += [("ANALOG", "SCALE", channels), ("ANALOG", "OFFSET", channels)]
    for group, name, least in need:
        have = n(group, name)
        if have < least:
            what = "absent" if have < 0 else f"{have} value(s), expected {least}"
            raise InputError(
                f"damaged parameter section: {group}:{name} {what}",
                path,
                f"parameter {group}:{name}",
                "export the C3D again from the capture software",
            )


def _parameters(section: bytes, order: str) -> dict[tuple[str, str], list[float]]:
    """The short numeric parameters of a C3D parameter section, ``{(GROUP, NAME): values}``
    (a damaged section gives what could be read before the damage)."""
    groups: dict[int, str] = {}
    found: list[tuple[int, str, int]] = []
    i16 = np.dtype(f"{order}i2")
    pos = 4
    while pos + 4 <= len(section):
        nlen, gid = np.frombuffer(section, np.int8, 2, pos).tolist()
        end = pos + 2 + abs(nlen)
        if nlen == 0 or end + 2 > len(section):
            break
        name = section[pos + 2 : end].decode("latin-1").upper()
        offset = int(np.frombuffer(section, i16, 1, end)[0])
        if gid < 0:
            groups[-gid] = name
        else:
            found.append((gid, name, end + 2))
        if offset <= 0:
            break
        pos = end + offset
    out: dict[tuple[str, str], list[float]] = {}
    types = {1: np.dtype("u1"), 2: i16, 4: np.dtype(f"{order}f4")}
    for gid, name, p in found:
        if p + 2 > len(section):
            continue
        kind, ndims = int(np.frombuffer(section, np.int8, 1, p)[0]), section[p + 1]
        count = int(np.prod(list(section[p + 2 : p + 2 + ndims]))) if ndims else 1
        dtype, body = types.get(kind), p + 2 + ndims
        if dtype is None or not 0 < count <= 16 or body + count * dtype.itemsize > len(section):
            continue
        values = np.frombuffer(section, dtype, count, body).astype(float)
        out[(groups.get(gid, ""), name)] = values.tolist()
    return out


def _truncated(path: Path, message: str, where: str | None) -> InputError:
    return InputError(f"truncated: {message}", path, where, "copy or export the file again")


def _value(group: dict, name: str, default: Any) -> Any:
    """First value of a C3D parameter, or ``default`` when absent or empty."""
    values = group.get(name, {}).get("value", [])
    if len(values) == 0:
        return default
    value = values[0]
    return value if isinstance(value, str) else float(value)


def _labels(point: dict, n_markers: int) -> list[str]:
    """``LABELS`` then ``LABELS2``, ``LABELS3``… stripped; missing names become ``M001``…"""
    labels: list[str] = []
    for key in ["LABELS"] + [f"LABELS{k}" for k in range(2, 100)]:
        if key not in point or len(labels) >= n_markers:
            break
        labels += [str(s).strip() for s in point[key]["value"]]
    labels += [""] * (n_markers - len(labels))
    return [name or f"M{k + 1:03d}" for k, name in enumerate(labels[:n_markers])]


def _names(point: dict, key: str) -> list[str]:
    """The labels a POINT parameter lists (``ANGLES``, continued in ``ANGLES2``…), stripped."""
    names: list[str] = []
    for k in [key] + [f"{key}{n}" for n in range(2, 100)]:
        if k not in point:
            break
        names += [str(v).strip() for v in point[k].get("value", [])]
    return [n for n in names if n]


def _kinds(
    point: dict, labels: list[str], warnings: list[str]
) -> tuple[list[str | None], list[str]]:
    """Per point: its model output kind (``None`` for a marker) and unit (``""`` for markers).

    A label matches a kind's list with or without its subject prefix on either side.
    """
    kinds: list[str | None] = [None] * len(labels)
    units = [""] * len(labels)
    bare = [lab.partition(":")[2] or lab for lab in labels]
    for kind, (key, unit_key, assumed) in MODEL_KINDS.items():
        listed = _names(point, key)
        if not listed:
            continue
        wanted = set(listed) | {n.partition(":")[2] or n for n in listed}
        unit = str(_value(point, unit_key, "")).strip()
        if not unit and assumed:
            unit = assumed
            warnings.append(f"POINT:{unit_key} absent; {assumed} assumed")
        for j, lab in enumerate(labels):
            if kinds[j] is None and (lab in wanted or bare[j] in wanted):
                kinds[j], units[j] = kind, unit
    return kinds, units


def _known_prefixes(parameters: dict) -> list[str]:
    """Vicon's ``SUBJECTS:LABEL_PREFIXES`` (``["A22:"]``) when ``USES_PREFIXES`` is set."""
    subjects = parameters.get("SUBJECTS", {})
    if not _value(subjects, "USES_PREFIXES", 0.0):
        return []
    values = subjects.get("LABEL_PREFIXES", {}).get("value", [])
    return [str(p).strip() for p in values if str(p).strip()]


def _strip_prefixes(labels: list[str], known: list[str]) -> tuple[list[str], dict[str, str]]:
    """Labels without their subject prefix, if the bare names are all distinct (else all kept,
    as two subjects or rigid bodies with the same marker names need them); name → prefix."""
    split = []
    for lab in labels:
        prefix = next((p for p in known if lab.startswith(p) and len(lab) > len(p)), None)
        if prefix is None and ":" in lab.strip(":"):
            prefix = lab[: lab.index(":") + 1]
        split.append((prefix, lab[len(prefix) :] if prefix else lab))
    if not any(p for p, _ in split):
        return list(labels), {}
    bare = [name for _, name in split]
    if len(set(bare)) < len(set(labels)):  # stripping would merge distinct labels
        return list(labels), {}
    return bare, {name: p for p, name in split if p}


def _unique(labels: list[str]) -> tuple[list[str], dict[str, int]]:
    """Repeated labels renamed ``NAME_2``, ``NAME_3``…; the repeats' counts by name."""
    counts: dict[str, int] = {}
    for lab in labels:
        counts[lab] = counts.get(lab, 0) + 1
    taken = set(labels)
    seen: dict[str, int] = {}
    out = []
    for lab in labels:
        seen[lab] = seen.get(lab, 0) + 1
        name, k = lab, seen[lab]
        if k > 1:
            name = f"{lab}_{k}"
            while name in taken:
                name += "_"
            taken.add(name)
        out.append(name)
    return out, {lab: n for lab, n in counts.items() if n > 1}
