"""C3D marker files (Vicon, OptiTrack, Qualisys, …), read with numpy.

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

The file is read here, not by ezc3d (whose object model takes about 11× the file): the header
block, the parameter section (:func:`_read_parameters`) and then the points of each frame
through a numpy structured dtype that skips the frame's analog samples (:func:`_read_points`),
a few MB at a time, so that the memory is the result's. Intel, DEC and MIPS files, float32 or
int16 storage, read as ezc3d 1.7 reads them (``tests/test_io_c3d_reader.py`` compares the two
bit for bit). Before the frames are read, the parameter section is walked record by record
(:func:`_check_records`: group ids, data types, dimensions, description lengths, each record
ending where the next one starts, the scale and offset parameters a frame needs), so that a
damaged record is refused with its byte offset, and the frames and points it announces
(``POINT:FRAMES``, ``POINT:USED``; the header block where absent) are checked against the
file's size; a truncated file is refused, a complete file with a stale header block is read.
A point is invalid — NaN in ``positions`` and ``residuals`` — when its residual is negative
(the C3D "not seen" flag) or all three coordinates are exactly zero (how some exporters write
a gap). Analog channels are not read; their count is kept in ``attrs["n_analog_channels"]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError, shorten
from motionlab.io import Recording
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
    _check_records(path, layout)
    _check_size(path, layout)
    if layout.frames > 0 and layout.size < layout.data_start + layout.frame_bytes:
        raise _truncated(path, "the file ends inside its first frame", "frame 1")
    point = layout.parameters.get("POINT", {})
    rate = _value(point, "RATE", layout.header_rate)
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"point rate {rate} Hz", path, "parameter POINT:RATE", "fix the rate")
    xyz, residuals = _read_points(path, layout)  # (N, M, 3), (N, M) in the file's unit
    n_frames, n_markers = residuals.shape
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
    labels, prefixes = _strip_prefixes(raw, _known_prefixes(layout.parameters))
    labels, duplicates = unique_labels(labels)
    for name, count in duplicates.items():
        warnings.append(
            f"label {name} appears {count} times; the repeats are renamed "
            + ", ".join(f"{name}_{k}" for k in range(2, count + 1))
        )
    unseen = (residuals < 0) | np.isnan(xyz).any(axis=2)
    is_marker = np.array([k is None for k in kinds], dtype=bool)
    invalid = unseen | (np.all(xyz == 0.0, axis=2) & is_marker)  # zeros: a marker gap only
    del unseen
    xyz[invalid] = np.nan
    residuals[invalid] = np.nan
    del invalid
    outputs = {
        labels[j]: ModelOutput(labels[j], kinds[j], units[j], xyz[:, j].copy())
        for j in np.flatnonzero(~is_marker)
    }
    if not is_marker.all():  # else the arrays are used as they are, scaled in place
        xyz, residuals = xyz[:, is_marker], residuals[:, is_marker]
    xyz *= scale
    residuals *= scale
    _drop_far(path, xyz, residuals, warnings)

    analogs = layout.parameters.get("ANALOG", {})
    attrs: dict[str, Any] = {
        "first_frame": layout.first_frame,
        "nominal_rate_hz": rate,
        "n_analog_channels": layout.analog_channels,
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
        positions=xyz,
        residuals=residuals,
        source_units={"positions": unit, "residuals": unit},
        attrs=attrs,
        model_outputs=outputs,
    )
    return Recording(markers=[markers], metadata={"c3d_unit": unit})


#: m: a marker coordinate further than this from the lab's origin is damage, not a marker
MARKER_MAX_M = 100.0


def _drop_far(path: Path, xyz: np.ndarray, residuals: np.ndarray, warnings: list[str]) -> None:
    """Marker samples with a coordinate beyond :data:`MARKER_MAX_M` (m; a damaged data block:
    random bytes read as floats reach 1e35 m) set missing, in place, with a warning; refused
    when they are most of the samples seen (the data block is not marker data)."""
    with np.errstate(invalid="ignore"):
        far = (np.abs(xyz) > MARKER_MAX_M).any(axis=2)
    n_far = int(far.sum())
    if not n_far:
        return
    seen = int(np.isfinite(xyz).all(axis=2).sum())
    if n_far > 0.5 * seen:
        frame, marker = np.argwhere(far)[0]
        raise InputError(
            f"{n_far} of {seen} marker samples lie beyond {MARKER_MAX_M:g} m of the origin "
            f"(frame {frame + 1}, point {marker + 1}: {np.nanmax(np.abs(xyz[frame, marker])):.3g}"
            " m): the data block is damaged",
            path,
            remedy="export the trial again from the motion-capture software",
        )
    xyz[far] = np.nan
    residuals[far] = np.nan
    warnings.append(f"{n_far} marker samples beyond {MARKER_MAX_M:g} m of the origin set missing "
                    "(damaged?)")  # fmt: skip


#: processor types (the parameter section's fourth byte)
INTEL, DEC, MIPS = 84, 85, 86
#: bytes of frames read at once (bounds the reading buffer, not the result)
_CHUNK_BYTES = 1 << 22


def _read_points(path: Path, layout: _Layout) -> tuple[np.ndarray, np.ndarray]:
    """Every point of every frame as ezc3d reads it: positions (N, M, 3) and residuals (N, M)
    in the file's unit (float64), NaN positions where the residual is negative.

    A frame is ``POINT:USED`` points of four words (x, y, z, residual) then the frame's analog
    samples; a word is a float32 (header scale factor negative) or an int16 scaled by
    ``POINT:SCALE``. Frames are read a few MB at a time through a structured dtype that only
    names the points, so that the memory is the result's, not the file's.

    The residual word, as ezc3d 1.7 reads it: float storage — the fourth float, negative
    for a point not seen, else rounded (half away from zero) to an integer whose second byte
    is the residual × ``|POINT:SCALE|`` and whose low byte is the camera mask (NaN, ∞ or
    beyond 2⁶³: residual 0); int16 storage — the word's high byte an int8 residual ×
    ``POINT:SCALE`` (negative: not seen), the low byte the camera mask. A point not seen has
    residual -1 and a NaN position, as ezc3d gives them.
    """
    n, m = layout.frames, layout.points
    xyz = np.empty((n, m, 3))
    residuals = np.empty((n, m))
    if n == 0 or m == 0:
        return xyz, residuals
    word = 4 if layout.is_float else 2
    frame = np.dtype({"names": ["p"], "formats": [("u1", (m, 4, word))],
                      "itemsize": layout.frame_bytes})  # fmt: skip
    scales = layout.scales[:m] if layout.scales.size >= m else np.full(m, layout.scales[0])
    step = max(1, _CHUNK_BYTES // layout.frame_bytes)
    with open(path, "rb") as f:
        f.seek(layout.data_start)
        for at in range(0, n, step):
            k = min(step, n - at)
            buf = f.read(k * layout.frame_bytes)
            if len(buf) < k * layout.frame_bytes:  # _check_size made sure it is there
                raise _truncated(path, "the file ends inside its data", f"frame {at + 1}")
            raw = np.frombuffer(buf, frame, k)["p"]  # (k, M, 4, word) bytes
            if layout.is_float:
                xyz[at : at + k] = _floats(raw[:, :, :3], layout.processor)
                word = _floats(raw[:, :, 3], layout.processor).astype(float)
                valid = ~(word < 0)  # NaN: valid, residual 0
                whole = np.where(valid & (word < 2.0**63), np.floor(word + 0.5), 0.0)
                high = (whole.astype(np.int64) >> 8) & 0xFF  # of the rounded integer
                residuals[at : at + k] = np.where(valid, high * np.abs(scales), -1.0)
            else:
                ints = np.ascontiguousarray(raw).view(f"{layout.order}i2")[..., 0]
                xyz[at : at + k] = ints[:, :, :3] * scales[:, None]
                high = raw[:, :, 3, 0 if layout.processor == MIPS else 1].view(np.int8)
                residuals[at : at + k] = high * scales
    unseen = residuals < 0
    xyz[unseen] = np.nan
    residuals[unseen] = -1.0  # ezc3d's value for a point not seen
    return xyz, residuals


def _floats(raw: np.ndarray, processor: int) -> np.ndarray:
    """float32 values from their 4 bytes (last axis) as ``processor`` stores them.

    DEC (VAX F-floating): the two 16-bit halves swapped, and the exponent 2 more than IEEE's
    (its byte, the second, less 1 unless 0), as ezc3d converts them.
    """
    raw = np.ascontiguousarray(raw, dtype=np.uint8)
    if processor == MIPS:
        return raw.view(">f4")[..., 0]
    if processor == DEC:
        swapped = np.ascontiguousarray(raw[..., [2, 3, 0, 1]])
        high = swapped[..., 3]
        swapped[..., 3] = np.where(high != 0, high - np.uint8(1), high)
        return swapped.view("<f4")[..., 0]
    return raw.view("<f4")[..., 0]


@dataclass
class _Layout:
    """Where things are in a C3D file, from its header block and parameter section (bytes)."""

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
    processor: int = INTEL
    is_float: bool = True  # the header's scale factor is negative: words are float32
    scales: np.ndarray = field(default_factory=lambda: np.array([-1.0]))  # POINT:SCALE
    header_rate: float = 0.0
    first_frame: int = 0  # 0-based, as ezc3d gives it
    analog_channels: int = 0  # ANALOG:USED
    parameters: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict)


def _layout(path: Path) -> _Layout:
    """The header block, the parameter section and the data layout they give, after checking
    that the file reaches its first frame.

    Header words (16-bit, 1-based): 1 parameter block (low byte) and key 0x50, 2 points per
    frame, 3 analog samples per frame, 4–5 first and last frame, 7–8 the scale factor (float;
    negative: samples stored as float32, else int16), 9 the first block of the data, 11–12
    the frame rate (float). The parameter section's fourth byte is the processor type: 84
    Intel, 85 DEC, 86 MIPS (the only big-endian one). The parameter section wins where it
    disagrees with the header block (``POINT:USED``, ``POINT:FRAMES``; analog samples per
    frame = ``ANALOG:USED`` × ``ANALOG:RATE`` / ``POINT:RATE``), as in ezc3d. Raises
    :class:`InputError` for a file cut before its first frame.
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
    processor = params[3]
    order = ">" if processor == MIPS else "<"
    words = np.frombuffer(head[:20], dtype=f"{order}u2").astype(int).tolist()
    frames = words[4] - words[3] + 1
    data_start = (words[8] - 1) * 512
    if size < min(start + params[2] * 512, data_start):  # some writers overstate params[2]
        raise _truncated(path, "the file ends inside its parameter section", None)
    if frames > 0 and size <= data_start:
        raise _truncated(
            path, f"the file ends before its first frame (the header announces {frames})",
            "frame 1",
        )  # fmt: skip
    if data_start <= start:
        raise InputError(
            f"damaged header block: the data starts at block {words[8]}, not after the "
            f"parameter section (block {start // 512 + 1})",
            path,
            "header word 9",
            "export the C3D again from the capture software",
        )
    floats = np.frombuffer(head[12:16] + head[20:24], np.uint8).reshape(2, 4)
    header_scale, header_rate = _floats(floats, processor).astype(float).tolist()
    is_float = bool(head[{INTEL: 15, DEC: 13, MIPS: 12}.get(processor, 15)] & 0x80)
    groups = _read_parameters(section, processor)
    point, analog = groups.get("POINT", {}), groups.get("ANALOG", {})
    points = _count(point, "USED", words[1])
    frames_param = _count(point, "FRAMES", frames, least=-(1 << 15))
    announced = frames_param if frames_param > 0 else max(int(frames), 0)  # > 32767: < 0
    rate = _value(point, "RATE", header_rate)
    channels = _count(analog, "USED", 0)
    analog_words = int(words[2])
    if "USED" in analog and "RATE" in analog:  # what ezc3d does (the header may be stale)
        ratio = _value(analog, "RATE", 0.0) / rate if np.isfinite(rate) and rate >= 1 else 1.0
        analog_words = channels * (int(ratio) if 0 <= ratio < 1e9 else 0)
    frame_bytes = (4 * points + analog_words) * (4 if is_float else 2)
    if frames_param < 0 and frame_bytes > 0:  # more frames than int16: read what it holds
        announced = max(announced, (size - data_start) // frame_bytes)
    scales = np.asarray(point.get("SCALE", {}).get("value", []), dtype=float).ravel()
    if scales.size == 0:
        scales = np.array([header_scale])
    first = max(int(words[3]) - 1, 0)
    return _Layout(size, start, order, int(words[2]), int(announced), int(data_start),
                   int(frame_bytes), int(frames), points, int(words[1]), processor, is_float,
                   scales, header_rate, first, channels, groups)  # fmt: skip


def _count(group: dict, name: str, default: int, least: int = 0) -> int:
    """An integer parameter's first value (``default`` if absent or not a number ≥ ``least``)."""
    value = _value(group, name, default)
    if isinstance(value, str) or not np.isfinite(value) or not least <= value < 1 << 31:
        return int(default)
    return int(value)


def _read_parameters(section: bytes, processor: int) -> dict[str, dict[str, dict[str, Any]]]:
    """The parameter section as ezc3d gives it: ``{GROUP: {NAME: {"value": …}}}``.

    Values: characters as a list of strings (one per column of a 2-D array, its first
    dimension the length; trailing spaces and NUL bytes removed), numbers as a numpy array in
    Fortran order (bytes as int8, words as int16, floats converted from the processor's
    format). A damaged section gives what could be read before the damage (:func:`_check_records`
    has refused a damaged record already).
    """
    order = ">" if processor == MIPS else "<"
    i16 = np.dtype(f"{order}i2")
    names: dict[int, str] = {}
    found: list[tuple[int, str, int]] = []
    pos = 4
    while pos + 4 <= len(section):
        nlen, gid = np.frombuffer(section, np.int8, 2, pos).tolist()
        end = pos + 2 + abs(nlen)
        if nlen == 0 or end + 2 > len(section):
            break
        name = section[pos + 2 : end].decode("latin-1").upper()
        offset = int(np.frombuffer(section, i16, 1, end)[0])
        if gid < 0:
            names.setdefault(-gid, name)
        elif gid > 0:
            found.append((gid, name, end + 2))
        if offset <= 0:
            break
        pos = end + offset
    groups: dict[str, dict[str, dict[str, Any]]] = {name: {} for name in names.values()}
    for gid, name, p in found:
        if gid not in names or p + 2 > len(section):
            continue
        kind, ndims = int(np.frombuffer(section, np.int8, 1, p)[0]), section[p + 1]
        dims = list(section[p + 2 : p + 2 + ndims])
        if kind not in _TYPES or ndims > _MAX_DIMS or len(dims) < ndims:
            continue
        body = p + 2 + ndims
        count = int(np.prod(dims)) if ndims else (0 if kind == -1 else 1)
        if body + count * abs(kind) > len(section):
            continue
        data = section[body : body + count * abs(kind)]
        if kind == -1:
            value: Any = _strings(data, dims)
        elif kind == 4:
            raw = np.frombuffer(data, np.uint8).reshape(-1, 4)
            value = _floats(raw, processor).astype(float)
        else:
            value = np.frombuffer(data, np.int8 if kind == 1 else i16).astype(int)
        if kind != -1 and ndims:
            value = value.reshape(dims, order="F")
        groups[names[gid]].setdefault(name, {"type": kind, "value": value})
    return groups


def _strings(data: bytes, dims: list[int]) -> list[str]:
    """Character parameter values: one string per column of ``dims[0]`` characters."""
    if not dims or len(dims) == 1 and dims[0] == 0:
        return []
    if dims[0] == 0:  # columns of no characters: empty strings
        return [""] * int(np.prod(dims[1:]))
    width = dims[0]
    out = []
    for k in range(0, len(data), width):
        chunk = data[k : k + width].replace(b"\x00", b"")
        try:
            text = chunk.decode("utf-8")
        except UnicodeDecodeError:
            text = chunk.decode("latin-1")
        out.append(text.rstrip(" "))
    return out


def _check_size(path: Path, layout: _Layout) -> None:
    """Refuse, before its frames are read, a file that cannot hold the frames its parameter
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
    (up to 16 values; from :func:`_read_parameters`, so a damaged section gives what could be
    read before the damage)."""
    groups = _read_parameters(section, MIPS if order == ">" else INTEL)
    return {
        (group, name): np.ravel(p["value"]).astype(float).tolist()
        for group, params in groups.items()
        for name, p in params.items()
        if p["type"] != -1 and 0 < np.size(p["value"]) <= 16
    }


def _truncated(path: Path, message: str, where: str | None) -> InputError:
    return InputError(f"truncated: {message}", path, where, "copy or export the file again")


def _value(group: dict, name: str, default: Any) -> Any:
    """First value of a C3D parameter, or ``default`` when absent or empty."""
    values = group.get(name, {}).get("value", [])
    if isinstance(values, np.ndarray):
        values = values.ravel()
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


def unique_labels(labels: list[str]) -> tuple[list[str], dict[str, int]]:
    """Repeated labels renamed ``NAME_2``, ``NAME_3``… (a name already taken gets ``_`` more);
    the repeats' counts by name. The reader and the writer (:func:`motionlab.export.write_c3d`)
    both use it: C3D tools look points up by label."""
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
