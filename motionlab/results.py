"""Typed stage results: what each analysis stage stores in a session, one dataclass per stage.

``session.results`` is a :class:`Results`: one attribute per stage, ``None`` (or an empty
``fusion``) until the stage has run. Read a stage's result by attribute and store it the same
way; the session file's ``/results/<stage>/`` group is written by :meth:`Results.to_tree` and
read by :meth:`Results.from_tree`, and no other code names the tree's keys::

    cal = session.results.calibration           # SegmentCalibration | None
    q = session.results.fusion["shank_r"].quat   # FusionEntry per sensor label
    session.results.angles = AngleTable(...)

=================  =============================  ===============================================
attribute          type                           stage (command)
=================  =============================  ===============================================
``clock_sync``     :class:`ClockSync`             IMU-to-IMU clock fits (``motionlab sync``)
``fusion``         ``{label: FusionEntry}``       orientation per sensor (``motionlab fuse``)
``calibration``    :class:`SegmentCalibration`    sensor-to-segment calibration (``calibrate``)
``angles``         :class:`AngleTable`            joint angle table (``motionlab angles``)
``heading``        ``{joint: HeadingCorrection}`` heading alignment per joint (``angles``)
``metrics``        :class:`Metrics`               metrics per task and joint (``metrics``)
``gait``           :class:`Gait`                  gait analysis (``metrics``, gait tasks)
``validation``     :class:`Validation`            agreement with optical (``motionlab validate``)
=================  =============================  ===============================================

Each class's ``to_tree()`` gives the tree the session file stores (dicts become HDF5 groups,
arrays datasets, other values JSON attributes; ``None`` fields are left out) and ``from_tree``
reads it back; keys a class does not know (written by a newer motionlab) are kept in ``more``
so that a round trip loses nothing. Units are SI except where a name says otherwise
(``*_deg``: degrees, ``*_s``: seconds, ``*_ppm``, ``*_pct``).

Maps keyed by the protocol's names (one entry per segment, joint, task or angle column) are
dictionaries; where their entries have fixed fields these are typed too (:class:`SegmentRecord`
with its :class:`SegmentQuality`, :class:`HingeFit`, :class:`JointGrades`,
:class:`CentreHeading`, :class:`HeadingTies`, :class:`AxisMeasurement`, :class:`AngleMetrics`,
:class:`StanceMetrics`, :class:`OutOfPlaneOffset`, :class:`TrunkCompensation`,
:class:`CrossTalk`, :class:`GaitEvents`, :class:`StrideStats`, a validation's
:class:`OpticalSegmentInfo`, :class:`SensorOrientationError` and :class:`AngleAgreement`), else
their keys are documented at the attribute.
"""

from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "STAGES",
    "AngleTable",
    "SegmentCalibration",
    "SegmentQuality",
    "SegmentRecord",
    "AxisMeasurement",
    "HingeFit",
    "HipAxis",
    "CentreHeading",
    "HeadingTie",
    "HeadingTies",
    "JointGrades",
    "TrunkMovement",
    "TwoAxisFit",
    "ClockFit",
    "ClockSync",
    "FusionEntry",
    "AppliedCalibration",
    "ChannelCalibration",
    "MarkerFusion",
    "LabToEarth",
    "Gait",
    "GaitSummary",
    "GaitEvents",
    "GaitPelvis",
    "StrideStats",
    "StrideTable",
    "StanceMetrics",
    "OutOfPlaneOffset",
    "TrunkAngleStats",
    "TrunkCompensation",
    "OffAxisRange",
    "CrossTalk",
    "MovementProfile",
    "HeadingCorrection",
    "Metrics",
    "AngleMetrics",
    "TaskBlock",
    "Results",
    "OpticalSync",
    "AlignmentRotation",
    "SpatialAlignment",
    "OpticalSegmentInfo",
    "SensorOrientationError",
    "OrientationErrors",
    "RepetitionAgreement",
    "AngleAgreement",
    "AngleAgreements",
    "ValidationReference",
    "Validation",
    "column_unit",
]


class _Record:
    """``to_tree`` / ``from_tree`` for a dataclass whose fields are its tree's keys.

    ``None`` fields are not stored; unknown keys of a tree go to ``more`` (when the class has
    that field) and come back out in ``to_tree``; the fields named in ``_nested`` hold records
    (or maps of them) stored as subtrees.
    """

    #: field name → its key in the file, where the two differ (the layout predates the name)
    _keys: ClassVar[dict[str, str]] = {}
    #: whether ``None`` fields are stored too (as JSON ``null``: the layout predates the class)
    _store_none: ClassVar[bool] = False
    #: fields stored even when ``None`` (the layout predates the class and always had them)
    _stored_when_none: ClassVar[frozenset[str]] = frozenset()
    #: field → (the record class stored under it, the levels of name-keyed maps holding the
    #: records: 0 one record, 1 ``{name: record}``, 2 ``{name: {name: record}}``)
    _nested: ClassVar[dict[str, tuple[Any, int]]] = {}

    def to_tree(self) -> dict[str, Any]:
        """The tree stored under the stage's group in the session file."""
        tree: dict[str, Any] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if f.name == "more":
                tree.update(value)
            elif value is not None or self._store_none or f.name in self._stored_when_none:
                if value is not None and f.name in self._nested:
                    value = _tree(value, self._nested[f.name][1])
                tree[self._keys.get(f.name, f.name)] = value
        return tree

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> Any:
        """The record of a stored tree (see :meth:`to_tree`)."""
        fields = dataclasses.fields(cls)  # type: ignore[arg-type]
        field_of = {cls._keys.get(f.name, f.name): f.name for f in fields}
        known = {field_of[k]: v for k, v in tree.items() if k in field_of and k != "more"}
        rest = {k: v for k, v in tree.items() if k not in field_of}
        if "more" in field_of:
            known["more"] = rest
        for name, (record, depth) in cls._nested.items():
            if known.get(name) is not None:
                known[name] = _map(known[name], record.from_tree, depth)
        return cls(**known)


# ------------------------------------------------------------------------------ clock sync


