"""Protocol files: what is recorded, where sensors go, how they are calibrated, what is computed.

A protocol is a YAML file (``protocols/*.yaml``; copy one and edit it). Schema::

    name: knee                          # short id (required)
    title: Bilateral knee kinematics    # one line for the report
    purpose: ...                        # a few sentences for the clinician
    segments:                           # every segment that carries a sensor (required)
      thigh_r:
        side: r                         # l, r, or omitted for midline segments
        placement: "lateral thigh, lower third, x forward, y up"   # text a clinician follows
        sensor_axes: [x, y, z]          # optional nominal sensor axes in segment axes (see below)
        landmarks: [GT_r, LE_r, ME_r]   # optional anatomical landmarks (marker names)
        required: true                  # false for optional sensors (e.g. a lumbar sensor)
        any_orientation: false          # true: the sensor may sit any way round (sensor_axes
                                        #   is a default; the data decide without a warning)
    calibration:                        # steps in the order the subject performs them
      - name: standing
        kind: static                    # static | functional
        pose: standing                  # static: standing | sitting | supine | other text
        duration_s: 5
        vertical_axis: {thigh_r: y}     # static: segment axis that is vertical, sign included
        horizontal_axis: {forearm_r: x} # static, optional: a segment axis lying horizontal
        instructions: "stand still, feet hip-width apart"
      - name: knee_flexion_r
        kind: functional
        segments: [thigh_r, shank_r]    # functional: the segments that move
        axis: {shank_r: -z}             # the segment axis the movement defines (sign = direction
                                        # of the angular velocity during the named movement)
        repetitions: 5
        duration_s: 10
        optional: false                 # true: the step may be left out of the recording
        reference_rho: {shank_r: 0.8}   # optional: expected reliability (quality report)
        time_range: [12.0, 20.5]        # optional: where the step is (s), skips detection
        axis_method: svd                # svd (default) | hinge: Seel's fit of the knee/elbow |
                                        # trunk: rest and flexion axis found anywhere in the
                                        # recording (segments/trunk_axes.py, lumbar_seated)
        instructions: "seated, flex and extend the right knee 5 times"
    joints:
      knee_r:
        type: knee                      # knee | elbow | lumbar | hinge | ball
                                        # (kinematics/joint_types.py has the table)
        proximal: thigh_r
        distal: shank_r                 # a segment other than proximal
        side: r                         # required for knee and elbow; optional otherwise
        sequence: ZXY                   # intrinsic Tait-Bryan sequence, upper case; knee, elbow
                                        # and lumbar: ZXY only (Grood & Suntay JCS, ISB)
      wrist_r:
        type: hinge                     # a generic hinge about its own axis
        axis: z                         # hinge only, required: x|y|z|-x|-y|-z, the same segment
                                        # axis in both segments at the zero pose; the sequence
                                        # (default z → ZXY, x → XYZ, y → YZX) starts with it
        proximal: forearm_r
        distal: hand_r
      shoulder_r:
        type: ball                      # three angles named by the sequence's letters
        sequence: YXZ                   # any of XYZ XZY YXZ YZX ZXY ZYX (default ZXY)
        proximal: thorax
        distal: upperarm_r
    tasks:                              # blocks of the recording after calibration
      - {name: gait, kind: gait, duration_s: 30}   # optional time_range: [95.0, 150.0] (s)
      - {name: sitting, kind: static, duration_s: 60}  # a pose held still (static, posture,
                                                        # rest): found as a rest, not a movement
    normative:                          # normal ranges per task and angle column, degrees;
                                        # a column without side (knee_flexion_deg) means both
      gait: {knee_flexion_deg: [0, 65]}
    metrics: [rom, peaks, cycles, cross_talk, varus_thrust]
    thresholds: {varus_thrust_deg: 3.0}  # numbers the metrics use (see kinematics/metrics.py)
    source: "where the normal ranges and the protocol come from"

Angle columns: ``<type>_<side>_<angle>_deg`` for knee, elbow and lumbar (``knee_r_flexion_deg``,
``lumbar_flexion_deg``); ``<joint>_<angle>_deg`` for hinge and ball joints (``wrist_r_angle_deg``,
``wrist_r_off_axis_1_deg``, ``shoulder_r_y_deg``). Two joints giving one column are an error.

Names of segments, joints, steps and tasks name groups of the session file and CSV files: not
empty, no ``/`` or ``\\``, at most 100 characters; a step's or task's name is given once. A
``normative`` key names a task (or ``range_of_motion``, the joint's anatomical range: an angle
more than 10° past it is reported as a sensor or calibration problem and states no finding,
:func:`motionlab.report.sentences.beyond_anatomy`) and its columns angle columns of the joints.
``thresholds`` holds only the keys :data:`THRESHOLD_KEYS`, each angle limit a size (0 to 180°).

The protocol's ``name`` (not empty, at most 80 characters) and ``title`` (200) are one line
each; the other texts the report shows (``purpose``, ``source``, ``placement``, ``pose``,
``instructions``) at most 2000 characters; no text holds a control character. Every number is
finite (``.nan`` and a 400-digit integer are refused).

Axis strings are ``x``, ``y``, ``z`` of the ISB segment frame (x anterior, y proximal, z right),
optionally with a sign: ``-z``. ``sensor_axes`` gives, for the sensor's x, y, z axes, the segment
axis each one points along in the nominal placement (e.g. ``[-z, y, x]``); the default is aligned.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.atomic import check_name_length, check_regular
from motionlab.errors import InputError, shorten
from motionlab.kinematics.joint_types import (
    JOINT_TYPES,
    angle_columns,
    joint_type,
    names_for,
    resolve_sequence,
    sequence_problem,
)
from motionlab.yamlsafe import (
    LineLoader,
    LineMap,
    did_you_mean,
    e_notation,
    finite,
    load_yaml,
    read_yaml_text,
    text_problem,
)

STEP_KINDS = ("static", "functional")
AXIS_METHODS = ("svd", "hinge", "trunk")
SIDES = ("l", "r", "")
AXES = {"x": 0, "y": 1, "z": 2}
#: the keys each part of a protocol may hold (anything else is a typo: an error with a hint)
TOP_KEYS = ("name", "title", "purpose", "segments", "calibration", "joints", "tasks",
            "normative", "metrics", "thresholds", "source", "angle_lowpass_hz")  # fmt: skip
#: the highest angle low-pass a protocol may set (Hz; any higher is the sampling's own limit)
MAX_ANGLE_LOWPASS_HZ = 1000.0
SEGMENT_KEYS = ("side", "placement", "sensor_axes", "landmarks", "required", "any_orientation")
#: s: the longest calibration step or task a protocol may ask for (a day)
MAX_DURATION_S = 86400.0
#: a ``normative`` key that names no task: the joint's full range (arm, elbow, children)
NORMATIVE_NOT_A_TASK = ("range_of_motion",)
#: the names ``metrics`` may list (the out-of-plane ones, :data:`motionlab.kinematics.metrics.
#: OUT_OF_PLANE`, are computed only when listed, or all when the list is empty)
METRICS = ("rom", "peaks", "cycles", "repetitions", "cross_talk", "out_of_plane_offset",
           "trunk_compensation", "varus_thrust", "stance_rotation")  # fmt: skip
#: the most repetitions a step or task may ask for
MAX_REPETITIONS = 10000
STEP_KEYS = ("name", "kind", "pose", "duration_s", "vertical_axis", "horizontal_axis",
             "instructions", "segments", "axis", "repetitions", "optional", "reference_rho",
             "time_range", "axis_method")  # fmt: skip
JOINT_KEYS = ("type", "proximal", "distal", "side", "sequence", "axis")
TASK_KEYS = ("name", "kind", "duration_s", "repetitions", "time_range", "instructions", "plane")
#: the keys ``thresholds`` may hold (:mod:`motionlab.kinematics.metrics`): limits in degrees
#: (``_deg``: a magnitude, 0 to :data:`MAX_THRESHOLD_DEG`; the trunk's one per angle of
#: :data:`TRUNK_ANGLES`), and percentages for comparison (``_pct``: any sign, not used)
THRESHOLD_KEYS = ("varus_thrust_deg", "out_of_plane_offset_deg", "trunk_compensation_deg",
                  "cross_talk_reference_pct")  # fmt: skip
#: the angles ``thresholds.trunk_compensation_deg`` gives a limit for
#: (:data:`motionlab.kinematics.out_of_plane.TRUNK_ANGLES`)
TRUNK_ANGLES = names_for("lumbar")
#: deg: the largest angle limit a threshold may be
MAX_THRESHOLD_DEG = 180.0
#: the most characters of the protocol's ``name`` (a short id, in every report page's heading),
#: its ``title`` (one line), its other texts shown in the report (``purpose``, ``source``,
#: ``placement``, ``pose``, ``instructions``: a few paragraphs at most) and of a segment's,
#: joint's, step's or task's name (it names a file); 100 000 characters kept the report's text
#: wrapping busy for minutes
MAX_NAME_CHARS = 80
MAX_TITLE_CHARS = 200
MAX_TEXT_CHARS = 2000
MAX_LABEL_CHARS = 100
PACKAGED = Path(__file__).resolve().parent / "protocols"


@dataclass
class Segment:
    name: str
    side: str = ""
    placement: str = ""
    sensor_axes: tuple[str, str, str] = ("x", "y", "z")
    landmarks: list[str] = field(default_factory=list)
    required: bool = True
    #: the sensor may sit in any orientation: ``sensor_axes`` is only a default, and a pose
    #: that finds it otherwise is no warning
    any_orientation: bool = False

    def nominal_mounting(self) -> np.ndarray:
        """3×3 matrix: columns are the sensor axes in segment coordinates (nominal placement)."""
        return np.column_stack([axis_vector(a) for a in self.sensor_axes])


@dataclass
class CalibrationStep:
    name: str
    kind: str
    duration_s: float
    instructions: str = ""
    pose: str = ""
    vertical_axis: dict[str, str] = field(default_factory=dict)
    horizontal_axis: dict[str, str] = field(default_factory=dict)
    segments: list[str] = field(default_factory=list)
    axis: dict[str, str] = field(default_factory=dict)
    repetitions: int = 0
    time_range: tuple[float, float] | None = None
    optional: bool = False
    reference_rho: dict[str, float] = field(default_factory=dict)
    axis_method: str = "svd"


@dataclass
class Joint:
    name: str
    type: str
    proximal: str
    distal: str
    side: str = ""
    #: intrinsic Euler sequence; ``""``: the type's standard one (the loader fills it in)
    sequence: str = ""
    #: hinge joints only: the hinge axis in segment coordinates (``'z'``, ``'-x'``)
    axis: str | None = None


#: task kinds that are a pose held still (:attr:`Task.is_pose`)
POSE_TASK_KINDS = ("static", "posture", "rest")


@dataclass
class Task:
    name: str
    kind: str
    duration_s: float = 0.0
    repetitions: int = 0
    time_range: tuple[float, float] | None = None
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def is_gait(self) -> bool:
        """Whether the task is walking (its kind says ``gait`` or ``walk``)."""
        return "gait" in self.kind.lower() or "walk" in self.kind.lower()

    @property
    def is_pose(self) -> bool:
        """Whether the task is a pose held still (kind ``static``, ``posture`` or ``rest``: quiet
        sitting or standing), found as a rest block rather than a movement."""
        return self.kind.lower() in POSE_TASK_KINDS


@dataclass
class Protocol:
    name: str
    segments: dict[str, Segment]
    joints: dict[str, Joint]
    calibration: list[CalibrationStep] = field(default_factory=list)
    tasks: list[Task] = field(default_factory=list)
    normative: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    metrics: list[str] = field(default_factory=list)
    thresholds: dict[str, Any] = field(default_factory=dict)
    title: str = ""
    purpose: str = ""
    source: str = ""
    #: the joint angles' low-pass (Hz) the protocol asks for (0: as computed; ``None``: the
    #: default, :data:`motionlab.kinematics.angle_filter.ANGLES_LOWPASS_HZ`)
    angle_lowpass_hz: float | None = None
    path: Path | None = None
    raw: dict[str, Any] = field(default_factory=dict)


def axis_vector(axis: str) -> np.ndarray:
    """Unit vector of a signed axis string (``'x'``, ``'-z'``) in segment coordinates."""
    axis = axis.strip()
    sign = -1.0 if axis.startswith("-") else 1.0
    v = np.zeros(3)
    v[AXES[axis.lstrip("+-")]] = sign
    return v


class _Reader:
    """Validates one protocol document, raising InputError that names the key and its line."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, where: str, line: int | None, message: str, remedy: str) -> None:
        place = f"line {line}, key {where}" if line else f"key {where}"
        raise InputError(message, self.path, place, remedy)

    def get(
        self,
        m: dict,
        key: str,
        where: str,
        kind: type | tuple,
        required: bool = True,
        default: Any = None,
    ) -> Any:
        line = getattr(m, "lines", {}).get(key)
        if key not in m:
            if required:
                parent_line = min(getattr(m, "lines", {}).values(), default=None)
                self.fail(
                    f"{where}.{key}".lstrip("."),
                    parent_line,
                    "missing",
                    f"add '{key}:' (see protocols/knee.yaml)",
                )
            return default
        value = m[key]
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = self.number(value, f"{where}.{key}".lstrip("."), line)  # 10**400: no float
        if not isinstance(value, kind) or (
            isinstance(value, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,))
        ):
            names = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
            if kind is float and (e := e_notation(value)):
                self.fail(f"{where}.{key}".lstrip("."), line, *e)
            self.fail(
                f"{where}.{key}".lstrip("."),
                line,
                f"is {type(value).__name__} {shorten(repr(value))}, expected {names}",
                "fix the value",
            )
        if isinstance(value, float):
            value = self.number(value, f"{where}.{key}".lstrip("."), line)
        return value

    def known(self, m: dict, where: str, allowed: tuple[str, ...]) -> None:
        """Fail on a key of ``m`` that is not ``allowed`` (a typo), with a hint."""
        lines = getattr(m, "lines", {})
        for key in m:
            if key not in allowed:
                place = f"{where}.{key}".lstrip(".")
                self.fail(place, lines.get(key), "unknown key", did_you_mean(key, allowed))

    def names(self, m: dict, where: str) -> None:
        """Fail on a key of ``m`` that is not text (a segment, joint or column name)."""
        lines = getattr(m, "lines", {})
        for key in m:
            if not isinstance(key, str):
                place = f"{where}.{key}".lstrip(".")
                self.fail(place, lines.get(key), f"name {key!r} is not text", "quote it")

    def label(self, value: Any, where: str, line: int | None) -> str:
        """A segment, joint, step or task name: text that can name a group of the session file
        and a CSV file (not empty, no '/' or '\\', not '.' or '..', no control characters)."""
        if not isinstance(value, str):
            self.fail(where, line, f"name {shorten(repr(value))} is not text", "quote it")
        bad = sorted({c for c in value if c in "/\\" or ord(c) < 32 or ord(c) == 127})
        if not value.strip() or value.strip(".") == "" or bad:
            what = f"holds {', '.join(map(repr, bad))}" if bad else "is empty or only dots"
            self.fail(where, line, f"name {shorten(repr(value))} {what}: it names a group of the "
                      "session file and a CSV file", "use letters, digits and '_', e.g. "
                      "knee_r")  # fmt: skip
        problem = text_problem(value, MAX_LABEL_CHARS)
        if problem:
            self.fail(where, line, f"name {shorten(repr(value))} {problem}: it names a group of "
                      "the session file and a CSV file", "shorten it, e.g. knee_r")  # fmt: skip
        return value

    def unique(self, name: str, seen: dict[str, str], where: str, line: int | None) -> None:
        """Fail when ``name`` was given before (at ``seen[name]``): results are kept by name."""
        if name in seen:
            self.fail(f"{where}.name", line, f"name {name!r} is given twice ({seen[name]} too)",
                      "give each its own name")  # fmt: skip
        seen[name] = where

    def repetitions(self, m: dict, where: str) -> int:
        """``repetitions`` of a step or task: a whole number ≥ 0 (0: not counted)."""
        value = self.get(m, "repetitions", where, int, False, 0)
        if not 0 <= value <= MAX_REPETITIONS:
            self.fail(f"{where}.repetitions", getattr(m, "lines", {}).get("repetitions"),
                      f"is {shorten(value)}",
                      f"give a count between 0 and {MAX_REPETITIONS}")  # fmt: skip
        return value

    def duration(self, m: dict, where: str, required: bool = True) -> float:
        """``duration_s`` of a step (required, > 0) or a task (optional, ≥ 0; 0: as long as
        the recording gives), at most :data:`MAX_DURATION_S`."""
        value = self.get(m, "duration_s", where, float, required, 0.0)
        low_ok = value > 0 if required else value >= 0
        if not (low_ok and value <= MAX_DURATION_S):
            low = "above 0 s" if required else "of 0 s or more"
            self.fail(f"{where}.duration_s".lstrip("."), getattr(m, "lines", {}).get("duration_s"),
                      f"is {value:g} s", f"give a duration {low}, at most {MAX_DURATION_S:g} "
                      "s")  # fmt: skip
        return value

    def number(self, value: Any, where: str, line: int | None) -> float:
        """A finite number (not a bool), as a float: an integer too large for a float
        (``10**400``), ``.nan`` and ``.inf`` are refused."""
        x = finite(value)
        if x is None:
            if e := e_notation(value):
                self.fail(where, line, *e)
            if isinstance(value, bool) or not isinstance(value, int | float):
                self.fail(where, line, f"{shorten(repr(value))} is not a number", "give a number")
            self.fail(where, line, f"{shorten(repr(value))} is not a finite number",
                      "give a finite number")  # fmt: skip
        return x

    def numbers(self, values: list, where: str, line: int | None) -> None:
        """Fail on an item of ``values`` that is a number but not a finite one (``.nan``,
        ``10**400``); others are the caller's to judge."""
        for v in values:
            if (isinstance(v, int | float) and not isinstance(v, bool)) or e_notation(v):
                self.number(v, where, line)

    def magnitude(self, value: Any, where: str, line: int | None) -> float:
        """An angle limit (deg) of ``thresholds``: a number from 0 to :data:`MAX_THRESHOLD_DEG`
        (a size: a negative one flagged every sample)."""
        x = self.number(value, where, line)
        if not 0 <= x <= MAX_THRESHOLD_DEG:
            self.fail(where, line, f"is {x:g}: a limit is a size in degrees, not signed",
                      f"give 0 to {MAX_THRESHOLD_DEG:g}, e.g. 3.0")  # fmt: skip
        return x

    def text(
        self,
        m: dict,
        key: str,
        where: str,
        limit: int = MAX_TEXT_CHARS,
        lines: bool = True,
        required: bool = False,
    ) -> str:
        """Free text shown in the report (``title``, ``purpose``, ``placement`` ...): at most
        ``limit`` characters, no control character (a tab or line break where ``lines``)."""
        value = self.get(m, key, where, str, required, "")
        value = value if lines else value.strip()  # a folded one-liner ('title: >') ends in \n
        problem = text_problem(value, limit, lines)
        if problem:
            remedy = "shorten it" if "long" in problem else "remove it"
            self.fail(f"{where}.{key}".lstrip("."), getattr(m, "lines", {}).get(key), problem,
                      remedy if lines else f"{remedy} (one line of text)")  # fmt: skip
        return value

    def axis(self, value: Any, where: str, line: int | None) -> str:
        if not isinstance(value, str) or value.strip().lstrip("+-") not in AXES:
            self.fail(
                where,
                line,
                f"axis {value!r} is not one of x, y, z, -x, -y, -z",
                "write e.g. 'y' or '-z'",
            )
        return value.strip().lstrip("+")

    def side(self, value: Any, where: str, line: int | None) -> str:
        if value is not None and not isinstance(value, str):
            self.fail(where, line, f"side {shorten(repr(value))} is not l or r", "write 'l' or 'r'")
        side = {"left": "l", "right": "r", None: ""}.get(value, value)
        if side not in SIDES:
            self.fail(where, line, f"side {value!r} is not l or r", "write 'l' or 'r'")
        return side


