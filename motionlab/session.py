"""The session: everything recorded in one visit, and every stage's results, in one HDF5 file.

Data model (SI units, first array dimension is time):

- :class:`SensorStream`: one IMU — ``time`` (s), ``acc`` (m/s², specific force), ``gyr`` (rad/s),
  ``mag`` (µT), optional vendor orientation ``quat`` (N×4, sensor → ENU earth, scalar first).
- :class:`MarkerSet`: one optical recording — marker ``positions`` (N×M×3, m, NaN = not seen),
  ``residuals`` (N×M, m), optional rigid-body orientations, and the model outputs a C3D file
  carries beside its markers (:class:`ModelOutput`: joint angles, forces, moments, powers… in
  the unit the file gives).
- :class:`Session`: sensors, marker sets, subject/session metadata, stage ``results``
  (:class:`motionlab.results.Results`: one typed attribute per stage, e.g.
  ``session.results.calibration``) and the provenance log.

Stage results are read and stored by attribute (``session.results.fusion[label].quat``); only
this module turns them into the file's tree and back (``Results.to_tree`` / ``from_tree``).

HDF5 layout (``h5dump`` shows it)::

    /                       attrs: format, schema_version, metadata (JSON), lineage (JSON)
    /sensors/<label>/       time, acc, gyr, mag, quat, extra/<name>; attrs: serial, vendor, ...
    /markers/<name>/        time, positions, residuals, rigid_bodies/<name>; attrs: labels, ...
    /markers/<name>/model_outputs/<kind>   (N×K×3) one dataset per kind; attrs: labels, units
    /results/<stage>/...    Results.to_tree(): groups = dicts, datasets = arrays, attrs = JSON
    /provenance             one JSON object per entry (software version, command, inputs' SHA-256)

Round trip :func:`save_session` → :func:`load_session` is bit-exact.

Schema versions: 3 (current) stores what each result was computed from, the root attribute
``lineage`` (:mod:`motionlab.lineage`); a schema-2 file has none and its results are taken as
consistent (:meth:`~motionlab.lineage.Lineage.assumed`). 2 stores the angle table's ``units`` and
``events``; a schema-1 file loads with the units taken from the column names and the events
from the calibration steps and metric blocks (:func:`_upgrade_v1`). Older files are written
back as schema 3 (a motionlab that knows only schema 2 then refuses the file instead of
replacing a result without its stamp).
"""

from __future__ import annotations

import datetime as _dt
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import h5py
import numpy as np

from motionlab import __version__
from motionlab.atomic import atomic_path, check_regular
from motionlab.errors import InputError, shorten
from motionlab.isolated import check_hdf5, looks_like_hdf5, open_hdf5
from motionlab.lineage import Lineage, sha256_file
from motionlab.lock import command_line
from motionlab.results import Results

SCHEMA_VERSION = 3
FORMAT_NAME = "motionlab-session"

#: SI unit of each sensor channel inside motionlab.
CHANNEL_UNITS = {"time": "s", "acc": "m/s^2", "gyr": "rad/s", "mag": "uT", "quat": "1"}
SENSOR_CHANNELS = ("acc", "gyr", "mag", "quat")


@dataclass
class SensorStream:
    """One inertial sensor's recording.

    ``source_units`` records the unit each channel had in the input file
    (e.g. ``{"gyr": "deg/s"}``); ``extra`` holds other per-sample channels (same length as
    ``time``), e.g. ``free_acc`` or a ``movement`` mask;
    ``qc`` holds the ingest quality checks; ``attrs`` anything else JSON-able.
    """

    label: str
    time: np.ndarray
    acc: np.ndarray | None = None
    gyr: np.ndarray | None = None
    mag: np.ndarray | None = None
    quat: np.ndarray | None = None
    serial: str = ""
    vendor: str = ""
    segment: str = ""
    side: str = ""
    source_units: dict[str, str] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    qc: dict[str, Any] = field(default_factory=dict)
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def channels(self) -> list[str]:
        """Names of the channels present (``acc``, ``gyr``, ``mag``, ``quat``)."""
        return [c for c in SENSOR_CHANNELS if getattr(self, c) is not None]

    @property
    def n_samples(self) -> int:
        return int(len(self.time))

    @property
    def rate_hz(self) -> float:
        """Sampling rate estimated from the timestamps (median interval)."""
        return estimate_rate(self.time)

    @property
    def duration_s(self) -> float:
        return float(self.time[-1] - self.time[0]) if len(self.time) > 1 else 0.0