@dataclass(frozen=True)
class ClockFit:
    """Clock of ``sensor`` relative to ``reference``: it reads ``t + offset_s + drift (t −
    t_mid_s)`` at the reference's time ``t`` (``offset_s`` s, ``drift`` s/s about ``t_mid_s``
    s); standard errors ``offset_se_s`` (s) and ``drift_se``; ``status``: ``applied``,
    ``consistent with one clock``, or why not (``not reliable: ...``, ``not enough shared
    movement``). ``method`` says which signal timed the pair (:mod:`motionlab.clocksync`):
    ``joint centre`` (``residual``: RMS residual of the joint-centre acceleration magnitudes,
    m/s², over ``moving_s`` seconds of shared movement) or ``impacts`` (the heel-strike
    transients; ``residual``: 1 − the correlation coefficient of the two envelopes, ``moving_s``
    the seconds of transients) or ``network`` (every sensor's clock solved at once against the
    root sensor from all pairwise measurements, :mod:`motionlab.clocknet`; ``residual`` NaN,
    ``moving_s`` 0); ``other``: one line on the other method's answer for the pair (empty when
    it was not tried), or for ``network`` what timed the sensor, what was set aside and what
    disagrees. Files written before ``method`` existed read as ``joint centre``."""

    reference: str
    sensor: str
    offset_s: float
    drift: float
    t_mid_s: float
    offset_se_s: float
    drift_se: float
    residual: float
    moving_s: float
    status: str  # "applied", "consistent with one clock", "not enough shared movement", ...
    method: str = "joint centre"  # or "impacts" (heel-strike transients)
    other: str = ""

    @property
    def timed(self) -> bool:
        """Whether the sync timed this sensor (:data:`RELIABLE`) or kept the vendor's
        synchronisation (:data:`VENDOR_KEPT`); a part's root :data:`NOT_LINKED` is not."""
        return self.status in RELIABLE or self.status.startswith(VENDOR_KEPT)

    def error_s(self, t: np.ndarray) -> np.ndarray:
        """c(t) (s) at reference times ``t``."""
        return self.offset_s + self.drift * (np.asarray(t, float) - self.t_mid_s)

    def corrected_time(self, t: np.ndarray) -> np.ndarray:
        """The sensor's own stamps ``t`` (s) on the reference clock."""
        return (np.asarray(t, float) - self.offset_s + self.drift * self.t_mid_s) / (
            1.0 + self.drift
        )

    def recorded_time(self, t: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`corrected_time`: the sensor's own stamps (s)."""
        drift = self.drift
        return np.asarray(t, float) * (1.0 + drift) + self.offset_s - drift * self.t_mid_s

    def to_tree(self) -> dict[str, Any]:
        """The fit's fields (stored as attributes of ``/results/clock_sync/<sensor>``)."""
        return asdict(self)

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> ClockFit:
        """The fit of a stored tree."""
        return cls(**tree)


#: the status of the fit of a part of the body's root sensor whose clock nothing tied to the
#: root sensor's (no sensor joins the parts, no reliable heel-strike lag across them):
#: ``not linked: <why>``; the part's own sensors are timed against that root
NOT_LINKED = "not linked"
#: the statuses of a fit that timed its pair (applied, or found the two on one clock already)
RELIABLE = ("applied", "consistent with one clock")
#: the status of a fit not applied because the vendor synchronised the sensors' clocks
VENDOR_KEPT = "not applied: the vendor synchronised these clocks"


@dataclass
class ClockSync:
    """The clock sync stage: ``fits`` ``{sensor label: ClockFit}`` in the order they were
    made (each against its reference's corrected clock)."""

    fits: dict[str, ClockFit] = field(default_factory=dict)

    def _chain(self, label: str) -> tuple[list[ClockFit], str]:
        """The fits from ``label`` along its references, and the sensor whose clock they end on:
        the root sensor, or a part's root whose fit is :data:`NOT_LINKED` (a sensor without a
        fit is on its own clock)."""
        seen, chain = {label}, []
        fit = self.fits.get(label)
        while fit is not None and not fit.status.startswith(NOT_LINKED):
            chain.append(fit)
            label = fit.reference
            if label in seen:  # no cycle in a stored result; stop rather than loop
                break
            seen.add(label)
            fit = self.fits.get(label)
        return chain, label

    def clock_of(self, label: str) -> str:
        """The sensor whose clock ``label``'s stamps are on after the sync: its references
        followed up to the root sensor, or to a part's root whose fit is :data:`NOT_LINKED`
        (a sensor without a fit is on its own clock)."""
        return self._chain(label)[1]

    def untimed(self, labels: list[str]) -> ClockFit | None:
        """The fit of the first sensor between ``labels`` whose clock the sync could not time
        (not :attr:`ClockFit.timed`: its stamps taken as recorded against its reference's), or
        ``None``.
        Between: on the way from each label up to the first sensor all their ways pass (a
        knee's shank timed against its thigh is timed for the knee, whatever the thigh's own
        fit), or the root of a part not linked to the others' clock (:meth:`untimed_way`).
        Such sensors are on one clock only as well as the recording kept them together: a
        simulated walk's shanks read 117 ms apart (43 % step-time asymmetry for a symmetric
        walker), its left knee 52 ms from its thigh (10° more flexion in swing)."""
        found = self.untimed_way(labels)
        return found[0] if found else None

    def untimed_way(self, labels: list[str]) -> tuple[ClockFit, list[str]] | None:
        """:meth:`untimed`'s fit and the labels on whose way to the others an untimed fit
        lies: the sensors whose stamps may be off against the others' (``None`` when all are
        timed). Labels whose ways end on different clocks (a part of the body the sync did not
        link to the root's, :data:`NOT_LINKED`: a walk whose legs the heel strikes timed
        against each other and nothing against the pelvis) were never compared: the fit is
        that part's root's, the labels those on its clock."""
        ends = {lab: self._chain(lab)[1] for lab in labels}
        apart = [lab for lab, end in ends.items() if end in self.fits]
        if len(set(ends.values())) > 1 and apart:
            return self.fits[ends[apart[0]]], apart
        chains = {lab: self._chain(lab)[0] for lab in labels}
        ways = [{lab, *(f.reference for f in chain)} for lab, chain in chains.items()]
        shared = set.intersection(*ways) if ways else set()
        found: dict[str, ClockFit] = {}
        for lab, chain in chains.items():
            for fit in chain:
                if fit.sensor in shared:
                    break
                if not fit.timed:
                    found[lab] = fit
                    break
        return (next(iter(found.values())), list(found)) if found else None

    def not_linked(self, labels: list[str]) -> str:
        """Why the sensors ``labels`` are not all on one clock after the sync (``thigh_l: no
        sensor joins it to ...``: the first part's root that no measurement tied to the
        others'), or empty."""
        clocks = sorted({self.clock_of(lab) for lab in labels})
        if len(clocks) < 2:
            return ""
        why = [f"{c}: {self.fits[c].status.removeprefix(NOT_LINKED + ': ')}" for c in clocks
               if c in self.fits]  # fmt: skip
        return why[0] if why else f"{', '.join(clocks)} keep their own clocks, never compared"

    def to_tree(self) -> dict[str, Any]:
        """``{sensor: fit tree}``."""
        return {k: f.to_tree() for k, f in self.fits.items()}

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> ClockSync:
        """The fits of a stored tree."""
        return cls({k: ClockFit.from_tree(v) for k, v in tree.items()})


# ---------------------------------------------------------------------------------- fusion


@dataclass(frozen=True)
class ChannelCalibration(_Record):
    """How one channel of a sensor was calibrated (:mod:`motionlab.sensorcal`): ``method``
    (the calibration method's name) and ``date`` (when the calibration was recorded, ISO
    8601)."""

    method: str
    date: str
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class AppliedCalibration(_Record):
    """The per-serial sensor calibration applied at fuse (:func:`motionlab.sensorcal.calfile.
    apply_calibration`, ``motionlab sensorcal``): the device's ``serial``, the calibration of
    each channel it corrected (``channels``: ``{acc | gyr | mag: ChannelCalibration}``) and the
    file it came from (``source``)."""

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {"channels": (ChannelCalibration, 1)}

    serial: str
    channels: dict[str, ChannelCalibration]
    source: str
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class LabToEarth(_Record):
    """The optical lab's rotation to the ENU earth frame, found from gravity and the magnetic
    field seen in the lab (:func:`motionlab.fusion.marker_registration.lab_to_earth`).

    ``quat`` (4,): lab → earth, scalar first; ``vertical_axis``: the lab axis the vertical was
    snapped to (``+z`` …; ``None``: none within the snap angle, always stored);
    ``vertical_lab`` (3,): the lab's up direction, unit; ``heading_from``: ``magnetometer`` or
    ``lab axes (no magnetometer)``; with the magnetometer ``field_fraction_used`` (0-1: the
    samples that agreed with the fitted field), ``field_uT`` (its norm, µT) and ``dip_deg``
    (its inclination below the horizontal, deg).
    """

    _stored_when_none: ClassVar[frozenset[str]] = frozenset({"vertical_axis"})

    quat: np.ndarray
    vertical_axis: str | None
    vertical_lab: np.ndarray
    heading_from: str
    field_fraction_used: float | None = None
    field_uT: float | None = None
    dip_deg: float | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class MarkerFusion(_Record):
    """What the marker cluster fused with a sensor gave (:func:`motionlab.fusion.
    marker_registration.session_references`): the ``segment`` the cluster is on, the sensor's
    clock against the optical one (``time_offset_s`` s, ``drift_ppm``), ``sensor_to_cluster``
    (4,) the sensor → cluster rotation (scalar first), ``gyro_bias_rad_s`` (3,) rad/s, the
    registration's RMS residual ``registration_residual_deg`` (deg), the markers' noise
    ``marker_noise_mm`` (mm), ``n_pairs`` (marker pairs giving directions), the share of the
    sensor's samples with the cluster seen ``visible_fraction`` (0-1) and the lab's rotation
    to the earth ``lab_to_earth`` (one for the session, repeated per sensor).
    """

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {"lab_to_earth": (LabToEarth, 0)}

    segment: str
    time_offset_s: float
    drift_ppm: float
    sensor_to_cluster: np.ndarray
    gyro_bias_rad_s: np.ndarray
    registration_residual_deg: float
    marker_noise_mm: float
    n_pairs: int
    visible_fraction: float
    lab_to_earth: LabToEarth
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class FusionEntry(_Record):
    """One sensor's orientation from the fusion stage (or the vendor's own).

    ``name``: estimator (``vendor``: the device's orientation); ``quat`` (N, 4) sensor → ENU
    earth, scalar first, on the sensor's own time stamps; ``params``: estimator parameters (SI);
    ``magnetometer``: 9-D (one earth heading shared by the sensors) or 6-D. What the estimator
    reports besides, when it does: ``gyro_bias`` (N, 3) rad/s, ``acc_bias`` (N, 3) m/s² in the
    sensor frame (what the segment calibration takes off the recorded accelerometer, its gravity
    directions being ``acc − acc_bias``: the default smoother's bias states at the calibration's
    wider prior, :func:`motionlab.fusion.stage.calibration_acc_bias`, plus the correction of a
    sensor calibration applied at fuse; none when there is neither; files written before it
    existed hold none), ``rest`` (N,) bool,
    ``mag_disturbed`` (N,) bool, marker ``scenario``, ``gaps_bridged_s`` (packet-loss gaps it
    ran across, s), ``nan_bridged_s`` (runs of non-finite samples held over, ``[start, end]``
    s each), ``gaps_missed_deg`` (per gap, bridged here or filled at ingest, ``[s after it,
    deg]``: the turn its bridge may have missed, :func:`motionlab.fusion.timegrid.gap_noise`).
    ``sensor_calibration``: the per-serial sensor calibration applied (an
    :class:`AppliedCalibration`; key ``calibration`` in the file); ``markers``: what the marker
    cluster fused with it gave (a :class:`MarkerFusion`).
    """

    _keys: ClassVar[dict[str, str]] = {"sensor_calibration": "calibration"}
    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "sensor_calibration": (AppliedCalibration, 0),
        "markers": (MarkerFusion, 0),
    }

    name: str
    quat: np.ndarray
    params: dict[str, float | int | bool | str] | None = None
    magnetometer: bool = True
    scenario: np.ndarray | None = None
    gaps_bridged_s: np.ndarray | list[list[float]] | None = None
    nan_bridged_s: np.ndarray | list[list[float]] | None = None
    gaps_missed_deg: np.ndarray | list[list[float]] | None = None
    gyro_bias: np.ndarray | None = None
    rest: np.ndarray | None = None
    mag_disturbed: np.ndarray | None = None
    acc_bias: np.ndarray | None = None
    sensor_calibration: AppliedCalibration | None = None
    markers: MarkerFusion | None = None
    more: dict[str, Any] = field(default_factory=dict)


# ----------------------------------------------------------------------------- calibration


@dataclass(frozen=True)
class SegmentQuality(_Record):
    """Calibration quality of one segment (:func:`motionlab.segments.quality.assess`).

    ``ok``: no check failed; ``messages``: one plain instruction per failed check (repeat a
    step, check the placement); ``min_rho``: the smallest reliability ρ of its axes (Ricci 2015
    eq. 6.2; NaN without axes); ``separation_deg``: the smallest angle (deg) between two segment
    axes fitted together (``None`` with one axis); ``lm_difference_deg``: how far (deg) Ricci's
    LM fit lies from the closed-form one (``None`` with one axis); ``hinge_check_deg`` ``{step:
    deg}``: the angle between a flexion step's SVD axis and Seel's hinge axis.
    """

    _store_none: ClassVar[bool] = True

    ok: bool
    messages: list[str] = field(default_factory=list)
    min_rho: float = float("nan")
    separation_deg: float | None = None
    lm_difference_deg: float | None = None
    hinge_check_deg: dict[str, float] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class AxisMeasurement(_Record):
    """One axis of a segment measured by a calibration step (one value of
    :attr:`SegmentRecord.axes`; :func:`motionlab.segments.mounting.measure`, the movement's hinge
    fits, the walk's forward direction, a trunk calibration).

    ``step``: the step (or ``movement:<joint>``, ``movement:turns``); ``kind``: ``static``,
    ``functional`` or ``movement`` (found in the recording's movement, not a protocol step);
    ``method``: ``gravity``, ``horizontal`` (an axis the pose lays level), ``svd`` (the principal
    axis of the rate), ``hinge`` (Seel's hinge fit), ``principal`` (the trunk's flexion axis),
    ``turns``, ``walk start`` or ``walk end`` (the pelvis's forward direction from the walk's
    turns, its first steps or its last steps before a stand that ends it); ``sensor_axis``
    (3,): the unit axis measured, in sensor coordinates; ``segment_axis`` (3,): the segment axis
    it is, in segment coordinates; ``rho``: its reliability ρ (0-1, Ricci 2015 eq. 6.2);
    ``reference_rho``: the protocol's reference ρ for the step (``None``: none given; always
    stored);
    ``joint_movement``: the step moves the joint (an axis a still-joint step also measured is
    left out of the fit); ``secondary``: the axis only turns the frame about a primary axis
    (``primary_secondary``); ``hinge_check_deg``: the angle (deg) between the step's SVD axis and
    Seel's hinge axis, ``hinge_residual_rad_s`` that fit's RMS residual (rad/s); ``used``: the
    mounting fit used it (``None``: the fit did not decide, as for a ``horizontal`` axis);
    ``residual_deg``: its angle (deg) to the fitted frame; ``verdict``: ``determined``, ``weak``
    or ``not determined`` for an axis found in the movement; ``turns`` and ``spread_deg``: the
    walk's turns the pelvis's forward direction came from and how far (deg) they disagreed
    (0 and NaN for its first steps).
    """

    _stored_when_none: ClassVar[frozenset[str]] = frozenset({"reference_rho"})

    step: str
    kind: str
    method: str
    sensor_axis: np.ndarray
    segment_axis: np.ndarray
    rho: float
    reference_rho: float | None = None
    joint_movement: bool = False
    secondary: bool = False
    hinge_check_deg: float | None = None
    hinge_residual_rad_s: float | None = None
    used: bool | None = None
    residual_deg: float | None = None
    verdict: str | None = None
    turns: int | None = None
    spread_deg: float | None = None
    more: dict[str, Any] = field(default_factory=dict)

    @property
    def in_fit(self) -> bool:
        """Whether the axis counts (``used`` is not ``False``)."""
        return self.used is not False