def parse_protocol(path: str | Path) -> tuple[Path, dict]:
    """The protocol file (a path, or the name of a packaged protocol) and its YAML document:
    mappings that know the line of each key (``.lines``), bounded in size and depth
    (:class:`~motionlab.yamlsafe.BoundedSafeLoader`); nothing checked beyond the YAML."""
    path = resolve_protocol_path(path)
    text = read_yaml_text(path, "protocol", "give a protocol YAML file (see protocols/knee.yaml)")
    return path, load_yaml(text, LineLoader, path, "check indentation and colons")


def load_protocol(path: str | Path) -> Protocol:
    """Load and validate a protocol YAML file (a path, or the name of a packaged protocol).

    Parse (:func:`parse_protocol`), then validate and build each part in the file's order
    (top level, segments, calibration steps, joints, tasks, normative ranges, the rest), so
    that the first error in the file is the one reported, naming its key and line."""
    path, doc = parse_protocol(path)
    r = _Reader(path)
    name = _top_level(r, doc)
    segments = _segments(r, doc)
    check_segment = partial(_check_segment, r, segments)
    steps = _steps(r, doc, check_segment)
    joints = _joints(r, doc, check_segment)
    tasks = _tasks(r, doc)
    normative = _normative(r, doc)
    _normative_names(r, doc, normative, tasks, joints)
    return Protocol(
        name=name,
        segments=segments,
        joints=joints,
        calibration=steps,
        tasks=tasks,
        normative={
            t: {c: [float(v) for v in rng] for c, rng in (ranges or {}).items()}
            for t, ranges in normative.items()
        },
        metrics=[
            _metric(r, m, doc.lines.get("metrics"))
            for m in r.get(doc, "metrics", "", list, False, [])
        ],
        thresholds=_thresholds(r, r.get(doc, "thresholds", "", dict, False, {})),
        title=r.text(doc, "title", "", MAX_TITLE_CHARS, lines=False),
        purpose=r.text(doc, "purpose", ""),
        source=r.text(doc, "source", ""),
        angle_lowpass_hz=_angle_lowpass(r, doc),
        path=path,
        raw=_plain(doc),
    )


