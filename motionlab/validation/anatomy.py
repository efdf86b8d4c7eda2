"""Anatomical segment frames from landmarks (ISB style: x anterior, y proximal, z right).

A frame is built from two directions between landmark groups (the mean of a group of landmarks
is one point): the *primary* axis points exactly along the first direction, the *secondary* axis
lies in the plane of both directions on the side of the second one, and the third axis completes
a right-handed frame. In the limbs the primary axis is the medio-lateral one through the
epicondyles (malleoli, styloids), i.e. the flexion axis of the joint the segment ends in, as in
the joint coordinate system of Grood & Suntay (1983, J Biomech Eng 105:136); the long axis
(distal joint centre → proximal joint centre or landmark) is secondary, so a landmark that lies
off the long axis (the greater trochanter) tilts nothing. Pelvis: z from the left to the right
ASIS, x from the mid-PSIS to the mid-ASIS (Wu et al. 2002, J Biomech 35:543). Thorax: y from
mid(PX, T8) to mid(IJ, C7), x from the back (C7, T8) to the front (IJ, PX) (Wu et al. 2005,
J Biomech 38:981). On the left side "lateral" is −z, so the medio-lateral directions swap.

Landmark names are matched without their side (``RLE``, ``LE_r``, ``R.LE`` → ``LE`` right) and
through common aliases (``RLHE`` → ``LE``, ``RASI`` → ``ASIS``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motionlab.kinematics.segment_types import kind_side

# canonical landmark → aliases (upper case, without side)
_ALIASES: dict[str, tuple[str, ...]] = {
    "ASIS": ("ASI",),
    "PSIS": ("PSI",),
    "GT": ("TRO", "FTC"),
    "HJC": ("HIP",),
    "LE": ("FLE", "LFE", "KNE", "LHE", "HLE", "LEP", "EL"),
    "ME": ("FME", "MFE", "KNEM", "MHE", "HME", "MEP", "EM"),
    "LM": ("LMAL", "FAL", "ANK"),
    "MM": ("MMAL", "TAM", "MED"),
    "FH": ("FAX",),
    "TT": ("TTC",),
    "OL": ("OLE",),
    "RS": ("RSP", "WRA"),
    "US": ("USP", "WRB"),
    "GH": ("GHJ",),
    "AC": ("ACR", "SHO", "SA"),
    "IJ": ("CLAV", "SJN"),
    "PX": ("STRN", "XP", "SXS"),
    "C7": ("CV7",),
    "T8": ("TV8",),
    "CA": ("HEE", "HEEL", "FCC"),
    "MT1": ("FM1",),
    "MT5": ("FM5",),
    "TOE": ("FM2",),
    "SACR": ("SACRUM",),
    "T12": (),
    "L1": (),
}
_CANONICAL = {alias: name for name, aliases in _ALIASES.items() for alias in (name, *aliases)}

Points = list[list[str]]  # alternatives, each a group of landmark keys averaged into one point


@dataclass(frozen=True)
class Direction:
    """A frame axis (``'x'``, ``'y'``, ``'z'``) pointing from one landmark group to another.

    ``start`` and ``end`` list alternative groups; the first group whose landmarks are all
    known is used. ``lateral=True``: the direction points laterally (swapped on the left side).
    """

    axis: str
    start: Points
    end: Points
    lateral: bool = False


@dataclass(frozen=True)
class FrameRecipe:
    primary: Direction
    secondary: Direction


_KNEE = [["LE", "ME"]]
_ANKLE = [["LM", "MM"]]
_WRIST = [["RS", "US"]]
RECIPES: dict[str, FrameRecipe] = {
    "pelvis": FrameRecipe(
        Direction("z", [["ASIS_l"], ["PSIS_l"]], [["ASIS_r"], ["PSIS_r"]]),
        Direction("x", [["PSIS"], ["SACR"]], [["ASIS"]]),
    ),
    "thigh": FrameRecipe(
        Direction("z", [["ME"]], [["LE"]], lateral=True),
        Direction("y", _KNEE, [["HJC"], ["GT"]]),
    ),
    "shank": FrameRecipe(
        Direction("z", [["ME"], ["MM"]], [["LE"], ["LM"]], lateral=True),
        Direction("y", _ANKLE, _KNEE + [["FH", "TT"], ["TT"]]),
    ),
    "foot": FrameRecipe(
        Direction("x", [["CA"]], [["MT1", "MT5"], ["TOE"]]),
        Direction("z", [["MT1"]], [["MT5"]], lateral=True),
    ),
    "upperarm": FrameRecipe(
        Direction("z", [["ME"]], [["LE"]], lateral=True),
        Direction("y", _KNEE, [["GH"], ["AC"]]),
    ),
    "forearm": FrameRecipe(
        Direction("z", [["US"], ["ME"]], [["RS"], ["LE"]], lateral=True),
        Direction("y", _WRIST, _KNEE + [["OL"]]),
    ),
    "thorax": FrameRecipe(
        Direction("y", [["PX", "T8"], ["T8"], ["T12"], ["L1"]], [["IJ", "C7"], ["C7"]]),
        Direction("x", [["C7", "T8"], ["C7"], ["T12"]], [["IJ", "PX"], ["IJ"]]),
    ),
}


def resolve_name(name: str) -> tuple[str, str]:
    """``(canonical landmark, side)`` of a marker name: ``RLHE`` → ``('LE', 'r')``.

    Unknown names come back upper-cased without a side.
    """
    n = name.strip().upper()
    if n in _CANONICAL:
        return _CANONICAL[n], ""
    for side in "RL":
        for head, tail in ((f"{side}_", ""), (f"{side}.", ""), ("", f"_{side}"), ("", f".{side}")):
            if n.startswith(head) and n.endswith(tail) and len(n) > len(head + tail):
                core = n[len(head) : len(n) - len(tail)]
                if core in _CANONICAL:
                    return _CANONICAL[core], side.lower()
        if n.startswith(side) and n[1:] in _CANONICAL:
            return _CANONICAL[n[1:]], side.lower()
    return n, ""


def landmark_keys(positions: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Points keyed by canonical name: ``LE`` (mean over sides), ``ASIS_r``, ``ASIS_l``."""
    groups: dict[str, list[np.ndarray]] = {}
    for name, p in positions.items():
        canon, side = resolve_name(name)
        groups.setdefault(canon, []).append(np.asarray(p, float))
        if side:
            groups.setdefault(f"{canon}_{side}", []).append(np.asarray(p, float))
    return {k: np.mean(v, axis=0) for k, v in groups.items()}