@dataclass(frozen=True)
class SegmentRecord(_Record):
    """How one sensor sits on its segment (one value of :attr:`SegmentCalibration.segments`).

    ``mounting`` (4,): the segment → sensor quaternion, scalar first (the segment's orientation
    is ``q_sensor ⊗ mounting``); ``method``: how the frame was fitted (``procrustes``: two or
    more axes, ``primary_secondary``: one axis turned by a secondary, ``single_axis``,
    ``nominal``: the protocol's placement hint alone); ``axes`` ``{step: AxisMeasurement}``:
    the measured axes; ``quality``: its :class:`SegmentQuality`
    (``None`` in a file written without one); ``sensor``: the sensor's label;
    ``hint_contradicted``: the data put a measured axis more than 60° from the placement hint
    (what was not measured is unknown; ``None``: not checked, as in a trunk calibration);
    ``unsigned_steps``: the steps whose axis (measured without a sign) still points the way the
    contradicted hint says, for want of a signed axis of the data to turn it by
    (:func:`motionlab.segments.placement.orient_by_data`): the frame may be half a turn off
    (``None``: none, or a file written before it was kept).
    """

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "axes": (AxisMeasurement, 1),
        "quality": (SegmentQuality, 0),
    }

    mounting: np.ndarray
    method: str
    axes: dict[str, AxisMeasurement] = field(default_factory=dict)
    quality: SegmentQuality | None = None
    sensor: str | None = None
    hint_contradicted: bool | None = None
    unsigned_steps: list[str] | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class HingeFit:
    """Hinge axis of one joint from movement, in the two sensors' coordinates
    (:func:`motionlab.segments.movement.fit_hinge`; one value of
    :attr:`SegmentCalibration.hinges`).

    ``joint``: its name; ``axis_proximal`` / ``axis_distal`` are unit vectors (3,) pointing along
    the positive (flexion) direction of the joint angle; ``residual_rad_s``: RMS residual of the
    hinge constraint (rad/s), ``relative_residual`` that over the RMS perpendicular rate;
    ``consistency_deg``: the largest angle (deg) between the axes of the movement's parts;
    ``relative_sign``: how the axes' relative sign was found (``measured``, ``anatomy``,
    ``nominal``), ``sign``: the anatomical sign's (``anatomy``, ``nominal``);
    ``excursion_deg``: the joint's excursion (deg) either way; ``window_s``: the movement's
    first and last time (s); ``n_samples``: the samples fitted; ``verdict`` is ``determined``,
    ``weak`` or ``not determined`` and ``reasons`` says why in plain words.
    ``used_for``: ``axes`` (the fit gives the joint's axes) or ``direction`` (a functional step
    measured them and the fit only tells which way they point: the placement hint was
    contradicted). ``method``: ``seel`` (Seel's hinge constraint) or ``principal`` (each
    segment's principal rotation axis over a walk, :mod:`motionlab.segments.gait_axes`, with the
    constrained hinge fit as its witness); with ``principal``: ``witness_deg`` (deg between the
    principal axes and the witness), ``dominance`` (second over first singular value of the
    segments' rates, the larger) and ``proximal_tilt_deg`` (how far the proximal segment's long
    axis tilts from its direction in the stand over the fit's window, deg, 99th percentile: how
    far a thigh swings, which bounds the flexion of the hip above it,
    :mod:`motionlab.segments.grades`) and ``speed_ratio`` (the proximal segment's angular speed
    over the distal's, 95th percentiles over the swings: a thigh turns slower than its shank in
    a walk; NaN where the movement is not walking).
    """

    joint: str
    axis_proximal: np.ndarray
    axis_distal: np.ndarray
    residual_rad_s: float
    relative_residual: float
    consistency_deg: float
    relative_sign: str  # "measured" | "anatomy" (the one that flexes one way) | "nominal"
    sign: str  # "anatomy" | "nominal"
    excursion_deg: tuple[float, float] = (float("nan"), float("nan"))
    window_s: tuple[float, float] = (float("nan"), float("nan"))
    n_samples: int = 0
    verdict: str = "determined"
    reasons: list[str] = field(default_factory=list)
    used_for: str = "axes"
    method: str = "seel"
    witness_deg: float = float("nan")
    dominance: float = float("nan")
    proximal_tilt_deg: float = float("nan")
    speed_ratio: float = float("nan")
    #: keys of a stored fit this version does not know (kept for the round trip)
    more: dict[str, Any] = field(default_factory=dict)

    def to_tree(self) -> dict[str, Any]:
        """The HDF5 results layout (plain numbers, lists and strings)."""
        return {
            "used_for": self.used_for,
            "method": self.method,
            "witness_deg": self.witness_deg,
            "dominance": self.dominance,
            "proximal_tilt_deg": self.proximal_tilt_deg,
            "speed_ratio": self.speed_ratio,
            "joint": self.joint,
            "axis_proximal": np.asarray(self.axis_proximal, float),
            "axis_distal": np.asarray(self.axis_distal, float),
            "residual_rad_s": self.residual_rad_s,
            "relative_residual": self.relative_residual,
            "consistency_deg": self.consistency_deg,
            "relative_sign": self.relative_sign,
            "sign": self.sign,
            "excursion_deg": list(self.excursion_deg),
            "window_s": list(self.window_s),
            "n_samples": self.n_samples,
            "verdict": self.verdict,
            "reasons": list(self.reasons),
        } | self.more

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> HingeFit:
        """The fit of a stored tree: a :class:`TwoAxisFit` when its ``kind`` is ``two_axes``;
        a stored fit names every field but ``more`` (and, before they existed, ``used_for``,
        ``method`` and the ``principal`` fields, which keep their defaults)."""
        kind = TwoAxisFit if tree.get("kind") == "two_axes" else HingeFit
        names = {f.name for f in dataclasses.fields(kind)} - {"more"}
        known = {k: v for k, v in tree.items() if k in names}
        more = {k: v for k, v in tree.items() if k not in names and k != "kind"}
        return kind(**known, more=more)


@dataclass
class TwoAxisFit(HingeFit):
    """A two-degree-of-freedom joint (the elbow; :func:`motionlab.segments.movement.fit_two_dof`):
    ``axis_proximal`` is the flexion axis in the proximal sensor, ``axis_distal`` the long
    (pronation) axis in the distal sensor, pointing proximally; ``flexion_distal`` the flexion
    axis in the distal sensor in the reference pose (the distal segment's z there).
    ``heading_times`` / ``heading_deltas`` (s, rad) are the heading offsets fitted with the axes
    (the distal sensor's earth frame turned by δ about the vertical matches the proximal one).
    ``axial_follow``: the fraction of the proximal segment's rotation about its long axis that
    its sensor follows, fitted with the axes (NaN when not fitted); ``across_deg``: how far (deg)
    the flexion axis lies from the perpendicular to that long axis in the reference pose (NaN
    when not checked; over ``movement.ACROSS_LONG_AXIS_DEG`` the fit is refused as no joint of
    its kind); ``lag_anchor``: the segment (the thorax) against whose sensor the angles undo the
    lag ``axial_follow`` measures (:mod:`motionlab.segments.skin_lag`; empty: not undone, no
    sensor there). Stored with ``kind`` ``two_axes``."""

    flexion_distal: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    heading_times: np.ndarray = field(default_factory=lambda: np.empty(0))
    heading_deltas: np.ndarray = field(default_factory=lambda: np.empty(0))
    axial_follow: float = float("nan")
    across_deg: float = float("nan")
    lag_anchor: str = ""

    def to_tree(self) -> dict[str, Any]:
        """The hinge fit's layout with ``kind`` and the two-axis fields."""
        # axial_follow, across_deg and lag_anchor only where they were found: a fit stored
        # before they existed is written back as it was read
        follow = {k: v for k, v in (("axial_follow", self.axial_follow),
                                    ("across_deg", self.across_deg)) if np.isfinite(v)}  # fmt: skip
        if self.lag_anchor:
            follow["lag_anchor"] = self.lag_anchor
        return (
            super().to_tree()
            | {
                "kind": "two_axes",
                "flexion_distal": np.asarray(self.flexion_distal, float),
                "heading_times": np.asarray(self.heading_times, float),
                "heading_deltas": np.asarray(self.heading_deltas, float),
            }
            | follow
        )