def _angle_lowpass(r: _Reader, doc: dict) -> float | None:
    """``angle_lowpass_hz``: a cut-off from 0 (the angles as computed) to
    :data:`MAX_ANGLE_LOWPASS_HZ`, or ``None`` when the protocol does not set one."""
    if "angle_lowpass_hz" not in doc:
        return None
    line = doc.lines.get("angle_lowpass_hz")
    x = r.number(doc["angle_lowpass_hz"], "angle_lowpass_hz", line)
    if not 0 <= x <= MAX_ANGLE_LOWPASS_HZ:
        r.fail("angle_lowpass_hz", line, f"is {x:g}: not a cut-off",
               "give a frequency in Hz (e.g. 6), or 0 to keep the angles as computed")  # fmt: skip
    return x


def _top_level(r: _Reader, doc: Any) -> str:
    """Check the document's top level (a mapping of known keys, named parts) and return the
    protocol's name."""
    if not isinstance(doc, dict):
        r.fail("(top level)", 1, "is not a mapping", "start from protocols/knee.yaml")
    r.names(doc, "")
    r.known(doc, "", TOP_KEYS)
    name = r.text(doc, "name", "", MAX_NAME_CHARS, lines=False, required=True)
    if not name.strip():
        r.fail("name", doc.lines.get("name"), "is empty: the report's title names the protocol",
               "give a short name, e.g. knee")  # fmt: skip
    for key in ("segments", "joints", "normative", "thresholds"):
        if isinstance(doc.get(key), dict):
            r.names(doc[key], key)
    return name


