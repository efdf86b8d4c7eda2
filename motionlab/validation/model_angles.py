"""A reference of joint angles computed by another model (Plug-in Gait and the like), as C3D
``POINT:ANGLES`` model outputs (:mod:`motionlab.io.c3d` keeps them apart from the markers).

The mapping from model-output labels to motionlab angle columns (:data:`PLUGIN_GAIT`, written out in
the README, "Validate"; built from the joint table's
:attr:`~motionlab.kinematics.joint_types.JointType.plugin_gait`) follows Vicon's Plug-in Gait
reference guide: each ``*Angles`` point holds three angles in degrees as X, Y, Z, already in
clinical signs on both sides (flexion, adduction/varus and internal rotation positive; the left side
is mirrored by the model), which are motionlab's signs (docs/conventions.md), so every sign is +1:

====================  ======  ===========================  ====
label                 comp.   motionlab column             sign
====================  ======  ===========================  ====
R/LHipAngles          X Y Z   hip_<s>_flexion / adduction / rotation     +1
R/LKneeAngles         X Y Z   knee_<s>_flexion / adduction / rotation    +1
R/LElbowAngles        X       elbow_<s>_flexion                          +1
R/LAnkleAngles        X       ankle_<s>_dorsiflexion                     +1
====================  ======  ===========================  ====

Plug-in Gait's elbow Y and Z are not the carrying angle and pronation (pronation lives in its wrist
angles), so they are left out; of the ankle's only dorsiflexion (X) is mapped: its Y and Z have not
been checked against the ISB ankle's inversion and rotation. motionlab's own C3D export
(``<joint>_angles`` with X, Y, Z the joint's three columns in decomposition order) maps by the
protocol. Other labels or signs: a YAML angle map (:func:`load_angle_map`)::

    knee_r_flexion_deg: {label: RKneeAngles, component: x, sign: 1}
    knee_r_rotation_deg: {label: RKneeAngles, component: z, sign: -1}

**Caveat:** the model's segment frames (from its markers and its joint centres) are not the
IMU calibration's, so constant offsets between the curves are expected, above all in
ab/adduction and rotation; the offset-free RMSE (``rmse_centred_deg``) and r are the numbers
that compare the two systems' movement. Every result carries this caveat in its notes.

Time sync: the joint angles are the only signal both sides share, so the clock model is fitted
on the angular rates of each joint's first (flexion) angle, IMU against reference
(:func:`motionlab.validation.time_alignment.synchronise` on signed scalar rates; both from
orientations, so no gyroscope timing is involved), falling back to one global offset when
windows fail.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.kinematics.angle_filter import smoothed
from motionlab.kinematics.joint_types import JOINT_TYPES, angle_columns, column_name
from motionlab.kinematics.session_angles import session_angles
from motionlab.protocol import Protocol
from motionlab.results import (
    AlignmentRotation,
    AngleAgreements,
    AngleTable,
    OrientationErrors,
    SpatialAlignment,
    Validation,
    ValidationReference,
)
from motionlab.session import MarkerSet, Session, estimate_rate
from motionlab.validation import angle_agreement, movement_mask, withhold
from motionlab.validation.agreement import repetitions
from motionlab.validation.time_alignment import no_sync, synchronise
from motionlab.validation.time_offset import sync_notes
from motionlab.yamlsafe import LineLoader, load_yaml, read_yaml_text

CAVEAT = (
    "the reference angles come from another model whose segment frames differ from the IMU "
    "calibration's: constant offsets are expected (above all in ab/adduction and rotation); "
    "compare the offset-free RMSE (rmse_centred_deg) and r"
)
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class AngleSource:
    """One reference angle: ``component`` (0, 1, 2 = X, Y, Z) of model output ``label``, times
    ``sign``."""

    label: str
    component: int
    sign: float = 1.0

    def describe(self) -> str:
        return f"{'-' if self.sign < 0 else ''}{self.label}.{'XYZ'[self.component]}"


def _plugin_gait() -> dict[str, AngleSource]:
    out = {}
    for jt in JOINT_TYPES.values():
        if jt.plugin_gait is None:
            continue
        label, n = jt.plugin_gait
        for side in ("r", "l"):
            for i, name in enumerate((jt.angle_names or ())[:n]):
                out[column_name(jt.name, side, name)] = AngleSource(f"{side.upper()}{label}", i)
    return out


#: motionlab angle column → its Plug-in Gait source (see the module docstring)
PLUGIN_GAIT: dict[str, AngleSource] = _plugin_gait()


def load_angle_map(path: str | Path) -> dict[str, AngleSource]:
    """An angle map YAML: ``column: {label: NAME, component: x|y|z, sign: 1|-1}``."""
    path = Path(path)
    remedy = "write 'column: {label: RKneeAngles, component: x, sign: 1}'"
    # LineLoader: a column written twice is refused (YAML keeps the last one silently)
    doc = load_yaml(read_yaml_text(path, "angle map", remedy), LineLoader, path, remedy)
    if not isinstance(doc, dict) or not doc:
        raise InputError(
            "is not a mapping of angle columns",
            path,
            remedy="write 'knee_r_flexion_deg: {label: RKneeAngles, component: x}'",
        )
    out = {}
    for col, spec in doc.items():
        ok = isinstance(spec, dict) and isinstance(spec.get("label"), str)
        comp = str(spec.get("component", "")).lower() if ok else ""
        sign = spec.get("sign", 1) if ok else 1
        if (
            not ok
            or comp not in _AXES
            or isinstance(sign, bool)  # true == 1 in Python, no sign in an angle map
            or sign not in (1, -1)
            or not str(col).endswith("_deg")
        ):
            raise InputError(
                f"entry {col!r} is {spec!r}",
                path,
                f"key {col}",
                "give '<column>_deg: {label: NAME, component: x|y|z, sign: 1|-1}'",
            )
        out[str(col)] = AngleSource(spec["label"], _AXES[comp], float(sign))
    return out


def default_mapping(reference: MarkerSet, protocol: Protocol | None) -> dict[str, AngleSource]:
    """Plug-in Gait's labels, and motionlab's own ``<joint>_angles`` (by the protocol)."""
    out = dict(PLUGIN_GAIT)
    if protocol is not None:
        for name, joint in protocol.joints.items():
            if f"{name}_angles" in reference.model_outputs:
                for i, (_, col) in enumerate(angle_columns(joint)):
                    out[col] = AngleSource(f"{name}_angles", i)
    return out


def has_model_angles(reference: MarkerSet) -> bool:
    """Whether the reference holds joint angles as model outputs."""
    return bool(reference.outputs_of("angles"))


def reference_angles(
    reference: MarkerSet, mapping: dict[str, AngleSource], columns: list[str]
) -> dict[str, np.ndarray]:
    """``column → (M,) deg`` on the reference clock, for the IMU ``columns`` the mapping finds
    among the reference's angle outputs (``rad`` outputs are converted)."""
    outputs = reference.outputs_of("angles")
    out = {}
    for col in columns:
        src = mapping.get(col)
        if src is None or src.label not in outputs:
            continue
        o = outputs[src.label]
        values = np.asarray(o.data, dtype=float)[:, src.component] * src.sign
        if o.unit.strip().lower() in ("rad", "radian", "radians"):
            values = np.degrees(values)
        out[col] = values
    return out