@dataclass(frozen=True)
class HipAxis(_Record):
    """A hip's flexion axis measured from the movement (:func:`motionlab.segments.hip_axis.
    flexion_turn`; one value of :attr:`SegmentCalibration.hip_axes`).

    ``used``: the angles are taken about it; ``turn_deg``: its angle (deg) about the pelvis's y
    axis from the pelvis's z (0 when not used); ``rho``: how dominant the axis is (1: the only
    one; NaN when not measured); ``n_samples``: the fast samples it was measured from;
    ``tilt_deg``: its angle (deg) out of the pelvis's transverse plane (``None`` when not
    measured); ``reason``: why it is not used (empty when it is).
    """

    used: bool
    turn_deg: float
    rho: float
    n_samples: int
    reason: str = ""
    tilt_deg: float | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TrunkMovement(_Record):
    """What a trunk calibration found in the movement (:mod:`motionlab.segments.trunk_axes`;
    the ``trunk`` of each of its :class:`JointGrades`).

    ``rest_s`` ``[start, end]`` (s): the rest taken as the zero of the angles;
    ``rest_speed_deg_s`` (deg/s): the mean angular speed of the joint's sensors over its
    stillest second; ``axis_ratio``: how much more one-sided the movement is about the chosen
    flexion axis than about the other horizontal axis; ``energy_ratio``: the mean squared
    relative rate about the axis turning most (the flexion axis) over that about the other
    (files written before 2026-11-29 also hold ``axis_rank``, kept in ``more``); ``one_sided``: per
    horizontal axis (the one turning most first) the larger excursion over the smaller about
    it (each at least 1°); ``excursion_deg`` ``[positive, negative]`` (deg): the 98th and
    2nd percentiles of the lean since the rest about the flexion axis found (the second below
    0 when the thorax leaned the other way); ``sign_ratio``: the thorax's excursion one way
    over the other about the flexion axis (its ``one_sided``); ``heading_deg`` (deg): the
    heading about the vertical that turns the thorax sensor's earth frame onto the pelvis
    sensor's, from the movement's rates; ``heading_rho``: the share of the horizontal rates
    that heading explains (1: all); ``heading_drift_deg`` (deg): the peak-to-peak drift of
    that heading followed from the gyroscopes over the recording (``None``: not followed, the
    rest was not still or a fusion was 9-D or reported no bias); ``lean_coupling``: the
    correlation of the lumbar flexion with the thorax's lean about the flexion axis over the
    movement (negative: the spine extended as the trunk leaned, as sensors swapped in the map
    read; ``twist_coupling``: the correlation of the thorax's rate about its vertical relative
    to the pelvis with its own (negative: the pelvis turned further than the thorax, as swapped
    sensors read); both ``None`` in files written before 2026-12-03).
    """

    # ``heading_drift_deg`` predates the class and was always stored; a later field is not
    _stored_when_none: ClassVar[frozenset[str]] = frozenset({"heading_drift_deg"})

    rest_s: list[float]
    rest_speed_deg_s: float
    axis_ratio: float
    energy_ratio: float
    one_sided: list[float]
    excursion_deg: list[float]
    sign_ratio: float
    heading_deg: float
    heading_rho: float
    heading_drift_deg: float | None = None
    lean_coupling: float | None = None
    twist_coupling: float | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class JointGrades(_Record):
    """What the recording determined of one joint's angles
    (:func:`motionlab.segments.grades.grade_joints`; one value of
    :attr:`SegmentCalibration.grades`).

    ``grades``: one per angle column in the joint type's order (flexion first):
    ``determined``, ``weak`` or ``not determined``; ``reasons``: why, in plain words, one per
    angle (empty for a determined one); ``trunk``: what a trunk calibration found in the
    movement (:class:`TrunkMovement`; ``None`` for any other calibration). A joint stored
    without ``grades`` or ``reasons`` has them empty (its angles count as ``determined``).
    """

    grades: list[str] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    trunk: TrunkMovement | None = None
    more: dict[str, Any] = field(default_factory=dict)

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {"trunk": (TrunkMovement, 0)}


@dataclass(frozen=True)
class GapTurn(_Record):
    """The turn packet-loss gaps may have hidden in a joint tied only at poses (one value of
    :attr:`SegmentCalibration.gap_turns`; :func:`motionlab.segments.gap_headings`):
    ``turn_deg`` (their bridges' possible misses, each total over the axes, combined as
    independent errors: the root of the sum of squares), the ``sensor`` of the largest and the
    first recorded instant after it, ``time_s``; ``gaps`` how many were combined (``None``,
    not stored: one, as a calibration stored before 30 Nov 2026 always took the largest
    alone)."""

    turn_deg: float
    sensor: str
    time_s: float
    gaps: int | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CentreHeading(_Record):
    """Heading ties fitted at calibration for a joint without a hinge (one value of
    :attr:`SegmentCalibration.centres`): the distal sensor's earth frame turned by
    ``heading_deltas`` (K,) rad about the vertical at ``heading_times`` (K,) s matches the
    proximal one. ``anchors``: K, for ties from a ball joint's shared centre
    (:func:`motionlab.segments.placement.centre_headings`); ``method``: ``trunk rest`` for a
    trunk calibration's ties at its rest (:mod:`motionlab.segments.trunk_axes`); each ``None``
    (not stored) for the other kind.
    """

    heading_times: np.ndarray
    heading_deltas: np.ndarray
    anchors: int | None = None
    method: str | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class HeadingTie(_Record):
    """One joint's heading ties (one value of :attr:`HeadingTies.joints`; what
    :func:`motionlab.segments.segment_orientations` applies): ``source`` (``hinge``,
    ``single pose``, ``steps``; ``two_axes`` and ``centre`` ties stay with their fit),
    ``times`` (K,) s and ``deltas`` (K,) rad: the distal segment turned by ``deltas`` about
    the vertical at ``times`` (interpolated between) matches the proximal one.
    """

    source: str
    times: np.ndarray
    deltas: np.ndarray
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class HeadingTies(_Record):
    """Each joint's heading ties found at calibration (:func:`motionlab.segments.heading_ties`;
    :attr:`SegmentCalibration.headings`): ``sha256`` ``{segment: hex}``: the SHA-256 of the
    sensor orientations they were found from (:func:`motionlab.segments.orientations_sha256`);
    ``joints`` ``{joint: HeadingTie}`` (:class:`HeadingTie`).
    """

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {"joints": (HeadingTie, 1)}

    sha256: dict[str, str] = field(default_factory=dict)
    joints: dict[str, HeadingTie] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class SegmentCalibration(_Record):
    """Sensor-to-segment calibration: how each sensor sits on its segment
    (:func:`motionlab.segments.calibrate_segments`).

    ``protocol``: its name; ``protocol_path``: the file it was read from. ``steps``
    ``{step: [start_s, end_s] | None}`` found in the recording. ``segments`` ``{segment:
    SegmentRecord}``: how each sensor sits on its segment (:class:`SegmentRecord`).
    ``hinges`` ``{joint: HingeFit}``: axes from ordinary movement (:class:`HingeFit`,
    :class:`TwoAxisFit` for a two-axis joint, with its headings).
    ``centres`` ``{joint: CentreHeading}``: heading ties from a ball joint's shared centre or a
    trunk's rest (:class:`CentreHeading`). ``warnings``:
    lines the user should read; ``ok``: every segment's quality passed. ``grades`` ``{joint:
    JointGrades}``: a grade and its reason per angle (:class:`JointGrades`).
    ``single_pose``: the static step a recording too short for more was taken as (an
    OpenSense-style single-pose calibration, :mod:`motionlab.segments.single_pose`), else ``None``.
    ``hip_axes`` ``{joint: HipAxis}``: the hips' flexion axes from the movement
    (:class:`HipAxis`). ``headings``: each joint's heading ties (:class:`HeadingTies`: the
    anchors of the heading alignment, :func:`motionlab.segments.heading_ties`), found once here
    from the sensor orientations whose SHA-256 per segment it holds (ties kept with a
    two-axis fit or a centre are in ``hinges``/``centres``); the angles, metrics and gait apply
    them to those orientations (:func:`motionlab.segments.segment_orientations`) and find them
    anew for others, or for a calibration stored without them (``None``; an empty stored
    group reads as ``None`` too). ``gap_turns`` ``{joint: GapTurn}``: for the joints tied only
    at poses, the turn the packet-loss gaps after the first pose may together have hidden
    (:class:`GapTurn`; the grades read it).
    """

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "segments": (SegmentRecord, 1),
        "hinges": (HingeFit, 1),
        "centres": (CentreHeading, 1),
        "grades": (JointGrades, 1),
        "hip_axes": (HipAxis, 1),
        "headings": (HeadingTies, 0),
        "gap_turns": (GapTurn, 1),
    }

    protocol: str
    steps: dict[str, list[float] | None] = field(default_factory=dict)
    segments: dict[str, SegmentRecord] = field(default_factory=dict)
    hinges: dict[str, HingeFit] = field(default_factory=dict)
    centres: dict[str, CentreHeading] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    ok: bool = True
    grades: dict[str, JointGrades] = field(default_factory=dict)
    protocol_path: str | None = None
    single_pose: str | None = None
    hip_axes: dict[str, HipAxis] = field(default_factory=dict)
    headings: HeadingTies | None = None
    gap_turns: dict[str, GapTurn] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> SegmentCalibration:
        """The calibration of a stored tree (see :meth:`to_tree`; empty ``headings``: none)."""
        return super().from_tree({k: v for k, v in tree.items() if k != "headings" or v})

    @property
    def protocol_source(self) -> str:
        """What to load the protocol from: its path, else its name."""
        return self.protocol_path or self.protocol


# ---------------------------------------------------------------------------------- angles


def column_unit(name: str) -> str:
    """Unit of an angle-table column from its name's suffix (``_deg`` → ``deg``, ``_s`` → ``s``)."""
    for suffix, unit in (("_deg", "deg"), ("_s", "s"), ("_pct", "%")):
        if name.endswith(suffix):
            return unit
    return "1"