#: model output kinds, as C3D names their POINT groups (``POINT:ANGLES`` → ``angles``)
MODEL_OUTPUT_KINDS = ("angles", "forces", "moments", "powers", "scalars", "reactions")


@dataclass
class ModelOutput:
    """One model output of an optical recording (a C3D ``POINT`` that is not a marker).

    ``kind`` is one of :data:`MODEL_OUTPUT_KINDS`; ``data`` is (N, 3) on the marker set's
    ``time``, in ``unit`` as the file gives it (e.g. ``deg`` for Plug-in Gait ``LKneeAngles``,
    ``Nmm`` for moments; not converted to SI), NaN where invalid.
    """

    name: str
    kind: str
    unit: str
    data: np.ndarray


@dataclass
class MarkerSet:
    """Optical motion capture: marker trajectories and/or rigid-body orientations.

    ``positions`` is N×M×3 in m with NaN where a marker was not seen; ``residuals`` N×M in m
    (NaN where unknown); ``rigid_bodies`` maps a body name to N×4 quaternions (body → lab frame);
    ``model_outputs`` maps a name to a :class:`ModelOutput` (joint angles etc., not markers).
    """

    name: str
    time: np.ndarray
    labels: list[str] = field(default_factory=list)
    positions: np.ndarray | None = None
    residuals: np.ndarray | None = None
    rigid_bodies: dict[str, np.ndarray] = field(default_factory=dict)
    source_units: dict[str, str] = field(default_factory=dict)
    attrs: dict[str, Any] = field(default_factory=dict)
    model_outputs: dict[str, ModelOutput] = field(default_factory=dict)

    @property
    def rate_hz(self) -> float:
        return estimate_rate(self.time)

    def outputs_of(self, kind: str) -> dict[str, ModelOutput]:
        """The model outputs of one kind (``"angles"``…), by name."""
        return {k: o for k, o in self.model_outputs.items() if o.kind == kind}

    @property
    def n_markers(self) -> int:
        return len(self.labels)


@dataclass
class Session:
    """One recording session: sensors, marker sets, metadata, stage results and provenance.

    ``results`` holds every stage's typed result (:class:`~motionlab.results.Results`);
    ``lineage`` what each was computed from (:class:`~motionlab.lineage.Lineage`: stale results);
    ``schema_version`` is the schema of the file it was loaded from (a save writes the current
    :data:`SCHEMA_VERSION`).
    """

    sensors: dict[str, SensorStream] = field(default_factory=dict)
    markers: dict[str, MarkerSet] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    results: Results = field(default_factory=Results)
    provenance: list[dict[str, Any]] = field(default_factory=list)
    schema_version: int = SCHEMA_VERSION
    lineage: Lineage = field(default_factory=Lineage)

    def add_provenance(
        self,
        command: str | None = None,
        parameters: dict[str, Any] | None = None,
        inputs: list[str | Path] = (),
    ) -> None:
        """Append a provenance entry: time, software version, command, parameters, input hashes."""
        self.provenance.append(
            {
                "time": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "software": f"motionlab {__version__}",
                "command": command if command is not None else command_line(),
                "parameters": parameters or {},
                "inputs": {str(p): sha256_file(p) for p in inputs},
            }
        )


def estimate_rate(time: np.ndarray) -> float:
    """Sampling rate (Hz) from the median sample interval; NaN for fewer than two samples."""
    time = np.asarray(time, dtype=float)
    if len(time) < 2:
        return float("nan")
    dt = np.median(np.diff(time))
    return float(1.0 / dt) if dt > 0 else float("nan")


# ------------------------------------------------------------------------------------ writing


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=_json_default)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot store {type(value).__name__} in a session file")