def _segments(r: _Reader, doc: dict) -> dict[str, Segment]:
    """The validated ``segments`` (at least one)."""
    segments: dict[str, Segment] = {}
    for seg_name, spec in r.get(doc, "segments", "", dict).items():
        where = f"segments.{seg_name}"
        line = doc["segments"].lines.get(seg_name)
        spec = spec if spec is not None else LineMap()
        if not isinstance(spec, dict):
            r.fail(where, line, "is not a mapping", "give side/placement keys")
        r.label(seg_name, where, line)
        r.known(spec, where, SEGMENT_KEYS)
        axes = r.get(spec, "sensor_axes", where, list, False, ["x", "y", "z"])
        if len(axes) != 3:
            r.fail(f"{where}.sensor_axes", line, "needs three axes", "e.g. [x, y, z]")
        axes = tuple(r.axis(a, f"{where}.sensor_axes", line) for a in axes)
        if abs(np.linalg.det(np.column_stack([axis_vector(a) for a in axes]))) < 0.5:
            r.fail(f"{where}.sensor_axes", line, "axes repeat", "name each axis once")
        if np.linalg.det(np.column_stack([axis_vector(a) for a in axes])) < 0:
            r.fail(f"{where}.sensor_axes", line, "axes are left-handed", "flip the sign of one")
        segments[seg_name] = Segment(
            name=seg_name,
            side=r.side(spec.get("side"), f"{where}.side", line),
            placement=r.text(spec, "placement", where),
            sensor_axes=axes,
            landmarks=[
                _text(r, v, f"{where}.landmarks", line)
                for v in r.get(spec, "landmarks", where, list, False, [])
            ],
            required=r.get(spec, "required", where, bool, False, True),
            any_orientation=r.get(spec, "any_orientation", where, bool, False, False),
        )
    if not segments:
        r.fail("segments", doc.lines.get("segments"), "is empty", "name at least one segment")

    return segments