@dataclass
class AngleTable:
    """The joint angle table (after kineticstoolkit's ``TimeSeries``): ``time`` (N,) s, one
    ``data`` column (N,) per angle (``knee_r_flexion_deg``, named by
    :func:`motionlab.kinematics.joint_types.angle_columns`), each column's unit in ``units``,
    and ``events`` ``{name: (start_s, end_s)}``: the calibration steps and the task blocks
    (added by the metrics stage). ``method``: ``imu`` or ``accel-only``. ``lowpass_hz``: the
    cut-off the columns were low-passed at (:mod:`motionlab.kinematics.angle_filter`; 0: as
    computed, as every table stored before it was recorded).
    """

    time: np.ndarray
    data: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    events: dict[str, tuple[float, float]] = field(default_factory=dict)
    method: str = "imu"
    lowpass_hz: float = 0.0

    TIME: ClassVar[str] = "time_s"

    def __post_init__(self) -> None:
        for name in self.data:
            self.units.setdefault(name, column_unit(name))

    @classmethod
    def from_columns(
        cls,
        columns: dict[str, Any],
        method: str = "imu",
        events: dict[str, tuple[float, float]] | None = None,
        lowpass_hz: float = 0.0,
    ) -> AngleTable:
        """From ``{"time_s": (N,), "<column>": (N,), ...}`` (as the angle functions give)."""
        data = {k: np.asarray(v) for k, v in columns.items() if k != cls.TIME}
        time, events = np.asarray(columns[cls.TIME]), dict(events or {})
        return cls(time, data, events=events, method=method, lowpass_hz=float(lowpass_hz))

    def columns(self) -> dict[str, np.ndarray]:
        """``{"time_s": time, <column>: values, ...}``: one dict of equal-length arrays (a
        ``pandas.DataFrame`` of it has only numeric columns)."""
        return {self.TIME: self.time} | dict(self.data)

    def to_tree(self) -> dict[str, Any]:
        """``time_s`` and the columns as datasets; ``method``, ``units``, ``events`` and
        ``lowpass_hz``."""
        tree: dict[str, Any] = self.columns()
        tree["method"] = self.method
        tree["lowpass_hz"] = float(self.lowpass_hz)
        tree["units"] = dict(self.units)
        tree["events"] = {k: [float(a), float(b)] for k, (a, b) in self.events.items()}
        return tree

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> AngleTable:
        """The table of a stored tree (schema 1 had no ``units`` nor ``events``; tables stored
        before 3 Dec 2026 no ``lowpass_hz``: they were as computed)."""
        columns = {k: v for k, v in tree.items() if isinstance(v, np.ndarray)}
        events = {k: (float(v[0]), float(v[1])) for k, v in tree.get("events", {}).items()}
        lowpass = float(tree.get("lowpass_hz", 0.0))
        table = cls.from_columns(columns, str(tree.get("method", "imu")), events, lowpass)
        table.units.update(tree.get("units", {}))
        return table


@dataclass
class HeadingCorrection(_Record):
    """What one joint's heading alignment did (:func:`motionlab.segments.segment_orientations`):
    ``source`` (``hinge``, ``two_axes``, ``centre``, ``steps``, ``walk``: the steps and a hip's
    straight walking, ``single pose``), the number of
    ``anchors``, and the correction's ``mean_deg``, ``range_deg`` and ``drift_deg_per_min`` (none
    without anchors).
    """

    source: str
    anchors: int
    mean_deg: float | None = None
    range_deg: float | None = None
    drift_deg_per_min: float | None = None


# --------------------------------------------------------------------------------- metrics


@dataclass(frozen=True)
class TaskBlock(_Record):
    """One task's time range (one value of :attr:`Metrics.blocks` or :attr:`Gait.tasks`):
    ``start_s`` and ``end_s`` (s, on the session's clock); ``source``: ``detected`` (found in
    the recording) or ``given`` (the user's time range; ``None``, not stored, when the metrics
    were computed from given ranges without a session,
    :func:`motionlab.kinematics.metrics.compute_metrics`, and in :attr:`Gait.tasks`).
    """

    start_s: float
    end_s: float
    source: str | None = None
    more: dict[str, Any] = field(default_factory=dict)


def _nan_curve() -> np.ndarray:
    return np.full(101, np.nan)


@dataclass(frozen=True)
class AngleMetrics(_Record):
    """One angle column's metrics over one task block (:func:`motionlab.kinematics.metrics.
    angle_metrics`; one value of ``Metrics.joints[task]``), all in degrees.

    ``rom_deg``: its range over the block, ``min_deg`` / ``max_deg`` its extremes (NaN without
    a finite sample); ``repetitions``: the cycles found (strides in gait, repetitions else; 0:
    none); per cycle ``cycle_max_deg`` / ``cycle_min_deg`` (one value each) and their means
    ``cycle_max_mean_deg`` / ``cycle_min_mean_deg`` (NaN without cycles); ``curve_mean_deg`` /
    ``curve_sd_deg`` (101,): mean and SD over the cycles normalised to 0–100 % (NaN without
    cycles); ``cycle_start_s`` (s): each cycle's start (``None`` when not given).
    """

    rom_deg: float
    min_deg: float
    max_deg: float
    repetitions: int = 0
    cycle_max_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cycle_min_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cycle_max_mean_deg: float = float("nan")
    cycle_min_mean_deg: float = float("nan")
    curve_mean_deg: np.ndarray = field(default_factory=_nan_curve)
    curve_sd_deg: np.ndarray = field(default_factory=_nan_curve)
    cycle_start_s: np.ndarray | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StanceMetrics(_Record):
    """A knee's varus thrust and stance rotation over a gait block's strides
    (:func:`motionlab.kinematics.out_of_plane.stance_metrics`; one value of
    ``Metrics.gait[task]``), in degrees.

    ``strides``: the strides found (heel strike to heel strike); per stride ``varus_thrust_deg``
    (the rise of the adduction angle from heel strike to its maximum in weight acceptance,
    :func:`~motionlab.kinematics.out_of_plane.weight_acceptance`) and
    ``stance_rotation_range_deg`` (the rotation's range over stance); their means
    ``varus_thrust_mean_deg`` / ``stance_rotation_range_mean_deg`` and SDs (ddof 1; 0 with one
    stride) ``varus_thrust_sd_deg`` / ``stance_rotation_range_sd_deg`` (NaN without strides);
    ``varus_thrust_above_pct`` (%): the share of strides whose thrust exceeds
    ``threshold_deg`` (the protocol's ``varus_thrust_deg``; NaN without strides);
    ``heel_strike_s`` / ``toe_off_s`` (s): each stride's heel strike and toe-off (``None``
    when not given).
    """

    strides: int
    varus_thrust_deg: np.ndarray
    varus_thrust_mean_deg: float
    varus_thrust_sd_deg: float
    varus_thrust_above_pct: float
    threshold_deg: float
    stance_rotation_range_deg: np.ndarray
    stance_rotation_range_mean_deg: float
    stance_rotation_range_sd_deg: float
    heel_strike_s: np.ndarray | None = None
    toe_off_s: np.ndarray | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class OutOfPlaneOffset(_Record):
    """To's axis-angle out-of-plane offset of a lumbar joint during a task in one plane
    (:func:`motionlab.kinematics.out_of_plane.out_of_plane_offset`; one value of
    ``Metrics.out_of_plane_offset[task]``), in degrees.

    ``axes``: the two segment axes (``x``, ``y``, ``z``) perpendicular to the rotation axis
    whose angles' difference is the offset; ``offset_deg`` (N,): that difference, as a change
    from the standing reference, per sample of the block; over the repetitions' span (the
    block without them): ``peak_deg`` and ``mean_deg`` of its size and ``above_pct`` (%) the
    share of samples above ``threshold_deg`` (the protocol's ``out_of_plane_offset_deg``);
    ``repetition_peak_deg``: its peak size per repetition.
    """

    axes: list[str]
    peak_deg: float
    mean_deg: float
    above_pct: float
    threshold_deg: float
    repetition_peak_deg: np.ndarray
    offset_deg: np.ndarray
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TrunkAngleStats(_Record):
    """One trunk angle's compensation over a task (one value of
    :attr:`TrunkCompensation.per_angle`), in degrees: ``max_deg`` / ``min_deg`` its extremes,
    ``peak_abs_deg`` its largest size, ``above_pct`` (%) the share of samples whose size
    exceeds ``threshold_deg`` (the protocol's ``trunk_compensation_deg`` for the angle; ``inf``
    when it gives none)."""

    max_deg: float
    min_deg: float
    peak_abs_deg: float
    above_pct: float
    threshold_deg: float
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TrunkCompensation(_Record):
    """Trunk lean and twist relative to the neutral posture before a task (Liu 2010;
    :func:`motionlab.kinematics.out_of_plane.trunk_compensation`; one value of
    :attr:`Metrics.trunk_compensation`).

    ``per_angle`` ``{angle: TrunkAngleStats}`` for the lumbar angles (``flexion``: forward lean,
    ``lateral_bending``: lean to the right, ``axial_rotation``: twist to the left, positive;
    :class:`TrunkAngleStats`), stored as the tree's subtrees by angle name (any subtree of a
    stored tree is read as an angle); ``compensated``: an angle went above its threshold;
    ``angles_deg`` (N, 3): the three angles (deg) per sample of the task.
    """

    per_angle: dict[str, TrunkAngleStats]
    compensated: bool
    angles_deg: np.ndarray
    more: dict[str, Any] = field(default_factory=dict)

    def to_tree(self) -> dict[str, Any]:
        """``{angle: stats tree, ..., compensated, angles_deg}`` and the unknown keys."""
        return (
            {k: v.to_tree() for k, v in self.per_angle.items()}
            | {"compensated": self.compensated, "angles_deg": self.angles_deg}
            | self.more
        )

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> TrunkCompensation:
        """The compensation of a stored tree (see :meth:`to_tree`)."""
        rest = {k: v for k, v in tree.items() if not isinstance(v, dict)}
        known = {k: rest.pop(k) for k in ("compensated", "angles_deg")}
        per_angle = {
            k: TrunkAngleStats.from_tree(v) for k, v in tree.items() if isinstance(v, dict)
        }
        return cls(per_angle, **known, more=rest)


@dataclass(frozen=True)
class OffAxisRange(_Record):
    """One off-axis angle's range during a single-plane movement (one value of
    :attr:`CrossTalk.off_axis`), in degrees: ``rom_deg`` its range, ``ratio_pct`` (%) that over
    the on-axis range (NaN when that is 0); with the protocol's nominal placement for
    comparison, ``nominal_rom_deg`` the range with it and ``change_pct`` (%) the calibration's
    change of the range (Ricci 2015: −39 % to −70 %; NaN when the nominal range is 0); each
    ``None`` (not stored) without the comparison.
    """

    rom_deg: float
    ratio_pct: float
    nominal_rom_deg: float | None = None
    change_pct: float | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CrossTalk(_Record):
    """Cross-talk of a joint during a single-plane movement (Ricci 2015 §6.3;
    :func:`motionlab.kinematics.out_of_plane.cross_talk`; one value of
    ``Metrics.cross_talk[block]``).

    ``on_axis``: the moving angle's name (``flexion``, ...); ``on_axis_rom_deg`` (deg): its
    range; ``off_axis`` ``{angle: OffAxisRange}``: the two other angles
    (:class:`OffAxisRange`), stored as the tree's subtrees by angle name (any subtree of a
    stored tree is read as an angle).
    """

    on_axis: str
    on_axis_rom_deg: float
    off_axis: dict[str, OffAxisRange] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)

    def to_tree(self) -> dict[str, Any]:
        """``{on_axis, on_axis_rom_deg, angle: range tree, ...}`` and the unknown keys."""
        head = {"on_axis": self.on_axis, "on_axis_rom_deg": self.on_axis_rom_deg}
        return head | {k: v.to_tree() for k, v in self.off_axis.items()} | self.more

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> CrossTalk:
        """The cross-talk of a stored tree (see :meth:`to_tree`)."""
        rest = {k: v for k, v in tree.items() if not isinstance(v, dict)}
        known = {k: rest.pop(k) for k in ("on_axis", "on_axis_rom_deg")}
        off = {k: OffAxisRange.from_tree(v) for k, v in tree.items() if isinstance(v, dict)}
        return cls(**known, off_axis=off, more=rest)


