"""The gait truth of a simulated walk: contacts from the feet's motion, and the pelvis angles.

Initial and final contacts come from the motion of the simulated feet, by the kinematic rule of
Zeni et al. (2008, Gait Posture 27:710), which needs no force plate: initial contact where the
heel is farthest in front of the pelvis (sacrum), final contact (toe-off) where the toe is
farthest behind it, both along the walking direction. The heel is 20 % of the foot length
behind the ankle, the toe 80 % in front of it, both at the sole. The feet are evaluated on a
1 kHz grid, so an event time is exact to 0.5 ms. An event counts as *steady* when it lies where
the walk's envelope is full (not in its start or stop ramp).

The pelvis angles (:mod:`motionlab.kinematics.pelvis`) are taken relative to the path's own
direction (the feet reference's heading, which the pelvis rotation swings about).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.signal import find_peaks

from motionlab import rotations as rot
from motionlab.kinematics.pelvis import PELVIS_COLUMNS, pelvis_angles
from motionlab.simulate.body import Body
from motionlab.simulate.chain import segment_poses
from motionlab.simulate.motion import CH, envelope
from motionlab.simulate.timeline import Timeline

EVENT_RATE_HZ = 1000.0
HEEL, TOE = -0.2, 0.8  # fractions of the foot length behind / in front of the ankle
RAMP_S = 2.0  # the gait block's envelope ramp (motion.gait_block)
CHUNK = 2**20  # instants of the 1 kHz grid per evaluation (≈ 17 min of walking)


def _forward(heading: np.ndarray) -> np.ndarray:
    return np.column_stack([np.cos(heading), np.sin(heading), np.zeros_like(heading)])


def gait_truth(body: Body, timeline: Timeline, t: np.ndarray) -> dict[str, Any]:
    """Events (s) per side of every gait block, and the pelvis angles (deg) on the grid ``t``.

    Returns ``{"ic_r": (K,), "fc_r": ..., "ic_l", "fc_l", "ic_r_steady": (K,) bool, ...,
    "pelvis_tilt_deg": (N,), "pelvis_obliquity_deg", "pelvis_rotation_deg",
    "walking_heading": (N,) rad}``.
    """
    out: dict[str, Any] = {}
    events: dict[str, list[np.ndarray]] = {}
    L = body.lengths
    for start, block in zip(timeline.starts, timeline.blocks, strict=True):
        if block.kind != "gait":
            continue
        tt = start + np.arange(0.0, block.duration, 1.0 / EVENT_RATE_HZ)
        full = envelope(tt - start, block.duration, min(RAMP_S, block.duration / 3)) > 0.999
        ahead: dict[str, list[np.ndarray]] = {}  # heel ahead of / toe behind the sacrum (m)
        for a in range(0, len(tt), CHUNK):  # the feet a chunk at a time: bounded memory
            ch = timeline.channels(tt[a : a + CHUNK])
            poses = segment_poses(body, ch, ["pelvis", "foot_r", "foot_l"])
            fwd = _forward(ch[:, CH["heading"]])
            sacrum = poses["pelvis"][1]
            for side in "rl":
                q, p = poses[f"foot_{side}"]
                heel = p + rot.rotate(q, np.array([HEEL * L["foot"], -L["ankle_height"], 0.0]))
                toe = p + rot.rotate(q, np.array([TOE * L["foot"], -L["ankle_height"], 0.0]))
                ahead.setdefault(f"heel_{side}", []).append(np.sum((heel - sacrum) * fwd, axis=1))
                ahead.setdefault(f"toe_{side}", []).append(-np.sum((toe - sacrum) * fwd, axis=1))
        for side in "rl":
            gap = int(0.4 * EVENT_RATE_HZ)
            heel, toe = (np.concatenate(ahead[f"{x}_{side}"]) for x in ("heel", "toe"))
            ic, _ = find_peaks(heel, distance=gap, prominence=0.1)
            fc, _ = find_peaks(toe, distance=gap, prominence=0.1)
            for name, idx in ((f"ic_{side}", ic), (f"fc_{side}", fc)):
                events.setdefault(name, []).append(tt[idx])
                events.setdefault(f"{name}_steady", []).append(full[idx])
    for name, parts in events.items():
        out[name] = np.concatenate(parts) if parts else np.zeros(0)
    ch = timeline.channels(t)
    heading = ch[:, CH["heading"]]
    q_pelvis = segment_poses(body, ch, ["pelvis"])["pelvis"][0]
    angles = np.degrees(pelvis_angles(q_pelvis, heading))
    for i, col in enumerate(PELVIS_COLUMNS):
        out[col] = angles[:, i]
    out["walking_heading"] = heading
    return out