def _check_segment(
    r: _Reader, segments: dict[str, Segment], seg: Any, where: str, line: int | None
) -> str:
    """``seg`` when it names one of ``segments``, else the error at ``where``."""
    if not isinstance(seg, str) or seg not in segments:
        r.fail(
            where,
            line,
            f"names segment {shorten(repr(seg))}, which is not under segments",
            f"use one of {', '.join(segments)}",
        )
    return seg


def _steps(r: _Reader, doc: dict, check_segment: Callable) -> list[CalibrationStep]:
    """The validated ``calibration`` steps."""
    steps: list[CalibrationStep] = []
    seen: dict[str, str] = {}
    for i, spec in enumerate(r.get(doc, "calibration", "", list, False, [])):
        where = f"calibration[{i}]"
        line = getattr(spec, "lines", {}).get("name", doc.lines.get("calibration"))
        if not isinstance(spec, dict):
            r.fail(where, line, "is not a mapping", "give name/kind keys")
        r.known(spec, where, STEP_KEYS)
        kind = r.get(spec, "kind", where, str)
        if kind not in STEP_KINDS:
            r.fail(
                f"{where}.kind",
                spec.lines["kind"],
                f"unknown step kind {kind!r}",
                "use static or functional",
            )
        vertical = {
            check_segment(s, f"{where}.vertical_axis", line): r.axis(
                a, f"{where}.vertical_axis.{s}", line
            )
            for s, a in r.get(spec, "vertical_axis", where, dict, False, {}).items()
        }
        horizontal = {
            check_segment(s, f"{where}.horizontal_axis", line): r.axis(
                a, f"{where}.horizontal_axis.{s}", line
            )
            for s, a in r.get(spec, "horizontal_axis", where, dict, False, {}).items()
        }
        if horizontal and kind != "static":
            r.fail(f"{where}.horizontal_axis", line, "only a static step has horizontal axes",
                   "move it to a static pose")  # fmt: skip
        axis = {
            check_segment(s, f"{where}.axis", line): r.axis(a, f"{where}.axis.{s}", line)
            for s, a in r.get(spec, "axis", where, dict, False, {}).items()
        }
        if kind == "static" and not vertical:
            r.fail(
                f"{where}.vertical_axis",
                line,
                "a static step needs vertical_axis",
                "name the vertical axis of each segment, e.g. {thigh_r: y}",
            )
        if kind == "functional" and not axis:
            r.fail(
                f"{where}.axis",
                line,
                "a functional step needs axis",
                "name the segment axis the movement defines, e.g. {shank_r: -z}",
            )
        time_range = r.get(spec, "time_range", where, list, False, None)
        r.numbers(time_range or [], f"{where}.time_range", spec.lines.get("time_range", line))
        if time_range is not None and not _is_range(time_range):
            r.fail(
                f"{where}.time_range",
                line,
                "needs [start_s, end_s] with start < end",
                "e.g. [12.0, 20.5]",
            )
        axis_method = r.get(spec, "axis_method", where, str, False, "svd")
        if axis_method not in AXIS_METHODS:
            r.fail(
                f"{where}.axis_method",
                spec.lines.get("axis_method"),
                f"unknown axis method {axis_method!r}",
                f"use one of {', '.join(AXIS_METHODS)}",
            )
        rho = r.get(spec, "reference_rho", where, dict, False, {})
        rho_lines = getattr(rho, "lines", {})
        steps.append(
            CalibrationStep(
                name=r.label(r.get(spec, "name", where, str), f"{where}.name", line),
                kind=kind,
                duration_s=r.duration(spec, where),
                instructions=r.text(spec, "instructions", where),
                pose=r.text(spec, "pose", where),
                vertical_axis=vertical,
                horizontal_axis=horizontal,
                segments=[
                    check_segment(s, f"{where}.segments", line)
                    for s in r.get(spec, "segments", where, list, False, list(axis))
                ],
                axis=axis,
                repetitions=r.repetitions(spec, where),
                time_range=tuple(float(t) for t in time_range) if time_range else None,
                optional=r.get(spec, "optional", where, bool, False, False),
                reference_rho={
                    check_segment(s, f"{where}.reference_rho", line): r.number(
                        v, f"{where}.reference_rho.{s}", rho_lines.get(s, line)
                    )
                    for s, v in rho.items()
                },
                axis_method=axis_method,
            )
        )
        r.unique(steps[-1].name, seen, where, line)

    return steps