def _map(tree: dict[str, Any] | None, read: Any, depth: int = 1) -> Any:
    """``read`` applied to the leaves of a ``depth``-level map of stored trees (depth 0: the
    tree is the leaf; ``None`` stays ``None``); a map or leaf that is not a group (a damaged
    file) raises ``TypeError``."""
    if tree is None:
        return None
    if depth == 0:
        return read(_group(tree))
    return {k: _map(v, read, depth - 1) for k, v in _group(tree).items()}


def _group(tree: Any) -> dict[str, Any]:
    """``tree`` when it is a group's tree, else ``TypeError``."""
    if not isinstance(tree, dict):
        raise TypeError(f"a group expected, not {type(tree).__name__}")
    return tree


def _tree(records: Any, depth: int = 1) -> Any:
    """The trees of a ``depth``-level map of records (depth 0: one record; ``None`` stays
    ``None``)."""
    if records is None:
        return None
    if depth == 0:
        return records.to_tree()
    return {k: _tree(v, depth - 1) for k, v in records.items()}


@dataclass
class Metrics(_Record):
    """Metrics per task block (:func:`motionlab.kinematics.metrics.session_metrics`).

    ``protocol``: its name. ``blocks`` ``{task: TaskBlock}``: each task's time range
    (:class:`TaskBlock`). ``joints`` ``{task: {column: AngleMetrics}}``
    (:class:`AngleMetrics`: range, extremes, cycles and the mean curve). When the protocol asks
    for them (``None`` otherwise):
    ``gait`` ``{task: {joint: StanceMetrics}}`` (:class:`StanceMetrics`: a knee's varus
    thrust and stance rotation), ``out_of_plane_offset`` ``{task: {joint: OutOfPlaneOffset}}``
    (:class:`OutOfPlaneOffset`), ``trunk_compensation`` ``{task: TrunkCompensation}``
    (:class:`TrunkCompensation`), ``cross_talk`` ``{block: {joint: CrossTalk}}``
    (:class:`CrossTalk`).
    """

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "joints": (AngleMetrics, 2),
        "blocks": (TaskBlock, 1),
        "gait": (StanceMetrics, 2),
        "out_of_plane_offset": (OutOfPlaneOffset, 2),
        "trunk_compensation": (TrunkCompensation, 1),
        "cross_talk": (CrossTalk, 2),
    }

    protocol: str
    joints: dict[str, dict[str, AngleMetrics]] = field(default_factory=dict)
    blocks: dict[str, TaskBlock] = field(default_factory=dict)
    gait: dict[str, dict[str, StanceMetrics]] | None = None
    out_of_plane_offset: dict[str, dict[str, OutOfPlaneOffset]] | None = None
    trunk_compensation: dict[str, TrunkCompensation] | None = None
    cross_talk: dict[str, dict[str, CrossTalk]] | None = None
    more: dict[str, Any] = field(default_factory=dict)

    def spans(self) -> dict[str, tuple[float, float]]:
        """``{task: (start_s, end_s)}`` of the blocks."""
        return {k: (float(b.start_s), float(b.end_s)) for k, b in self.blocks.items()}


@dataclass(frozen=True)
class StrideStats(_Record):
    """One stride-table column's statistics over a side's kept strides
    (:func:`motionlab.kinematics.spatiotemporal.summary`; one value of
    ``GaitSummary.sides[side]``), in the column's unit: ``mean``, ``sd`` (ddof 1), ``cv_pct``
    (%, 100 SD/mean), ``se`` (SD/√n), ``median``, ``q1`` and ``q3`` (the quartiles), each NaN
    below the summary's ``min_strides`` values; ``strides_n``: the values it had. In a file
    written before they existed ``se``, the median and the quartiles are ``None``, and so is
    ``strides_n`` where the count was stored as ``n`` (kept in ``more``).
    """

    mean: float
    sd: float
    cv_pct: float
    se: float | None = None
    median: float | None = None
    q1: float | None = None
    q3: float | None = None
    strides_n: int | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class GaitSummary(_Record):
    """The kept strides summarised (:func:`motionlab.kinematics.spatiotemporal.summary`;
    :attr:`Gait.summary`).

    ``sides`` ``{side: {column: StrideStats}}``: per side (``r``, ``l``) and stride-table
    column the statistics of its kept strides (:class:`StrideStats`, in the column's unit).
    Both sides together: ``cadence_steps_per_min`` (steps/min), ``step_time_asymmetry_pct`` (%)
    with its standard error ``step_time_asymmetry_se_pct`` from ``step_pairs`` paired
    steady steps, ``stride_time_cv_pct`` (%, within steady bouts) with
    ``stride_time_cv_se_pct``, ``walking_speed_m_s`` (m/s; NaN without leg lengths) — each NaN
    when withheld, and NaN in a file written before it existed. ``strides_kept``;
    ``strides_rejected`` ``{reason: count}``; ``min_strides``: the fewest strides a mean needs
    (``None`` in a file written without it); ``withheld`` ``{number: why it is not given}``.
    """

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {"sides": (StrideStats, 2)}

    sides: dict[str, dict[str, StrideStats]] = field(default_factory=dict)
    min_strides: int | None = None
    cadence_steps_per_min: float = float("nan")
    step_pairs: int = 0
    step_time_asymmetry_pct: float = float("nan")
    step_time_asymmetry_se_pct: float = float("nan")
    stride_time_cv_pct: float = float("nan")
    stride_time_cv_se_pct: float = float("nan")
    walking_speed_m_s: float = float("nan")
    strides_kept: int = 0
    strides_rejected: dict[str, int] = field(default_factory=dict)
    withheld: dict[str, str] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class MovementProfile(_Record):
    """The Movement Analysis Profile and Gait Profile Score (Baker et al. 2009;
    :mod:`motionlab.kinematics.gps`; :attr:`Gait.map`), in degrees.

    ``gvs`` ``{side: {variable: deg}}``: each variable's Gait Variable Score (RMS difference of
    its mean curve from the normative mean); ``gps`` ``{side: deg, "overall": deg}``: their RMS
    per side and over both (NaN when withheld); ``population_gps_deg``: the GPS expected of a
    normal subject over the same variables (``None`` in a file written without it);
    ``variables``: the variables scored or withheld; ``withheld`` ``{side: {variable: why}}``
    and ``not_computed`` (a sentence naming what is missing, empty when the overall GPS is
    given): what the grades and strides did not allow (:func:`motionlab.kinematics.gps.
    gated_profile`; ``None`` for a profile not gated).
    """

    gvs: dict[str, dict[str, float]] = field(default_factory=dict)
    gps: dict[str, float] = field(default_factory=dict)
    population_gps_deg: float | None = None
    variables: list[str] = field(default_factory=list)
    withheld: dict[str, dict[str, str]] | None = None
    not_computed: str | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class GaitEvents(_Record):
    """One side's gait events over the whole recording (:func:`motionlab.kinematics.
    gait_events.detect`; one value of :attr:`Gait.events`): ``ic`` (s) the initial contacts
    and ``fc`` (s) the final contacts, each with its ``ic_confidence`` / ``fc_confidence``
    (0–1: how clearly the shank's angular velocity shows it)."""

    ic: np.ndarray
    ic_confidence: np.ndarray
    fc: np.ndarray
    fc_confidence: np.ndarray
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StrideTable(_Record):
    """The stride table of a gait analysis (:func:`motionlab.kinematics.spatiotemporal.
    stride_table`; :attr:`Gait.strides`): one value per stride of both sides in each array,
    in time order.

    ``start_s`` (s): its initial contact; ``kept``: it passed the checks, else ``reason`` says
    why not (``turn``, ``start/stop``, ...; empty when kept); ``side`` (``r``, ``l``);
    ``stride_time_s``, ``step_time_s``, ``stance_time_s``, ``swing_time_s`` (s),
    ``stance_pct``, ``swing_pct``, ``double_support_pct`` (% of the stride),
    ``cadence_steps_per_min`` (steps/min), ``step_length_m``, ``stride_length_m`` (m) and
    ``walking_speed_m_s`` (m/s) as :mod:`motionlab.kinematics.spatiotemporal` defines them
    (NaN where not measured; a column is ``None`` in a file written before it existed).
    """

    start_s: np.ndarray
    kept: np.ndarray
    stride_time_s: np.ndarray | None = None
    step_time_s: np.ndarray | None = None
    stance_time_s: np.ndarray | None = None
    swing_time_s: np.ndarray | None = None
    stance_pct: np.ndarray | None = None
    swing_pct: np.ndarray | None = None
    double_support_pct: np.ndarray | None = None
    cadence_steps_per_min: np.ndarray | None = None
    step_length_m: np.ndarray | None = None
    stride_length_m: np.ndarray | None = None
    walking_speed_m_s: np.ndarray | None = None
    side: np.ndarray | None = None
    reason: np.ndarray | None = None
    more: dict[str, Any] = field(default_factory=dict)

    def frame(self) -> pd.DataFrame:
        """The table as a ``pandas.DataFrame``, its columns in the stored order."""
        import pandas as pd

        return pd.DataFrame({k: np.asarray(v) for k, v in self.to_tree().items()})


@dataclass(frozen=True)
class GaitPelvis(_Record):
    """The pelvis angles of a gait analysis relative to the walking direction
    (:func:`motionlab.kinematics.pelvis.pelvis_angles`; :attr:`Gait.pelvis`): ``time_s`` (N,)
    s, ``pelvis_tilt_deg``, ``pelvis_obliquity_deg`` and ``pelvis_rotation_deg`` (N,) deg
    (:data:`motionlab.kinematics.pelvis.PELVIS_COLUMNS`), and ``method``: how the pelvis frame
    and the walking direction were found."""

    time_s: np.ndarray
    pelvis_tilt_deg: np.ndarray
    pelvis_obliquity_deg: np.ndarray
    pelvis_rotation_deg: np.ndarray
    method: str = ""
    more: dict[str, Any] = field(default_factory=dict)

    def angles_deg(self) -> np.ndarray:
        """(N, 3) tilt, obliquity and rotation (deg), in ``PELVIS_COLUMNS`` order."""
        return np.column_stack(
            [self.pelvis_tilt_deg, self.pelvis_obliquity_deg, self.pelvis_rotation_deg]
        )