def _point(points: Points, keys: dict[str, np.ndarray]) -> tuple[np.ndarray, list[str]] | None:
    for group in points:
        if all(g in keys for g in group):
            return np.mean([keys[g] for g in group], axis=0), group
    return None


def _vector(d: Direction, keys: dict[str, np.ndarray], side: str):
    a = _point(d.start, keys)
    b = _point(d.end, keys)
    if a is None or b is None:
        return None
    v = b[0] - a[0]
    if d.lateral and side == "l":
        v = -v
    return v, a[1] + b[1]


def two_axis_frame(axis1: str, v1: np.ndarray, axis2: str, v2: np.ndarray) -> np.ndarray:
    """Rotation matrix (columns x, y, z) with ``axis1`` along ``v1``, ``axis2`` towards ``v2``."""
    i, j = "xyz".index(axis1), "xyz".index(axis2)
    if i == j:
        raise ValueError(f"primary and secondary axis are both {axis1}")
    u1 = v1 / np.linalg.norm(v1)
    u2 = v2 - (v2 @ u1) * u1
    u2 = u2 / np.linalg.norm(u2)
    u3 = np.cross(u1, u2) if (j - i) % 3 == 1 else np.cross(u2, u1)
    m = np.empty((3, 3))
    m[:, i], m[:, j], m[:, 3 - i - j] = u1, u2, u3
    return m


def anatomical_frame(
    recipe: FrameRecipe, positions: dict[str, np.ndarray], side: str = "", by_name: bool = True
) -> tuple[np.ndarray, list[str]] | None:
    """Segment axes (3, 3; columns x, y, z in the coordinates of ``positions``) and the
    landmarks used, or ``None`` when the landmarks needed are missing or (nearly) parallel.

    ``by_name``: match the recipe's canonical names (:func:`landmark_keys`); ``False``: the
    recipe names the markers of ``positions`` directly (a recipe from a marker map).
    """
    keys = landmark_keys(positions) if by_name else dict(positions)
    first = _vector(recipe.primary, keys, side)
    second = _vector(recipe.secondary, keys, side)
    if first is None or second is None:
        return None
    (v1, used1), (v2, used2) = first, second
    n1, n2 = np.linalg.norm(v1), np.linalg.norm(v2)
    if n1 < 1e-6 or n2 < 1e-6 or np.linalg.norm(np.cross(v1, v2)) < 0.1 * n1 * n2:
        return None
    m = two_axis_frame(recipe.primary.axis, v1, recipe.secondary.axis, v2)
    return m, sorted(set(used1 + used2))


def recipe_for(segment: str) -> FrameRecipe | None:
    """The default recipe of a segment by its kind (``thigh_r`` → thigh), or ``None``."""
    return RECIPES.get(kind_side(segment)[0])