def _joints(r: _Reader, doc: dict, check_segment: Callable) -> dict[str, Joint]:
    """The validated ``joints``; two joints giving one angle column are an error."""
    joints = {}
    owners: dict[str, tuple[str, int | None]] = {}  # column → (joint key, line)
    for jname, spec in r.get(doc, "joints", "", dict).items():
        where = f"joints.{jname}"
        line = doc["joints"].lines.get(jname)
        if not isinstance(spec, dict):
            r.fail(where, line, "is not a mapping", "give type/proximal/distal keys")
        r.label(jname, where, line)
        r.known(spec, where, JOINT_KEYS)
        joints[jname] = _joint(r, jname, spec, line, check_segment)
        for _, col in angle_columns(joints[jname]):
            if col in owners:
                other, other_line = owners[col]
                r.fail(
                    where,
                    line,
                    f"gives column {col}, as joint {other} (line {other_line}) does",
                    "give the two joints different sides, or use a generic type (hinge, ball) "
                    "whose columns carry the joint's name",
                )
            owners[col] = (where, line)

    return joints


def _tasks(r: _Reader, doc: dict) -> list[Task]:
    """The validated ``tasks``."""
    tasks: list[Task] = []
    seen: dict[str, str] = {}
    for i, spec in enumerate(r.get(doc, "tasks", "", list, False, [])):
        where = f"tasks[{i}]"
        if not isinstance(spec, dict):
            r.fail(where, doc.lines.get("tasks"), "is not a mapping", "give name/kind keys")
        r.known(spec, where, TASK_KEYS)
        line = spec.lines.get("name", doc.lines.get("tasks"))
        known = {"name", "kind", "duration_s", "repetitions", "time_range"}
        r.text(spec, "instructions", where)
        time_range = r.get(spec, "time_range", where, list, False, None)
        r.numbers(time_range or [], f"{where}.time_range", spec.lines.get("time_range", line))
        if time_range is not None and not _is_range(time_range):
            r.fail(
                f"{where}.time_range",
                spec.lines.get("time_range"),
                "needs [start_s, end_s] with start < end",
                "e.g. [95.0, 150.0]",
            )
        tasks.append(
            Task(
                name=r.label(r.get(spec, "name", where, str), f"{where}.name", line),
                kind=r.get(spec, "kind", where, str),
                duration_s=r.duration(spec, where, required=False),
                repetitions=r.repetitions(spec, where),
                time_range=tuple(float(t) for t in time_range) if time_range else None,
                options={k: v for k, v in spec.items() if k not in known},
            )
        )
        r.unique(tasks[-1].name, seen, where, line)

    return tasks