@dataclass
class Gait(_Record):
    """The gait analysis (:func:`motionlab.kinematics.gait.analyse_gait`).

    ``status``: ``ok`` or ``no gait: <why>``. With ``ok``: ``tasks`` ``{task: TaskBlock}``
    (the gait tasks' time ranges, :class:`TaskBlock`), ``events`` ``{side: GaitEvents}``
    (:class:`GaitEvents`; also with ``no gait`` when strides were found but none kept),
    ``strides`` (the stride table, :class:`StrideTable`), ``summary`` (:class:`GaitSummary`),
    ``walking_speed`` (the step and
    stride length model and the segment lengths used, or why they are not measured), ``pelvis``
    (pelvis angles, :class:`GaitPelvis`), ``curves`` ``{side: {variable: (101,) deg}}`` and
    ``map`` (the movement analysis profile, :class:`MovementProfile`).
    """

    status: str
    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "tasks": (TaskBlock, 1),
        "events": (GaitEvents, 1),
        "strides": (StrideTable, 0),
        "summary": (GaitSummary, 0),
        "pelvis": (GaitPelvis, 0),
        "map": (MovementProfile, 0),
    }

    tasks: dict[str, TaskBlock] | None = None
    events: dict[str, GaitEvents] | None = None
    strides: StrideTable | None = None
    summary: GaitSummary | None = None
    walking_speed: str | None = None
    pelvis: GaitPelvis | None = None
    curves: dict[str, dict[str, np.ndarray]] | None = None
    map: MovementProfile | None = None
    more: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Whether strides were found and analysed."""
        return self.status == "ok"


# ------------------------------------------------------------------------------ validation


@dataclass(frozen=True)
class OpticalSync(_Record):
    """The optical-to-IMU time alignment of a validation
    (:func:`motionlab.validation.time_alignment.synchronise`): the reference's clock reads
    ``t_ref = time_offset_s + (1 + drift_ppm · 1e-6) · t_imu``.

    ``method``: ``cross-correlation`` (windowed, RANSAC over the windows) or ``none`` (the streams
    taken as on one clock); ``time_offset_s`` (s) and ``drift_ppm`` (ppm) the clock model,
    ``standard_error_s`` (s) the offset's standard error and ``grade`` (``good``, ``fair``,
    ``poor``, ``none``; empty in a file written before it existed) what that allows;
    ``inlier_ratio``: the share of windows the model fits; ``residual_rms_s`` (s): RMS lag
    residual of the inliers; ``coarse_lag_s`` (s): the whole-recording correlation's lag;
    ``n_windows``; per window: ``window_time_s`` (its centre on the IMU clock, s),
    ``window_lag_s`` (t_ref − t_imu found there, s), ``window_sd_s`` (the lag's standard
    deviation, s), ``window_corr`` (the correlation peak), ``window_pair`` (the sensor pair's
    index), ``inliers`` (bool); ``fallback``: why a simpler method was used (empty: none);
    ``signal``: what the IMU side was (``gyroscope``, ``joint angle rates``, ...; empty without
    sync); ``sensor_residual_s`` ``{sensor: s}``: each sensor's median lag residual (sensors
    whose own clocks disagree show here). ``standard_error_s`` is the clock's standard error at
    the centre of the recording and ``ends_standard_error_s`` (s) the larger one at its ends,
    which ``grade`` grades; ``drift_measured_ppm`` ± ``drift_se_ppm`` the drift the windows
    show and ``drift_grade`` (``determined``, ``not determined``: then ``drift_ppm`` is 0, the
    drift not corrected; ``none`` without sync). The four are ``None`` in a file written before
    them (its grade is of the centre's standard error), and are then not stored.
    """

    method: str = "none"
    time_offset_s: float = 0.0
    drift_ppm: float = 0.0
    inlier_ratio: float = float("nan")
    residual_rms_s: float = float("nan")
    coarse_lag_s: float = 0.0
    n_windows: int = 0
    window_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_lag_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_sd_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_corr: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window_pair: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    inliers: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    standard_error_s: float = float("nan")
    grade: str = ""
    fallback: str = ""
    signal: str = ""
    sensor_residual_s: dict[str, float] = field(default_factory=dict)
    ends_standard_error_s: float | None = None
    drift_measured_ppm: float | None = None
    drift_se_ppm: float | None = None
    drift_grade: str | None = None
    more: dict[str, Any] = field(default_factory=dict)

    def drift_words(self) -> str:
        """The drift in words: ``+12.3 ± 4.1 ppm``; ``not determined (measured −28 ± 78 ppm), not
        corrected``; ``not determined (one offset), not corrected``; a record written before
        drift grades, ``12.3 ppm``."""
        seen = np.array([self.drift_measured_ppm, self.drift_se_ppm], dtype=float)  # None: NaN
        if self.drift_grade == "not determined":
            what = f"measured {seen[0]:+.0f} ± {seen[1]:.0f} ppm" if np.isfinite(seen).all() else (
                "one offset")  # fmt: skip
            return f"not determined ({what}), not corrected"
        if self.drift_grade == "determined" and np.isfinite(seen[1]):
            return f"{self.drift_ppm:+.1f} ± {seen[1]:.1f} ppm"
        return f"{self.drift_ppm:.1f} ppm"


@dataclass(frozen=True)
class AlignmentRotation(_Record):
    """One rotation of the spatial alignment: ``quat`` (4,) scalar first, its scalar part ≥ 0,
    and its angle ``angle_deg`` (deg)."""

    quat: np.ndarray
    angle_deg: float
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SpatialAlignment(_Record):
    """The IMU-to-optical spatial alignment of a validation (:mod:`motionlab.validation.align`:
    ``A_i = Y_i ⊗ B_i ⊗ X_i``; :attr:`Validation.alignment`).

    ``mode``: ``full``, ``heading`` or ``none``; ``lab_to_earth``: Y, the lab → earth rotation
    (:class:`AlignmentRotation`); ``sensor_to_cluster`` ``{sensor: AlignmentRotation}``: X_i,
    each sensor's axes in its marker cluster's coordinates; ``heading_deg`` ``{sensor: deg}``:
    the heading about the vertical per sensor in ``heading`` mode (empty otherwise);
    ``residual_rms_deg`` ``{sensor: deg}``: the RMS residual angle after alignment;
    ``conditioning`` ``{sensor: ratio}``: the smallest over the largest singular value of the
    relative rotations X_i was fitted from (0: about one axis only, X_i not determined about it).
    """

    mode: str
    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "lab_to_earth": (AlignmentRotation, 0),
        "sensor_to_cluster": (AlignmentRotation, 1),
    }

    lab_to_earth: AlignmentRotation
    sensor_to_cluster: dict[str, AlignmentRotation] = field(default_factory=dict)
    heading_deg: dict[str, float] = field(default_factory=dict)
    residual_rms_deg: dict[str, float] = field(default_factory=dict)
    conditioning: dict[str, float] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class OpticalSegmentInfo(_Record):
    """How the optical system saw one segment (:mod:`motionlab.validation.reference`; one value
    of :attr:`Validation.optical`, keyed by segment).

    ``source``: ``cluster`` (a marker cluster fitted frame by frame) or ``rigid_body`` (the
    capture system's own rigid body); ``landmarks``: the landmarks its anatomical frame was built
    from (empty: none); ``frame``: where the segment frame of the joint angles came from
    (``landmarks``, ``segment_frame``: the rigid body's frame is the anatomical one, or
    ``imu_calibration``: the cluster carried into the IMU's segment frame; ``None``: no joint
    angles). Of the tracking: ``fitted_fraction`` (share of frames with a pose),
    ``interpolated_fraction`` and ``flagged_fraction`` (shares of frames bridged over a short gap
    and flagged as a long one), ``n_long_gaps``, ``residual_rms_mm`` (mm: RMS residual of the
    cluster fit), ``shape_m`` (K, 3) m: the cluster's marker positions in its own frame
    (:class:`motionlab.validation.optical.ClusterTrack`); for a rigid body ``rigid_body`` (its
    name) and ``segment_frame`` (``True``: its frame is the anatomical one). Of the landmarks,
    for a cluster with some: ``static_source`` (``static trial``, ``static_time_s``, ``still
    window`` or ``whole recording``) and ``static_s`` ([start, end] s on that recording's clock):
    where they were fixed in the cluster frame; ``landmark_spread_mm`` ``{landmark: mm}``: their
    spread there; ``landmark_rms_mm`` ``{landmark: mm}`` (without a static trial): reconstructed
    against measured where the landmark is seen outside that window. Fields a segment has no
    value for are ``None`` and not stored.
    """

    source: str = ""
    landmarks: list[str] = field(default_factory=list)
    fitted_fraction: float | None = None
    interpolated_fraction: float | None = None
    flagged_fraction: float | None = None
    n_long_gaps: int | None = None
    residual_rms_mm: float | None = None
    rigid_body: str | None = None
    segment_frame: bool | None = None
    shape_m: np.ndarray | None = None
    static_source: str | None = None
    static_s: list[float] | None = None
    landmark_spread_mm: dict[str, float] | None = None
    landmark_rms_mm: dict[str, float] | None = None
    frame: str | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SensorOrientationError(_Record):
    """One sensor's orientation error against its optical segment after the alignment
    (:mod:`motionlab.validation.orientation_error`; one value of
    :attr:`OrientationErrors.sensors`), in degrees.

    Per sample of :attr:`OrientationErrors.time_s` (NaN without a reference): ``total_deg``
    (the geodesic angle), ``heading_deg`` (about the vertical) and ``inclination_deg`` (about a
    horizontal axis), as BROAD defines them. Over the samples used (``n_samples``; the movement
    only with ``movement_only``): ``total_rmse_deg``, ``heading_rmse_deg``,
    ``inclination_rmse_deg``, and the total error's ``median_deg``, ``iqr_deg`` and ``p95_deg``
    — all ``None`` (not stored) when no sample has both, ``n_samples`` then 0, or when the
    validation cannot state them: ``withheld`` then says why (:func:`motionlab.validation.
    withhold`).
    """

    total_deg: np.ndarray
    heading_deg: np.ndarray
    inclination_deg: np.ndarray
    total_rmse_deg: float | None = None
    heading_rmse_deg: float | None = None
    inclination_rmse_deg: float | None = None
    median_deg: float | None = None
    iqr_deg: float | None = None
    p95_deg: float | None = None
    n_samples: int = 0
    withheld: str | None = None
    more: dict[str, Any] = field(default_factory=dict)


def _timed_tree(time_s: np.ndarray | None, entries: dict[str, Any], more: dict) -> dict:
    """``{"time_s": ..., name: entry tree, ..., <more>}``: the flat layout of a validation's
    orientation errors and angles."""
    tree: dict[str, Any] = {} if time_s is None else {"time_s": time_s}
    tree.update({k: e.to_tree() for k, e in entries.items()})
    tree.update(more)
    return tree


def _timed_entries(tree: dict[str, Any], entry: type) -> tuple[Any, dict, dict]:
    """``(time_s, {name: entry}, more)`` of a flat tree: every subtree is an entry."""
    entries = {k: entry.from_tree(v) for k, v in tree.items() if isinstance(v, dict)}
    more = {k: v for k, v in tree.items() if k != "time_s" and not isinstance(v, dict)}
    return tree.get("time_s"), entries, more


@dataclass
class OrientationErrors:
    """The orientation errors of a validation (:attr:`Validation.orientation`): ``time_s``
    (N,) s, the IMU clock's samples they are given at (``None``: no sensor was compared, as with
    a model-angle reference stored without it), and ``sensors`` ``{sensor label:
    SensorOrientationError}``. Stored flat, as before the record: ``time_s`` and one group per
    sensor; other keys are kept in ``more``.
    """

    time_s: np.ndarray | None = None
    sensors: dict[str, SensorOrientationError] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)

    def to_tree(self) -> dict[str, Any]:
        """``{"time_s": ..., sensor: error tree, ...}``."""
        return _timed_tree(self.time_s, self.sensors, self.more)

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> OrientationErrors:
        """The errors of a stored tree (see :meth:`to_tree`)."""
        return cls(*_timed_entries(tree, SensorOrientationError))


@dataclass(frozen=True)
class RepetitionAgreement(_Record):
    """An angle's agreement per repetition of the movement
    (:func:`motionlab.validation.agreement.per_repetition`; :attr:`AngleAgreement.repetitions`).

    ``n``: the repetitions with three or more usable samples; per repetition (n,): ``start_s``
    and ``end_s`` (s, IMU clock), ``rmse_deg`` and ``bias_deg`` (deg, IMU − optical),
    ``rom_error_deg`` (the IMU's range of motion minus the optical one, deg) and
    ``peak_error_deg`` (the difference at the optical curve's peak, deg); ``cmc``: Ferrari's
    coefficient of multiple correlation over the gap-free repetitions (NaN when undefined).
    """

    n: int
    start_s: np.ndarray
    end_s: np.ndarray
    rmse_deg: np.ndarray
    bias_deg: np.ndarray
    rom_error_deg: np.ndarray
    peak_error_deg: np.ndarray
    cmc: float = float("nan")
    more: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class AngleAgreement(_Record):
    """One joint angle's agreement between the IMU and the optical reference
    (:func:`motionlab.validation.agreement.agreement`; one value of
    :attr:`AngleAgreements.columns`), in degrees, error = IMU − optical.

    ``rmse_deg``, ``bias_deg`` (mean error), ``sd_deg`` (its SD, ddof 1), ``max_abs_deg``,
    ``rmse_centred_deg`` (RMSE without the bias), ``r`` (Pearson), ``cmc`` (Ferrari's CMC of the
    two curves), ``loa_deg`` ([lower, upper]: Bland–Altman 95 % limits of agreement) over
    ``n_samples`` samples (each NaN below two); ``imu_deg`` and ``ref_deg`` (N,): the two curves
    on :attr:`AngleAgreements.time_s`; ``repetitions``: per repetition
    (:class:`RepetitionAgreement`; ``None`` with fewer than two repetitions). ``withheld``: why
    the validation cannot state this agreement (a poor clock sync, a sensor's alignment the
    movement did not determine, too little compared; :func:`motionlab.validation.withhold`),
    its statistics then NaN and its curves kept; ``None`` when stated.
    """

    rmse_deg: float
    bias_deg: float
    sd_deg: float
    max_abs_deg: float
    rmse_centred_deg: float
    r: float
    cmc: float
    loa_deg: list[float]
    n_samples: int
    imu_deg: np.ndarray | None = None
    ref_deg: np.ndarray | None = None
    repetitions: RepetitionAgreement | None = None
    withheld: str | None = None
    more: dict[str, Any] = field(default_factory=dict)

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {"repetitions": (RepetitionAgreement, 0)}


@dataclass
class AngleAgreements:
    """The joint angles of a validation (:attr:`Validation.angles`): ``time_s`` (N,) s, the IMU
    angle table's time base, and ``columns`` ``{angle column: AngleAgreement}`` in the order
    compared. Stored flat, as before the record: ``time_s`` and one group per column; other
    keys are kept in ``more``.
    """

    time_s: np.ndarray | None = None
    columns: dict[str, AngleAgreement] = field(default_factory=dict)
    more: dict[str, Any] = field(default_factory=dict)

    def to_tree(self) -> dict[str, Any]:
        """``{"time_s": ..., column: agreement tree, ...}``."""
        return _timed_tree(self.time_s, self.columns, self.more)

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> AngleAgreements:
        """The agreements of a stored tree (see :meth:`to_tree`)."""
        return cls(*_timed_entries(tree, AngleAgreement))


@dataclass(frozen=True)
class ValidationReference(_Record):
    """What a validation's reference was (:attr:`Validation.reference`; every field ``None``
    and nothing stored for a validation run outside :func:`motionlab.stages.validate`).

    ``kind``: ``markers``, ``segments`` (a CSV of segment quaternions, with its ``frames``:
    ``anatomical`` or ``body``) or ``model_angles`` (a C3D of model joint angles such as
    Plug-in Gait's, with its ``file`` and ``mapping`` ``{angle column: source}``, the source
    as ``label.X`` (its output and component; ``-`` in front: the sign flipped)).
    """

    kind: str | None = None
    frames: str | None = None
    file: str | None = None
    mapping: dict[str, str] | None = None
    more: dict[str, Any] = field(default_factory=dict)


@dataclass
class Validation(_Record):
    """Agreement with an optical reference (:func:`motionlab.validation.validate`).

    ``mode`` (``full`` or ``heading`` alignment; ``angles`` against model joint angles),
    ``marker_set``, ``movement_only``, ``pairs`` ``{sensor: segment}``; ``sync``: the
    optical-to-IMU time alignment (:class:`OpticalSync`); ``alignment``: the spatial alignment
    (:class:`SpatialAlignment`; ``None`` when a file holds none or an empty one); ``optical``
    ``{segment: OpticalSegmentInfo}``; ``orientation``: the orientation errors per sensor
    (:class:`OrientationErrors`); ``angles``: the IMU and optical angle curves and their
    agreement per angle column (:class:`AngleAgreements`; ``None`` without a protocol);
    ``notes``: lines the user should read; ``reference``: what the reference was
    (:class:`ValidationReference`).
    """

    mode: str
    marker_set: str = ""
    movement_only: bool = False
    pairs: dict[str, str] = field(default_factory=dict)
    sync: OpticalSync = field(default_factory=OpticalSync)
    alignment: SpatialAlignment | None = None
    optical: dict[str, OpticalSegmentInfo] = field(default_factory=dict)
    orientation: OrientationErrors = field(default_factory=OrientationErrors)
    angles: AngleAgreements | None = None
    notes: list[str] = field(default_factory=list)
    reference: ValidationReference = field(default_factory=ValidationReference)
    more: dict[str, Any] = field(default_factory=dict)

    _nested: ClassVar[dict[str, tuple[Any, int]]] = {
        "sync": (OpticalSync, 0),
        "alignment": (SpatialAlignment, 0),
        "optical": (OpticalSegmentInfo, 1),
        "orientation": (OrientationErrors, 0),
        "angles": (AngleAgreements, 0),
        "reference": (ValidationReference, 0),
    }

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> Validation:
        """The validation of a stored tree (see :meth:`to_tree`; empty ``alignment``: none)."""
        return super().from_tree({k: v for k, v in tree.items() if k != "alignment" or v})


# -------------------------------------------------------------------------------- container

#: the stages in the order they run; each is an attribute of :class:`Results`
STAGES = (
    "clock_sync",
    "fusion",
    "calibration",
    "angles",
    "heading",
    "metrics",
    "gait",
    "validation",
)


@dataclass
class Results:
    """Every stage's result of a session (see the module docstring's table)."""

    clock_sync: ClockSync | None = None
    fusion: dict[str, FusionEntry] = field(default_factory=dict)
    calibration: SegmentCalibration | None = None
    angles: AngleTable | None = None
    heading: dict[str, HeadingCorrection] | None = None
    metrics: Metrics | None = None
    gait: Gait | None = None
    validation: Validation | None = None
    #: stages written by a newer motionlab, kept as trees so that a round trip loses nothing
    more: dict[str, Any] = field(default_factory=dict)

    def stages(self) -> list[str]:
        """Names of the stages that hold a result, in :data:`STAGES` order."""
        done = [s for s in STAGES if getattr(self, s) not in (None, {})]
        return done + list(self.more)

    def to_tree(self) -> dict[str, Any]:
        """``{stage: tree}`` of the stages that hold a result (``/results`` of the file)."""
        tree: dict[str, Any] = {}
        for stage in self.stages():
            value = getattr(self, stage) if stage in STAGES else self.more[stage]
            if stage == "fusion":
                tree[stage] = {k: e.to_tree() for k, e in value.items()}
            elif stage == "heading":
                tree[stage] = {k: c.to_tree() for k, c in value.items()}
            elif stage in STAGES:
                tree[stage] = value.to_tree()
            else:
                tree[stage] = value
        return tree

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> Results:
        """The results of a stored ``/results`` tree (current schema; see
        :func:`motionlab.session.load_session` for the older ones)."""
        out = cls()
        readers = {
            "clock_sync": ClockSync.from_tree,
            "fusion": lambda t: {k: FusionEntry.from_tree(e) for k, e in t.items()},
            "calibration": SegmentCalibration.from_tree,
            "angles": AngleTable.from_tree,
            "heading": lambda t: {k: HeadingCorrection.from_tree(c) for k, c in t.items()},
            "metrics": Metrics.from_tree,
            "gait": Gait.from_tree,
            "validation": Validation.from_tree,
        }
        for stage, sub in tree.items():
            if stage in readers:
                setattr(out, stage, readers[stage](sub))
            else:
                out.more[stage] = sub
        return out
