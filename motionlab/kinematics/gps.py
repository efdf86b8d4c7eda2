"""Gait Profile Score (GPS) and Movement Analysis Profile (MAP), Baker et al. (2009, Gait
Posture 30:265).

For each kinematic variable ``i`` the Gait Variable Score is the RMS difference between the
subject's mean curve (one side's strides, 0-100 % from initial contact) and the normative mean
curve, over the cycle (51 points, every 2 %, as Baker et al.): ``GVS_i = sqrt(mean_t (x_i(t) −
x̄_i(t))²)`` (deg). The GPS is the RMS of the GVS: ``GPS = sqrt(mean_i GVS_i²)``; the MAP is the
bar chart of the GVS, with the GPS of each side and of both.

Variables (the sensors of the walk protocol give them): pelvic tilt, obliquity, rotation; hip
flexion, adduction, rotation; knee flexion, each per side (the pelvis with the side's signs,
:func:`motionlab.kinematics.pelvis.side_angles`). Ankle and foot progression need foot sensors and
are left out, so this GPS has 7 variables per side instead of Baker's 9 (15 with the pelvis once
for both sides); the overall GPS uses the pelvis once (the right side's cycles) and hip and knee of
both sides: 11 variables.

Normative curves: ``report_data/gait_normative.csv`` (see its YAML for sources, licence and why
they are approximate).

A score is only as good as its inputs (:func:`gated_profile`): a variable's GVS is given only when
its angle is ``determined`` (:mod:`motionlab.segments.grades`; the pelvis variables by the pelvis
frame's grade) and its side has at least :data:`~.spatiotemporal.MIN_STRIDES` kept strides; a
side's GPS only when every variable of that side is given (one whose sensor is missing, the
pelvis's for the pelvis and the hips, too: a knee-only score is no GPS), the overall GPS only
when both are.
``withheld`` then says which variables are missing and why ("GPS not computed: right knee flexion
not determined").
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

from motionlab.kinematics.joint_types import angle_columns
from motionlab.kinematics.spatiotemporal import MIN_STRIDES, too_few
from motionlab.results import JointGrades, MovementProfile
from motionlab.segments.grades import _frame_grade

if TYPE_CHECKING:
    from motionlab.protocol import Protocol
    from motionlab.results import SegmentCalibration

DATA = Path(__file__).resolve().parent.parent / "report_data"  # as motionlab.report.normative
NORMATIVE = DATA / "gait_normative.csv"
NORMATIVE_SOURCES = DATA / "gait_normative.yaml"
PELVIS = ("pelvis_tilt", "pelvis_obliquity", "pelvis_rotation")
#: the joint angles of the GPS, ``<joint type>_<angle>`` of the joint table's names
JOINT_VARIABLES = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_flexion")
VARIABLES = PELVIS + JOINT_VARIABLES
GPS_POINTS = np.arange(0, 101, 2)  # % of the cycle (Baker et al. 2009)
#: why a variable of a measured side has no score: its sensor is missing (the pelvis's, for the
#: pelvis and the hips): the GPS is then not computed, as a knee-only "GPS" is no GPS
NOT_MEASURED = "not measured (no sensor)"
#: why a joint variable has no score when the protocol has no such joint on that side (the knee
#: protocol's hips, though its pelvis and thigh sensors are there)
NOT_IN_PROTOCOL = "not measured (no such joint in the protocol)"


@lru_cache(maxsize=1)
def _table() -> pd.DataFrame:
    return pd.read_csv(NORMATIVE)


def normative(variable: str, percent: np.ndarray = GPS_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Normative mean and SD (deg) of ``variable`` at ``percent`` (0-100)."""
    t = _table()
    rows = t[t["variable"] == variable].sort_values("percent_pct")
    if rows.empty:
        raise KeyError(variable)
    x = rows["percent_pct"].to_numpy(dtype=float)
    mean = PchipInterpolator(x, rows["mean_deg"].to_numpy(dtype=float))(percent)
    sd = PchipInterpolator(x, rows["sd_deg"].to_numpy(dtype=float))(percent)
    return mean, sd