def _normative(r: _Reader, doc: dict) -> dict:
    """The ``normative`` ranges as the file gives them (checked: ``column: [low, high]``)."""
    normative = r.get(doc, "normative", "", dict, False, {})
    for task, ranges in normative.items():
        if ranges is not None and not isinstance(ranges, dict):
            r.fail(f"normative.{task}", doc["normative"].lines.get(task), "is not a mapping",
                   "give 'column: [low, high]' lines, e.g. knee_flexion_deg: [0, 65]")  # fmt: skip
        r.names(ranges or {}, f"normative.{task}")
        for col, rng in (ranges or {}).items():
            if isinstance(rng, list):
                r.numbers(rng, f"normative.{task}.{col}", getattr(ranges, "lines", {}).get(col))
            if not (isinstance(rng, list) and len(rng) == 2 and _is_range(rng, strict=False)):
                r.fail(
                    f"normative.{task}.{col}",
                    getattr(ranges, "lines", {}).get(col),
                    f"range {shorten(repr(rng))} is not [low, high]",
                    "e.g. [0, 65]",
                )
    return normative


def _normative_names(
    r: _Reader, doc: dict, normative: dict, tasks: list[Task], joints: dict[str, Joint]
) -> None:
    """Each normal range names a task and an angle column of the protocol (a column with or
    without its side, as :func:`motionlab.report.model.normal_range` looks it up): a typo
    (``giat``) would leave the task without normal ranges and say nothing."""
    names = [t.name for t in tasks] + list(NORMATIVE_NOT_A_TASK)
    columns = {c for j in joints.values() for _, c in angle_columns(j)}
    columns |= {c.replace("_r_", "_").replace("_l_", "_") for c in columns}
    for task, ranges in normative.items():
        line = doc["normative"].lines.get(task)
        if task not in names:
            r.fail(f"normative.{task}", line, "names no task of the protocol",
                   did_you_mean(task, names) if names else "add the task under tasks")  # fmt: skip
        for col in ranges or {}:
            if col not in columns:
                r.fail(f"normative.{task}.{col}", getattr(ranges, "lines", {}).get(col),
                       "names no angle column of the protocol's joints",
                       did_you_mean(col, sorted(columns)))  # fmt: skip


def _joint(r: _Reader, jname: str, spec: Any, line: int | None, check_segment) -> Joint:
    """One validated joint of the protocol's ``joints`` (see the module docstring)."""
    where = f"joints.{jname}"
    lines = getattr(spec, "lines", {})
    jtype = r.get(spec, "type", where, str)
    if jtype not in JOINT_TYPES:
        r.fail(
            f"{where}.type",
            lines.get("type"),
            f"unknown joint type {jtype!r}",
            f"use one of {', '.join(JOINT_TYPES)}",
        )
    jt = joint_type(jtype)
    proximal = check_segment(
        r.get(spec, "proximal", where, str), f"{where}.proximal", lines.get("proximal")
    )
    distal = check_segment(
        r.get(spec, "distal", where, str), f"{where}.distal", lines.get("distal")
    )
    if proximal == distal:
        r.fail(
            f"{where}.distal",
            lines.get("distal"),
            f"is the proximal segment {proximal!r} too",
            "a joint joins two different segments",
        )
    side = r.side(spec.get("side"), f"{where}.side", lines.get("side", line))
    if jt.sided and not side:
        r.fail(f"{where}.side", line, f"a {jtype} joint needs a side", "add side: l or side: r")
    axis = None
    if "axis" in spec:
        axis = r.axis(spec["axis"], f"{where}.axis", lines.get("axis"))
    sequence = r.get(spec, "sequence", where, str, False, "").strip()
    if jt.sequence_rule == "axis" and axis is None:
        r.fail(f"{where}.axis", line, f"a {jtype} joint needs axis", "add e.g. axis: z")
    if axis is not None and jt.sequence_rule != "axis":
        r.fail(f"{where}.axis", lines.get("axis"), f"a {jtype} joint takes no axis",
               "remove it (only a hinge joint has its own axis)")  # fmt: skip
    problem = sequence_problem(jtype, sequence or None, axis)
    if problem:
        r.fail(
            f"{where}.sequence",
            lines.get("sequence", line),
            problem,
            "write an upper-case intrinsic sequence such as ZXY, or leave sequence out",
        )
    return Joint(
        name=jname,
        type=jtype,
        proximal=proximal,
        distal=distal,
        side=side,
        sequence=resolve_sequence(jtype, sequence or None, axis),
        axis=axis,
    )