def _write_array(group: h5py.Group, name: str, data: np.ndarray, unit: str | None = None) -> None:
    data = np.asarray(data)
    if data.dtype.kind == "U":
        ds = group.create_dataset(name, data=data.astype(object), dtype=h5py.string_dtype())
        ds.attrs["kind"] = "str"
    else:
        ds = group.create_dataset(name, data=data)
    if unit is not None:
        ds.attrs["unit"] = unit


def _write_tree(group: h5py.Group, tree: dict[str, Any]) -> None:
    """Dicts become groups, arrays datasets, everything else a JSON attribute; groups keep the
    order of their keys (``track_order``), so a result read back iterates as it was written
    (a report rebuilt from the file lists joints, sensors and tasks as ``run``'s did)."""
    for key, value in tree.items():
        key = str(key)
        if isinstance(value, dict):
            _write_tree(group.create_group(key, track_order=True), value)
        elif isinstance(value, np.ndarray):
            _write_array(group, key, value)
        else:
            _write_text_attr(group, key, _json(value))


_TEXT = h5py.string_dtype()  # variable-length UTF-8, as h5py stores a str attribute
_TEXT_TYPE = h5py.h5t.py_create(_TEXT, logical=True)


def _write_text_attr(group: h5py.Group, name: str, text: str) -> None:
    """``group.attrs[name] = text`` for a new attribute: the same attribute, without h5py's
    per-call type guessing (half the time; a session's results hold a thousand of them)."""
    space = h5py.h5s.create(h5py.h5s.SCALAR)
    h5py.h5a.create(group.id, name.encode(), _TEXT_TYPE, space).write(np.array(text, dtype=_TEXT))


def write_session(session: Session, path: str | Path | BinaryIO) -> None:
    """Write ``session`` to ``path`` (or a binary file object) directly (no atomic rename; see
    :func:`save_session`)."""
    with h5py.File(path, "w", track_order=True) as f:
        f.attrs["format"] = FORMAT_NAME
        f.attrs["schema_version"] = SCHEMA_VERSION
        f.attrs["metadata"] = _json(session.metadata)
        f.attrs["lineage"] = _json(session.lineage.to_tree())
        sensors = f.create_group("sensors", track_order=True)
        for label, s in session.sensors.items():
            g = sensors.create_group(label)
            _write_array(g, "time", s.time, "s")
            for ch in SENSOR_CHANNELS:
                arr = getattr(s, ch)
                if arr is not None:
                    _write_array(g, ch, arr, CHANNEL_UNITS[ch])
            if s.quat is not None:
                g["quat"].attrs["convention"] = "w,x,y,z; sensor -> ENU earth"
            if s.extra:
                ex = g.create_group("extra", track_order=True)
                for name, arr in s.extra.items():
                    _write_array(ex, name, arr)
            g.attrs["label"] = s.label
            for key in ("serial", "vendor", "segment", "side"):
                g.attrs[key] = getattr(s, key)
            for key in ("source_units", "qc", "attrs"):
                g.attrs[key] = _json(getattr(s, key))
        markers = f.create_group("markers", track_order=True)
        for name, m in session.markers.items():
            g = markers.create_group(name)
            _write_array(g, "time", m.time, "s")
            if m.positions is not None:
                _write_array(g, "positions", m.positions, "m")
            if m.residuals is not None:
                _write_array(g, "residuals", m.residuals, "m")
            if m.rigid_bodies:
                rb = g.create_group("rigid_bodies", track_order=True)
                for body, q in m.rigid_bodies.items():
                    _write_array(rb, body, q, "1")
            if m.model_outputs:
                _write_model_outputs(g.create_group("model_outputs", track_order=True), m)
            g.attrs["name"] = m.name
            g.attrs["labels"] = _json(list(m.labels))
            g.attrs["source_units"] = _json(m.source_units)
            g.attrs["attrs"] = _json(m.attrs)
        _write_tree(f.create_group("results", track_order=True), session.results.to_tree())
        f.create_dataset(
            "provenance",
            data=np.array([_json(p) for p in session.provenance], dtype=object),
            dtype=h5py.string_dtype(),
        )


