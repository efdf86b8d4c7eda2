"""Anthropometry and the kinematic tree of the simulated subject.

Segment lengths are fractions of body height ``H`` after Winter (2009, *Biomechanics and Motor
Control of Human Movement*, 4th ed., Fig. 4.1): thigh (hip joint to knee) 0.245 H, shank (knee to
ankle) 0.246 H, ankle height 0.039 H, foot length 0.152 H, upper arm 0.186 H, forearm 0.146 H,
shoulder width 0.259 H, hip height 0.530 H, shoulder height 0.818 H. The distance between the hip
joint centres (0.10 H) and the position of L5/S1 are approximations of ours.

Conventions: every segment frame is ISB style (x anterior, y proximal, z to the subject's right in
the standing pose) with its origin at the proximal joint centre; positions in m. On the left side
a "lateral" offset is ``-z``. The tree (parent, joint channel, origin in the parent frame)::

    pelvis (root, origin midway between the hip joint centres)
    ├── thigh_s ── shank_s ── foot_s          (hip_s, knee_s, ankle_s)
    ├── lumbar                                (half the lumbar rotation; optional sensor)
    └── thorax ── upperarm_s ── forearm_s     (lumbar, shoulder_s, elbow_s)
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from motionlab.errors import InputError
from motionlab.kinematics.segment_types import kind_side

SEGMENTS = (
    "pelvis",
    "thigh_r",
    "shank_r",
    "foot_r",
    "thigh_l",
    "shank_l",
    "foot_l",
    "lumbar",
    "thorax",
    "upperarm_r",
    "forearm_r",
    "upperarm_l",
    "forearm_l",
)


# Anatomical landmarks in the segment frame, as (x, y, lateral) in units of H; ``y`` may name a
# segment length ("-L" = the distal joint). Aliases map common marker-set names to one entry.
_LANDMARKS: dict[str, dict[str, tuple[float, float | str, float]]] = {
    "pelvis": {
        "ASIS": (0.035, 0.030, 0.070),
        "PSIS": (-0.060, 0.040, 0.025),
        "SACR": (-0.065, 0.035, 0.0),
        "GT": (0.0, 0.0, 0.095),
    },
    "thigh": {
        "GT": (0.0, 0.005, 0.045),
        "LE": (0.0, "-L", 0.029),
        "ME": (0.0, "-L", -0.029),
        "THI": (0.0, -0.12, 0.045),
    },
    "shank": {
        "FH": (-0.005, -0.025, 0.025),
        "TT": (0.025, -0.040, 0.0),
        "LM": (-0.005, "-L", 0.020),
        "MM": (0.005, "-L", -0.020),
        "TIB": (0.0, -0.12, 0.030),
        "LE": (0.0, 0.0, 0.029),
        "ME": (0.0, 0.0, -0.029),
    },
    "foot": {
        "CA": (-0.030, -0.030, 0.0),
        "MT1": (0.100, -0.035, -0.020),
        "MT5": (0.090, -0.035, 0.025),
        "TOE": (0.115, -0.035, 0.0),
    },
    "thorax": {
        "C7": (-0.040, 0.290, 0.0),
        "T8": (-0.060, 0.180, 0.0),
        "T10": (-0.060, 0.140, 0.0),
        "IJ": (0.040, 0.255, 0.0),
        "PX": (0.070, 0.170, 0.0),
        "AC": (-0.005, 0.260, 0.130),
        "T12": (-0.060, 0.100, 0.0),
        "L1": (-0.058, 0.080, 0.0),
    },
    "lumbar": {"L3": (-0.055, 0.030, 0.0), "L1": (-0.055, 0.075, 0.0)},
    "upperarm": {
        "GH": (0.0, 0.0, 0.0),
        "AC": (0.0, 0.020, 0.010),
        "LE": (0.0, "-L", 0.020),
        "ME": (0.0, "-L", -0.022),
    },
    "forearm": {
        "OL": (-0.015, 0.0, 0.0),
        "LE": (0.0, 0.0, 0.020),
        "ME": (0.0, 0.0, -0.022),
        "RS": (0.0, "-L", 0.016),
        "US": (0.0, "-L", -0.016),
    },
}
_ALIASES = {
    "ASI": "ASIS",
    "PSI": "PSIS",
    "FLE": "LE",
    "FME": "ME",
    "HLE": "LE",
    "HME": "ME",
    "EL": "LE",
    "EM": "ME",
    "LEP": "LE",
    "MEP": "ME",
    "KNE": "LE",
    "KNEM": "ME",
    "ELB": "LE",
    "ELBM": "ME",
    "LMAL": "LM",
    "MMAL": "MM",
    "FAL": "LM",
    "TAM": "MM",
    "ANK": "LM",
    "MED": "MM",
    "HEE": "CA",
    "HEEL": "CA",
    "FCC": "CA",
    "FM1": "MT1",
    "FM5": "MT5",
    "FM2": "TOE",
    "CLAV": "IJ",
    "SJN": "IJ",
    "STRN": "PX",
    "SXS": "PX",
    "XP": "PX",
    "CV7": "C7",
    "TV8": "T8",
    "TV10": "T10",
    "LHE": "LE",
    "MHE": "ME",
    "GHJ": "GH",
    "SHO": "AC",
    "ACR": "AC",
    "SA": "AC",
    "OLE": "OL",
    "RSP": "RS",
    "USP": "US",
    "WRA": "RS",
    "WRB": "US",
    "TTC": "TT",
    "FAX": "FH",
    "LFE": "LE",
    "MFE": "ME",
}


# Where a strap may sit, per segment kind: y range (proximal, distal end; units of H, or of the
# segment length for the long segments in _LONG), centre of the cross-section along x (H), its
# semi-axes (x, lateral; H) at the two ends, and the angle range around it (rad, 0 = anterior,
# π/2 = lateral). Circumferences after adult anthropometric tables (thigh about 50 cm at mid-
# thigh, calf 37 cm, ankle 22 cm, upper arm 30 cm, forearm 26 cm, wrist 16 cm, for H = 1.75 m).
_LONG = ("thigh", "shank", "upperarm", "forearm")
_SURFACES: dict[str, tuple] = {
    "thigh": (-0.15, -0.85, 0.0, (0.050, 0.050), (0.033, 0.033), (0.0, 2 * np.pi)),
    "shank": (-0.12, -0.80, 0.0, (0.034, 0.034), (0.022, 0.022), (0.0, 2 * np.pi)),
    "upperarm": (-0.20, -0.85, 0.0, (0.028, 0.028), (0.024, 0.024), (0.0, 2 * np.pi)),
    "forearm": (-0.15, -0.90, 0.0, (0.024, 0.024), (0.015, 0.015), (0.0, 2 * np.pi)),
    "pelvis": (0.050, 0.0, -0.015, (0.050, 0.095), (0.050, 0.095), (0.0, 2 * np.pi)),
    "lumbar": (0.060, 0.010, 0.0, (0.055, 0.080), (0.055, 0.080), (0.8 * np.pi, 1.2 * np.pi)),
    "thorax": (0.220, 0.120, 0.005, (0.065, 0.090), (0.065, 0.090), (0.0, 2 * np.pi)),
}


def _candidates(name: str) -> list[tuple[str, str]]:
    """(name, side) to look up: ``LE_r``, ``R_LE``, ``RLE`` → ``('LE', 'r')`` (upper case)."""
    n = name.upper()
    out = [(n, "")]
    for side in "RL":
        for head, tail in ((f"{side}_", ""), (f"{side}.", ""), ("", f"_{side}"), ("", f".{side}")):
            if n.startswith(head) and n.endswith(tail) and len(n) > len(head + tail):
                out.append((n[len(head) : len(n) - len(tail)], side.lower()))
        if n.startswith(side) and len(n) > 2:
            out.append((n[1:], side.lower()))
    return out


@dataclass
class Body:
    """A subject of a given height (m): segment lengths, joint offsets, landmarks, sensor sites."""

    height: float = 1.75
    lengths: dict[str, float] = field(init=False)

    def __post_init__(self) -> None:
        if not 0.5 <= self.height <= 2.5:
            raise InputError(
                f"height {self.height} m is outside 0.5–2.5 m",
                where="argument height",
                argument="height",
                remedy="give the subject's height in metres, e.g. 1.75",
            )
        h = self.height
        self.lengths = {
            "thigh": 0.245 * h,
            "shank": 0.246 * h,
            "ankle_height": 0.039 * h,
            "foot": 0.152 * h,
            "upperarm": 0.186 * h,
            "forearm": 0.146 * h,
            "hip_width": 0.100 * h,
            "shoulder_width": 0.259 * h,
            "shoulder_height": 0.245 * h,  # above L5/S1 along the thorax y axis
            "pelvis_depth": 0.060 * h,  # hip joint centre above the floor when supine
        }

    def lateral(self, side: str) -> float:
        """Sign of the lateral direction along z: +1 right (and midline), -1 left."""
        return -1.0 if side == "l" else 1.0

    def parent(self, segment: str) -> tuple[str | None, str | None, np.ndarray]:
        """(parent segment, joint channel group, origin in the parent frame in m)."""
        kind, side = kind_side(segment)
        L, h = self.lengths, self.height
        s = self.lateral(side)
        l5s1 = np.array([-0.030 * h, 0.060 * h, 0.0])
        table = {
            "pelvis": (None, None, np.zeros(3)),
            "thigh": ("pelvis", f"hip_{side}", np.array([0.0, 0.0, s * L["hip_width"] / 2])),
            "shank": (f"thigh_{side}", f"knee_{side}", np.array([0.0, -L["thigh"], 0.0])),
            "foot": (f"shank_{side}", f"ankle_{side}", np.array([0.0, -L["shank"], 0.0])),
            "lumbar": ("pelvis", "lumbar_half", l5s1),
            "thorax": ("pelvis", "lumbar", l5s1),
            "upperarm": (
                "thorax",
                f"shoulder_{side}",
                np.array([-0.01 * h, L["shoulder_height"], s * L["shoulder_width"] / 2]),
            ),
            "forearm": (f"upperarm_{side}", f"elbow_{side}", np.array([0.0, -L["upperarm"], 0])),
        }
        if kind not in table or segment not in SEGMENTS:
            raise InputError(
                f"segment {segment!r} is not in the simulator's body model",
                where=f"segments.{segment}",
                remedy=f"use one of {', '.join(SEGMENTS)}",
            )
        return table[kind]

    def chain(self, segment: str) -> list[str]:
        """Segments from the root to ``segment`` (inclusive)."""
        out = [segment]
        while (p := self.parent(out[-1])[0]) is not None:
            out.append(p)
        return out[::-1]

    def segment_length(self, segment: str) -> float:
        kind, _ = kind_side(segment)
        return self.lengths.get(kind, 0.1 * self.height)

    def landmark(self, segment: str, name: str) -> tuple[np.ndarray, bool]:
        """Position (m, segment frame) of an anatomical landmark and whether it is known.

        Unknown names get a reproducible place on the segment surface (from a CRC of the name).
        """
        kind, side = kind_side(segment)
        table = _LANDMARKS.get(kind, {})
        spec = None
        for cand, named_side in _candidates(name):
            spec = table.get(cand, table.get(_ALIASES.get(cand, "")))
            if spec is not None:
                side = side or named_side
                break
        h, s = self.height, self.lateral(side)
        if spec is None:
            u = zlib.crc32(name.encode()) / 2**32
            y = -(0.2 + 0.6 * u) * self.segment_length(segment)
            ang = 2 * np.pi * (zlib.crc32(name[::-1].encode()) / 2**32)
            r = 0.035 * h
            return np.array([r * np.cos(ang), y, s * r * np.sin(ang)]), False
        x, y, lat = spec
        y_m = -self.segment_length(segment) if y == "-L" else y * h
        return np.array([x * h, y_m, s * lat * h]), True

    def sensor_site(self, segment: str) -> np.ndarray:
        """Nominal sensor position (m, segment frame): lateral thigh and shank, sacrum, sternum…"""
        kind, side = kind_side(segment)
        h, s, L = self.height, self.lateral(side), self.segment_length(segment)
        sites = {
            "pelvis": (-0.065 * h, 0.035 * h, 0.0),
            "thigh": (0.0, -0.60 * L, s * 0.045 * h),
            "shank": (0.0, -0.40 * L, s * 0.030 * h),
            "foot": (0.045 * h, -0.010 * h, 0.0),
            "lumbar": (-0.055 * h, 0.030 * h, 0.0),
            "thorax": (0.070 * h, 0.190 * h, 0.0),
            "upperarm": (0.0, -0.50 * L, s * 0.030 * h),
            "forearm": (-0.015 * h, -0.80 * L, 0.0),
        }
        return np.array(sites[kind])

    def surface_site(self, segment: str, u: float, v: float) -> tuple[np.ndarray, np.ndarray]:
        """A place on the segment's skin where a strap may sit, and its outward normal.

        ``u`` in [0, 1] runs along the segment (proximal → distal end of the strap zone), ``v``
        in [0, 1] around it (from anterior, through lateral, back to anterior; the lumbar zone
        covers the back only, the foot zone is its dorsum). Position in m, segment frame.
        """
        kind, side = kind_side(segment)
        h, s, L = self.height, self.lateral(side), self.segment_length(segment)
        if kind == "foot":
            site = np.array([(0.02 + 0.06 * u) * h, -0.010 * h, (v - 0.5) * 0.04 * h])
            return site, np.array([0.0, 1.0, 0.0])
        y0, y1, cx, (ax0, az0), (ax1, az1), arc = _SURFACES[kind]
        if kind in _LONG:
            y0, y1 = y0 * L / h, y1 * L / h
        ax, az = ax0 + u * (ax1 - ax0), az0 + u * (az1 - az0)
        phi = arc[0] + v * (arc[1] - arc[0])
        c, sn = np.cos(phi), np.sin(phi)
        site = np.array([cx + ax * c, y0 + u * (y1 - y0), s * az * sn]) * h
        normal = np.array([c / ax, 0.0, s * sn / az])
        return site, normal / np.linalg.norm(normal)

    def strap_zone(self, segment: str) -> tuple[float, float]:
        """Proximal and distal end (m, along the segment's y axis) of the zone where a strap may
        sit (:meth:`surface_site`'s ``u`` = 0 and 1)."""
        kind, _ = kind_side(segment)
        if kind == "foot":
            return -0.010 * self.height, -0.010 * self.height
        y0, y1 = _SURFACES[kind][:2]
        scale = self.segment_length(segment) if kind in _LONG else self.height
        return y0 * scale, y1 * scale

    def site_normal(self, segment: str, site: np.ndarray) -> np.ndarray:
        """Outward skin normal (unit, segment frame) near ``site`` (m): radial about the strap
        zone's centre line (the dorsum's normal on the foot)."""
        kind, _ = kind_side(segment)
        if kind == "foot":
            return np.array([0.0, 1.0, 0.0])
        cx = _SURFACES[kind][2] * self.height
        radial = np.array([site[0] - cx, 0.0, site[2]])
        n = np.linalg.norm(radial)
        return radial / n if n > 1e-9 else np.array([1.0, 0.0, 0.0])

    def cluster_site(self, segment: str) -> tuple[np.ndarray, np.ndarray]:
        """Centre (m) and outward normal of a marker cluster plate on the segment."""
        kind, side = kind_side(segment)
        s = self.lateral(side)
        centre = self.sensor_site(segment).copy()
        if kind in ("pelvis", "lumbar", "forearm"):
            normal = np.array([-1.0, 0.0, 0.0])
        elif kind in ("thorax", "foot"):
            normal = np.array([1.0, 0.0, 0.0]) if kind == "thorax" else np.array([0.0, 1.0, 0.0])
        else:
            normal = np.array([0.0, 0.0, s])
        # keep the cluster clear of the sensor: shift it along the segment
        centre[1] += 0.10 * self.segment_length(segment) * (1 if kind != "foot" else 0)
        if kind == "foot":
            centre[0] += 0.03 * self.height
        return centre, normal