def _text(r: _Reader, value: Any, where: str, line: int | None) -> str:
    """An item of a list of names: text."""
    if not isinstance(value, str):
        r.fail(where, line, f"item {shorten(repr(value))} is not text", "quote it")
    return value


def _metric(r: _Reader, value: Any, line: int | None) -> str:
    """An item of ``metrics``: one of :data:`METRICS` (a misspelt one switched its metric off
    without a word)."""
    name = _text(r, value, "metrics", line)
    if name not in METRICS:
        r.fail("metrics", line, f"unknown metric {name!r}", did_you_mean(name, METRICS))
    return name


def _thresholds(r: _Reader, m: dict) -> dict[str, Any]:
    """``thresholds``: the known keys (:data:`THRESHOLD_KEYS`; a misspelt one left its metric
    at the default without a word), each angle limit a magnitude (:meth:`_Reader.magnitude`),
    the trunk's one per angle (:data:`TRUNK_ANGLES`)."""
    r.known(m, "thresholds", THRESHOLD_KEYS)
    out: dict[str, Any] = {}
    for key, value in m.items():
        where, line = f"thresholds.{key}", getattr(m, "lines", {}).get(key)
        if key == "trunk_compensation_deg":
            if not isinstance(value, dict):
                r.fail(where, line, f"is {type(value).__name__} {shorten(repr(value))}, expected "
                       "a limit per trunk angle", "e.g. {flexion: 10.0, lateral_bending: 8.0, "
                       "axial_rotation: 10.0}")  # fmt: skip
            r.names(value, where)
            r.known(value, where, TRUNK_ANGLES)
            lines = getattr(value, "lines", {})
            out[key] = {
                angle: r.magnitude(v, f"{where}.{angle}", lines.get(angle, line))
                for angle, v in value.items()
            }
        elif key.endswith("_deg"):
            out[key] = r.magnitude(value, where, line)
        else:
            out[key] = _numbers(r, value, where, line)
    return out


def _numbers(r: _Reader, value: Any, where: str, line: int | None) -> Any:
    """A number, a list of numbers or a mapping of them (keys text), each finite."""
    if isinstance(value, dict):
        r.names(value, where)
        lines = getattr(value, "lines", {})
        return {k: _numbers(r, v, f"{where}.{k}", lines.get(k, line)) for k, v in value.items()}
    if isinstance(value, list):
        return [r.number(v, where, line) for v in value]
    return r.number(value, where, line)


def _is_range(value: list, strict: bool = True) -> bool:
    """``[start, end]``: two finite numbers with start < end (``strict``) or start ≤ end."""
    numbers = all(finite(v) is not None for v in value)
    if not (len(value) == 2 and numbers):
        return False
    return value[0] < value[1] if strict else value[0] <= value[1]


def packaged_copy(path: str | Path) -> Path | None:
    """The installed copy of a file in the repository's ``protocols/`` folder, for a relative path
    into it that does not exist here (``protocols/examples/trunk_map.yaml``, as the help's
    examples write it, given outside the repository); else ``None``."""
    p = Path(path)
    if p.is_absolute() or p.exists() or p.is_symlink() or p.parts[:1] != ("protocols",):
        return None
    copy = PACKAGED.joinpath(*p.parts[1:])
    return copy if copy.is_file() else None


def resolve_protocol_path(path: str | Path) -> Path:
    """A path as given, or the packaged protocol of that name (``knee`` → protocols/knee.yaml),
    or the installed copy of a path into the repository's ``protocols/`` (:func:`packaged_copy`).

    A file of the name comes first; a folder (or anything not a regular file) of a packaged
    protocol's name in the working folder, such as the output folder of an earlier ``run``
    called ``knee``, does not hide the packaged protocol."""
    p = Path(path)
    check_name_length(p)  # is_file() raises on a name the file system cannot hold
    if p.is_file():
        return p
    if (copy := packaged_copy(p)) is not None:
        return copy
    packaged = PACKAGED / f"{p.stem}.yaml"
    if p.suffix in ("", ".yaml") and packaged.is_file() and not p.parent.parts[1:]:
        return packaged
    check_regular(p, what="a protocol")  # a FIFO or device given as one: said so, never opened
    if p.is_symlink() and not p.exists():  # a link to nowhere, or to itself (a loop)
        raise InputError("is a symbolic link that leads nowhere (or back to itself)", p,
                         remedy="give the protocol file's own path")  # fmt: skip
    raise InputError(
        "no such protocol file", p, remedy=f"give a path or one of {', '.join(list_protocols())}"
    )


def list_protocols() -> list[str]:
    """Names of the protocols shipped with motionlab."""
    return sorted(p.stem for p in PACKAGED.glob("*.yaml"))


def _plain(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    return obj