def _write_model_outputs(group: h5py.Group, m: MarkerSet) -> None:
    """One (N, K, 3) dataset per kind, with its output names and units as attributes."""
    for kind in dict.fromkeys(o.kind for o in m.model_outputs.values()):
        outs = list(m.outputs_of(kind).values())
        data = np.stack([np.asarray(o.data, dtype=float) for o in outs], axis=1)
        ds = group.create_dataset(kind, data=data)
        ds.attrs["labels"] = _json([o.name for o in outs])
        ds.attrs["units"] = _json([o.unit for o in outs])


def _read_model_outputs(group: h5py.Group, place: _Place, n: int) -> dict[str, ModelOutput]:
    out = {}
    for kind, ds in group.items():
        names, units = _json_attr(ds, "labels", place), _json_attr(ds, "units", place)
        if not isinstance(names, list) or not isinstance(units, list):
            raise place.fail("labels and units are not lists")
        data = _numeric(ds, place, n, len(names), 3)
        for k, (name, unit) in enumerate(zip(names, units, strict=True)):
            out[name] = ModelOutput(name, kind, unit, data[:, k])
    return out


def save_session(session: Session, path: str | Path, force: bool = False) -> None:
    """Write ``session`` atomically: a temporary file in the same folder renamed onto ``path``.

    An existing ``path`` is replaced only with ``force=True`` (:class:`InputError` otherwise).
    The file is built in memory and written with Python's own writes, so that a full disk is an
    :class:`InputError` (:func:`motionlab.atomic.atomic_path`) and the old file stays whole.
    """
    buffer = io.BytesIO()  # libhdf5 reports a failed write (a full disk) only as a warning
    write_session(session, buffer)
    with atomic_path(path, force=force) as tmp, open(tmp, "wb") as f:
        f.write(buffer.getbuffer())  # raises on a full disk: the old file stays


# ------------------------------------------------------------------------------------ reading


#: shape of each sensor channel after the time axis
_CHANNEL_WIDTH = {"acc": 3, "gyr": 3, "mag": 3, "quat": 4}


class _Place:
    """Where :func:`load_session` is reading (``/sensors/shank/acc``), for its messages."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.where = "/"

    def fail(self, message: str, remedy: str = "") -> InputError:
        return InputError(
            message,
            self.path,
            f"key {self.where}",
            remedy or "write the session again with 'motionlab ingest'",
        )


def _read_array(ds: h5py.Dataset, place: _Place | None = None) -> np.ndarray:
    if not isinstance(ds, h5py.Dataset):
        raise (place or _Place(Path("session"))).fail("cannot be opened as a dataset")
    if place is not None:
        place.where = ds.name
    if ds.attrs.get("kind") == "str":
        return ds.asstr()[()].astype(str)
    return ds[()]


def _numeric(ds: h5py.Dataset, place: _Place, *shape: int | None) -> np.ndarray:
    """A dataset that must hold numbers in ``shape`` (``None``: any length there) as float64
    (booleans stay booleans)."""
    place.where = ds.name
    if not isinstance(ds, h5py.Dataset):
        raise place.fail("is a group, expected a dataset")
    if len(ds.shape) != len(shape) or any(
        w is not None and w != d for w, d in zip(shape, ds.shape, strict=True)
    ):
        want = tuple("N" if w is None else w for w in shape)
        raise place.fail(f"shape {ds.shape}, expected {want}")
    if ds.dtype.kind not in "biuf":
        raise place.fail(f"holds {ds.dtype}, expected numbers")
    data = ds[()]
    return data if data.dtype.kind == "b" else np.asarray(data, dtype=float)


def _json_attr(obj: h5py.Group | h5py.Dataset, key: str, place: _Place) -> Any:
    place.where = f"{obj.name.rstrip('/')}/@{key}"
    if key not in obj.attrs:
        raise place.fail("missing attribute")
    value = obj.attrs[key]
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if not isinstance(value, str):
        raise place.fail(f"holds {type(value).__name__}, expected JSON text")
    _utf8(value, place)
    try:
        return json.loads(value)
    except ValueError:
        raise place.fail(f"not JSON: {shorten(value)!r}") from None


def _text_attr(obj: h5py.Group, key: str, place: _Place) -> str:
    place.where = f"{obj.name.rstrip('/')}/@{key}"
    if key not in obj.attrs:
        raise place.fail("missing attribute")
    value = obj.attrs[key]
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return _utf8(str(value), place)


def _utf8(text: str, place: _Place) -> str:
    """``text`` if it is valid UTF-8 (h5py decodes damaged bytes to surrogates, which cannot be
    printed or written again)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise place.fail(f"is not valid UTF-8 text: {shorten(text)!r}") from None
    return text