def _interp(t: np.ndarray, y: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Linear interpolation; NaN outside ``t`` and next to NaN samples."""
    out = np.full(len(t_new), np.nan)
    k = np.searchsorted(t, t_new, side="right") - 1
    inside = (t_new >= t[0]) & (t_new <= t[-1])
    k = np.clip(k, 0, len(t) - 2)
    w = (t_new - t[k]) / (t[k + 1] - t[k])
    est = np.where(w <= 0, y[k], (1 - w) * y[k] + w * y[k + 1])
    out[inside] = est[inside]
    return out


def _rate_rad_s(t: np.ndarray, deg: np.ndarray) -> np.ndarray:
    """Angular rate (rad/s) of a curve in degrees (central differences; NaN stays NaN)."""
    return np.gradient(np.radians(deg), t)


def validate_model_angles(
    session: Session,
    reference: MarkerSet,
    protocol: Protocol | None = None,
    *,
    mapping: dict[str, AngleSource] | None = None,
    sync: bool = True,
    movement_only: bool = False,
    seed: int = 0,
) -> Validation:
    """Compare the session's joint angles with model joint angles of ``reference``.

    The IMU angles are the session's ``angles`` results (else computed from the calibration
    with ``protocol``). Returns the :class:`~motionlab.results.Validation` (which
    :func:`motionlab.stages.validate` stores), shaped as :func:`motionlab.validation.validate`'s
    (``sync``, ``alignment`` (mode ``none``: no frames to align), ``orientation`` (no sensor:
    none is compared), ``angles``, ``notes``) with ``reference``: ``kind``
    (``model_angles``), ``file`` and ``mapping`` (column → source).
    """
    table = session.results.angles
    if table is None:
        if protocol is None:
            raise InputError(
                "the session has no joint angles",
                where="validation",
                remedy="compute the angles stage first, or pass protocol=",
                argument="protocol",
            )
        columns = session_angles(session, protocol, session.results.calibration)
        table = AngleTable.from_columns(columns)
    t = np.asarray(table.time, dtype=float)
    columns = [k for k in table.data if k.endswith("_deg")]
    given = mapping is not None
    mapping = mapping if given else default_mapping(reference, protocol)
    outputs = reference.outputs_of("angles")
    absent = sorted({src.label for src in mapping.values() if src.label not in outputs})
    if given and absent:  # a map the user wrote names what the file holds: a typo is no note
        raise InputError(
            f"the angle map names {', '.join(absent)}, which the file does not hold (its angle "
            f"outputs: {', '.join(list(outputs)[:8]) or 'none'})",
            reference.attrs.get("source_file"),
            "POINT:ANGLES",
            "correct the label in the angle map",
            argument="angle_map",
        )
    ref = reference_angles(reference, mapping, columns)
    if not ref:
        names = ", ".join(list(reference.outputs_of("angles"))[:8]) or "none"
        raise InputError(
            f"none of its angle outputs ({names}) maps to the session's angles "
            f"({', '.join(columns[:6])})",
            reference.attrs.get("source_file"),
            "POINT:ANGLES",
            "pass angle_map=map.yaml ('knee_r_flexion_deg: {label: RKneeAngles, component: x}')",
            argument="angle_map",
        )
    t_ref = np.asarray(reference.time, dtype=float)
    primary = _primaries(list(ref), protocol)
    if sync:
        imu_sig, ref_sig = [], []
        for col in primary:
            imu_sig.append((t, _rate_rad_s(t, np.asarray(table.data[col], float))))
            ref_sig.append((t_ref, _rate_rad_s(t_ref, ref[col])))
        clock = synchronise(imu_sig, ref_sig, seed=seed, ref_is_rate=True)
    else:
        clock = no_sync()
    tq = clock.model.to_reference(t)
    mask = None
    notes = [CAVEAT]
    if movement_only:
        labels = [k for k in session.sensors if session.sensors[k].gyr is not None]
        if labels:
            mask = movement_mask(session, labels, t)
        else:
            notes.append("movement_only: no gyroscope to find movement; all samples used")
    rate = estimate_rate(t)
    angles = AngleAgreements(time_s=t)
    for col, values in ref.items():
        ref_deg = smoothed(_interp(t_ref, values, tq), rate, table.lowpass_hz)  # as the IMU's
        imu_deg = np.asarray(table.data[col], dtype=float)
        reps = repetitions(ref_deg, rate) if col in primary else None
        angles.columns[col] = angle_agreement(imu_deg, ref_deg, mask, reps, t)
    unmapped = [c for c in columns if c not in ref]
    if unmapped:
        notes.append(f"no reference for {', '.join(unmapped)}")
    sync_record = clock.record("joint angle rates" if sync else "", [])
    notes += sync_notes(sync_record) if sync else []
    result = Validation(
        mode="angles",
        marker_set=reference.name,
        movement_only=movement_only,
        pairs={},
        sync=sync_record,
        alignment=SpatialAlignment("none", AlignmentRotation(rot.IDENTITY.copy(), 0.0)),
        optical={},
        orientation=OrientationErrors(time_s=t),
        angles=angles,
        reference=ValidationReference(
            kind="model_angles",
            file=str(reference.attrs.get("source_file", "")),
            mapping={col: mapping[col].describe() for col in ref},
        ),
        notes=notes,
    )
    return withhold(result, protocol)


def _primaries(columns: list[str], protocol: Protocol | None) -> list[str]:
    """The first (flexion) angle of each joint among ``columns`` (all flexion columns without a
    protocol; every column when none is a flexion)."""
    if protocol is not None:
        out = [angle_columns(j)[0][1] for j in protocol.joints.values()]
        out = [c for c in out if c in columns]
        if out:
            return out
    out = [c for c in columns if "_flexion_" in c]
    return out or columns