def gvs(curve: np.ndarray, variable: str) -> float:
    """Gait Variable Score (deg) of a mean curve sampled at 0-100 % (any number of points)."""
    curve = np.asarray(curve, dtype=float)
    pct = np.linspace(0.0, 100.0, len(curve))
    x = np.interp(GPS_POINTS, pct, curve)
    mean, _ = normative(variable)
    return float(np.sqrt(np.nanmean((x - mean) ** 2)))


def gps(scores: dict[str, float]) -> float:
    """GPS (deg): the RMS of the given GVS values (NaN ignored)."""
    v = np.array([s for s in scores.values() if np.isfinite(s)])
    return float(np.sqrt(np.mean(v**2))) if len(v) else float("nan")


def population_gps(variables: tuple[str, ...] = VARIABLES) -> float:
    """Expected GPS (deg) of a subject from the normative population: the RMS of the normative SD
    over variables and the cycle (each GVS² of a normal subject has the mean SD² of its
    variable)."""
    return float(np.sqrt(np.mean([np.mean(normative(v)[1] ** 2) for v in variables])))


def _profile(scores: dict[str, dict[str, float]]) -> MovementProfile:
    overall = {f"r_{v}": x for v, x in scores.get("r", {}).items()}
    overall |= {f"l_{v}": x for v, x in scores.get("l", {}).items() if v not in PELVIS}
    if "r" not in scores:
        overall |= {f"l_{v}": x for v, x in scores.get("l", {}).items() if v in PELVIS}
    used = tuple(v for v in VARIABLES if any(v in x for x in scores.values()))
    return MovementProfile(
        gvs=scores,
        gps={side: gps(x) for side, x in scores.items()} | {"overall": gps(overall)},
        population_gps_deg=population_gps(used) if used else float("nan"),
        variables=list(used),
    )


def movement_analysis_profile(curves: dict[str, dict[str, np.ndarray]]) -> MovementProfile:
    """MAP and GPS from mean curves ``{side: {variable: (P,) deg over 0-100 %}}``
    (:class:`~motionlab.results.MovementProfile`); a missing variable is left out. Ungraded:
    see :func:`gated_profile`.
    """
    scores: dict[str, dict[str, float]] = {}
    for side, by_var in curves.items():
        scores[side] = {v: gvs(by_var[v], v) for v in VARIABLES if v in by_var}
    return _profile(scores)


def variable_grades(
    protocol: Protocol, calibration: SegmentCalibration | None
) -> dict[str, dict[str, tuple[str, str]]]:
    """``{side: {variable: (grade, reason)}}`` of the GPS variables the protocol's joints give:
    hip and knee angles by their joint angle's grade, the pelvis variables by the pelvis frame's
    (:func:`motionlab.segments.grades._frame_grade`), a hip or knee the protocol has on the
    other side only or not at all :data:`NOT_IN_PROTOCOL`. A calibration without grades (a
    session calibrated before they existed) has everything else ``determined``."""
    graded = calibration.grades if calibration is not None else {}
    out: dict[str, dict[str, tuple[str, str]]] = {"r": {}, "l": {}}
    for joint in protocol.joints.values():
        if joint.side not in out:
            continue
        entry = graded.get(joint.name) or JointGrades()
        grades, reasons = entry.grades, entry.reasons
        for k, (angle, _) in enumerate(angle_columns(joint)):
            v = f"{joint.type}_{angle}"
            if v in VARIABLES:
                g = str(grades[k]) if k < len(grades) else "determined"
                out[joint.side][v] = (g, str(reasons[k]) if k < len(reasons) else "")
    for graded_side in filter(None, out.values()):  # a side the protocol measures
        for v in JOINT_VARIABLES:
            graded_side.setdefault(v, (NOT_IN_PROTOCOL, ""))
    segments = calibration.segments if calibration is not None else {}
    if "pelvis" in protocol.segments and (not graded or "pelvis" in segments):
        frame = ("determined", "")
        if graded:
            frame = _frame_grade("pelvis", segments.get("pelvis"))
        for side in out:
            out[side] |= dict.fromkeys(PELVIS, frame)
    return out