def _read_tree(group: h5py.Group, place: _Place | None = None) -> dict[str, Any]:
    place = place or _Place(Path(group.file.filename))
    tree: dict[str, Any] = {k: _json_attr(group, k, place) for k in group.attrs}
    for key, item in group.items():
        place.where = f"{group.name.rstrip('/')}/{shorten(key)}"
        _utf8(key, place)
        if item is None:
            raise place.fail("cannot be opened, the file is damaged")
        if isinstance(item, h5py.Group):
            tree[key] = _read_tree(item, place)
        else:
            tree[key] = _read_array(item, place)
    return tree


def is_session_file(path: str | Path) -> bool:
    """Whether ``path`` is a motionlab session (HDF5 with the session format attribute); a
    damaged HDF5 file that would crash libhdf5 is refused
    (:func:`~motionlab.isolated.check_hdf5`)."""
    if not looks_like_hdf5(path):
        return False
    check_hdf5(path)
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == FORMAT_NAME
    except (OSError, RuntimeError):
        return False


def load_session(path: str | Path) -> Session:
    """Read a session file written by :func:`save_session`.

    Raises :class:`InputError` when the file is missing, not HDF5 or not a motionlab session,
    and, naming the dataset or attribute, for damaged data (h5py cannot read it), attributes
    that are not JSON, or channels that are not numbers of the right shape.
    """
    path = Path(path)
    check_regular(path)
    if not path.is_file():
        raise InputError("no such session file", path, remedy="check the path")
    check_hdf5(path)  # a damaged file can crash libhdf5 itself: probed in a child first
    damaged = looks_like_hdf5(path)  # what a run calls a damaged HDF5 file, info calls so too
    f = open_hdf5(
        path,
        "HDF5 file is damaged or truncated (h5py cannot open it)" if damaged
        else "not an HDF5 file",
        "copy the file again, or run the stages again" if damaged
        else "give a session written by 'motionlab ingest'",
    )  # fmt: skip
    place = _Place(path)
    with f:
        try:
            return _load(f, path, place)
        except (OSError, KeyError, RuntimeError, TypeError, ValueError) as exc:  # h5py: damage
            detail = shorten(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
            raise place.fail(
                f"cannot be read, the file is damaged ({detail})",
                "copy the session again, or ingest the recordings again",
            ) from None


def _upgrade_v1(results: Results) -> None:
    """Schema 1 → 2: the angle table's events from the calibration steps and metric blocks
    (its units come from the column names, :func:`motionlab.results.column_unit`)."""
    if results.angles is None or results.angles.events:
        return
    if results.calibration is not None:
        for step, rng in results.calibration.steps.items():
            if rng is not None:
                results.angles.events[step] = (float(rng[0]), float(rng[1]))
    if results.metrics is not None:
        results.angles.events.update(results.metrics.spans())


def _groups(f: h5py.File, name: str, place: _Place) -> list[tuple[str, h5py.Group]]:
    """The subgroups of ``/name`` (sensors, marker sets), each checked to be a group."""
    place.where = f"/{name}"
    parent = f[name]
    if not isinstance(parent, h5py.Group):
        raise place.fail("is not a group")
    out = []
    for key, g in parent.items():
        place.where = f"/{name}/{shorten(key)}"
        _utf8(key, place)
        if not isinstance(g, h5py.Group):
            raise place.fail("cannot be opened as a group, the file is damaged")
        out.append((key, g))
    return out


def _group(parent: h5py.Group, key: str, place: _Place) -> h5py.Group:
    """``parent[key]``, which must be a group (a damaged file can make it anything)."""
    place.where = f"{parent.name.rstrip('/')}/{key}"
    item = parent[key]
    if not isinstance(item, h5py.Group):
        raise place.fail("cannot be opened as a group, the file is damaged")
    return item


def _load(f: h5py.File, path: Path, place: _Place) -> Session:
    if f.attrs.get("format") != FORMAT_NAME:
        raise InputError(
            "HDF5 file is not a motionlab session",
            path,
            remedy="create one with 'motionlab ingest'",
        )
    place.where = "/@schema_version"
    try:
        version = int(np.ravel(f.attrs["schema_version"])[0])
    except (ValueError, TypeError, IndexError):
        raise place.fail("is not an integer") from None
    if version > SCHEMA_VERSION:
        raise InputError(
            f"session schema {version} is newer than this motionlab ({SCHEMA_VERSION})",
            path,
            remedy="upgrade motionlab",
        )
    metadata = _json_attr(f, "metadata", place)
    if not isinstance(metadata, dict):
        raise place.fail("is not a JSON object")
    session = Session(metadata=metadata, schema_version=version)
    place.where = "/sensors"
    for label, g in _groups(f, "sensors", place):
        time = _numeric(g["time"], place, None)
        n = len(time)
        arrays = {
            ch: _numeric(g[ch], place, n, _CHANNEL_WIDTH[ch]) for ch in SENSOR_CHANNELS if ch in g
        }
        extra = (
            {k: _read_array(v, place) for k, v in _group(g, "extra", place).items()}
            if "extra" in g
            else {}
        )
        session.sensors[label] = SensorStream(
            label=_text_attr(g, "label", place),
            time=time,
            **arrays,
            serial=_text_attr(g, "serial", place),
            vendor=_text_attr(g, "vendor", place),
            segment=_text_attr(g, "segment", place),
            side=_text_attr(g, "side", place),
            source_units=_json_attr(g, "source_units", place),
            extra=extra,
            qc=_json_attr(g, "qc", place),
            attrs=_json_attr(g, "attrs", place),
        )
    place.where = "/markers"
    for name, g in _groups(f, "markers", place):
        time = _numeric(g["time"], place, None)
        n = len(time)
        labels = _json_attr(g, "labels", place)
        rb = {}
        if "rigid_bodies" in g:
            rb = {k: _numeric(v, place, n, 4) for k, v in _group(g, "rigid_bodies", place).items()}
        positions = g.get("positions")
        residuals = g.get("residuals")
        session.markers[name] = MarkerSet(
            name=_text_attr(g, "name", place),
            time=time,
            labels=labels,
            positions=None if positions is None else _numeric(positions, place, n, None, 3),
            residuals=None if residuals is None else _numeric(residuals, place, n, None),
            rigid_bodies=rb,
            source_units=_json_attr(g, "source_units", place),
            attrs=_json_attr(g, "attrs", place),
            model_outputs=(
                _read_model_outputs(_group(g, "model_outputs", place), place, n)
                if "model_outputs" in g
                else {}
            ),
        )
    place.where = "/results"
    tree = _read_tree(_group(f, "results", place), place)
    place.where = "/results"
    try:
        session.results = Results.from_tree(tree)
    except (TypeError, ValueError, KeyError, IndexError) as exc:
        raise place.fail(f"does not hold stage results this motionlab reads ({exc})") from None
    if version < 2:
        _upgrade_v1(session.results)
    if version < 3:  # no stamps yet: the results as consistent as the older motionlab took them
        session.lineage = Lineage.assumed(session.results)
    else:
        tree = _json_attr(f, "lineage", place)
        try:
            session.lineage = Lineage.from_tree(tree)
        except (TypeError, ValueError, KeyError, AttributeError) as exc:
            raise place.fail(f"is not a lineage this motionlab reads ({exc})") from None
    place.where = "/provenance"
    provenance = f["provenance"]
    if not isinstance(provenance, h5py.Dataset):
        raise place.fail("cannot be opened as a dataset, the file is damaged")
    entries = provenance.asstr()[()]
    try:
        session.provenance = [json.loads(s) for s in entries]
    except ValueError:
        raise place.fail("an entry is not JSON") from None
    return session