def gated_profile(
    mp: MovementProfile,
    grades: dict[str, dict[str, tuple[str, str]]],
    strides: dict[str, int] | None = None,
) -> MovementProfile:
    """The MAP and GPS of :func:`movement_analysis_profile` keeping only what its inputs allow
    (module docstring): the GVS of ``determined`` variables (``grades`` from
    :func:`variable_grades`; a variable not graded counts as determined) of sides with at least
    ``MIN_STRIDES`` kept strides (``strides`` ``{side: n}``; None: not checked), a side's GPS only
    with all its variables, the overall GPS only with both sides'. Sets ``withheld`` ``{side:
    {variable: why}}`` and ``not_computed``: a sentence naming what is missing, empty when the
    overall GPS is given. Applying it again with the same inputs changes nothing."""
    strides = strides or {}
    scores: dict[str, dict[str, float]] = {}
    withheld: dict[str, dict[str, str]] = {}
    for side in ("r", "l"):
        before = (mp.withheld or {}).get(side, {})
        gone: dict[str, str] = {}
        curves = mp.gvs.get(side, {})
        n = strides.get(side)
        for v in VARIABLES:
            grade = grades.get(side, {}).get(v, ("determined", ""))[0]
            if v not in curves and v not in before and grade == "determined":
                if curves:  # a side's GPS of fewer variables is not the GPS (knee alone)
                    gone[v] = NOT_MEASURED
                continue  # a leg without sensors: no score of that side
            if grade == "determined" and before.get(v) == NOT_MEASURED:
                gone[v] = before[v]
            elif grade == "determined" and v in before and "steady strides" in before[v]:
                gone[v] = before[v]  # its score was withheld for its strides: still is
            elif grade != "determined" or v in before:
                gone[v] = grade if grade != "determined" else before[v]
            elif n is not None and n < MIN_STRIDES:
                gone[v] = too_few(n)
        kept = {v: x for v, x in curves.items() if v not in gone}
        if kept:
            scores[side] = kept
        if gone:
            withheld[side] = gone
    out = _profile(scores)
    scored = dict(out.gps)
    for side in ("r", "l"):
        if withheld.get(side):
            scored[side] = float("nan")
    if withheld:
        scored["overall"] = float("nan")
    named = [set(x) for x in scores.values()] + [set(x) for x in withheld.values()]
    return replace(
        out,
        gps=scored,
        population_gps_deg=(
            out.population_gps_deg if mp.population_gps_deg is None else mp.population_gps_deg
        ),
        variables=[v for v in VARIABLES if any(v in x for x in named)],
        withheld=withheld,
        not_computed=not_computed(withheld),
    )


def not_computed(withheld: dict[str, dict[str, str]]) -> str:
    """``'GPS not computed: pelvis tilt, hip flexion weak; right knee flexion not determined'``
    (the grade only, the reasons are on the calibration page; a variable missing on both sides
    for one reason is named once, without side); empty when nothing is withheld."""
    names = {"r": "right ", "l": "left "}
    groups: dict[str, list[str]] = {}
    for v in VARIABLES:
        why = {side: gone[v] for side, gone in withheld.items() if v in gone}
        both = len(why) == 2 and len(set(why.values())) == 1
        for side, w in why.items():
            label = v.replace("_", " ")
            if both:
                if side == "r":
                    groups.setdefault(w, []).append(label)
            else:
                groups.setdefault(w, []).append(names.get(side, "") + label)
    parts = [f"{', '.join(vs)} {w}" for w, vs in groups.items()]
    return "GPS not computed: " + "; ".join(parts) if parts else ""
