"""Find the protocol's calibration steps in one continuous recording.

Rest and movement are told apart by the smoothed gyroscope norm of all sensors on a common 50 Hz
grid: a sample is "moving" when any sensor turns faster than ``MOVING_RAD_S``. Short gaps are
closed (pauses between repetitions belong to the step; twitches during a pose do not end it).
Steps are then matched in protocol order:

- a static step takes the next rest block that lasts at least half its ``duration_s`` (≥ 1 s) and
  in which every named segment's sensor sees gravity within ``POSE_TOLERANCE_DEG`` of the nominal
  placement's vertical axis (so standing and sitting are told apart);
- a functional step takes the next movement block in which the step's segments turn fastest
  (their mean rate at least ``LEAD_FRACTION`` of the fastest sensor's); an optional step also
  needs every other sensor to be nearly still.

A step's ``time_range`` in the protocol overrides detection. A required step that is not found
raises :class:`InputError` naming the step and what to do.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_closing, uniform_filter1d

from motionlab.errors import InputError
from motionlab.protocol import CalibrationStep, Protocol, axis_vector

GRID_HZ = 50.0
MOVING_RAD_S = 0.35
SMOOTH_S = 0.4
REP_GAP_S = 1.2
TWITCH_S = 0.3
POSE_TOLERANCE_DEG = 50.0
LEAD_FRACTION = 0.6
QUIET_FRACTION = 0.3


@dataclass
class Block:
    start: float
    end: float
    moving: bool
    rate: dict[str, float]  # mean smoothed gyro norm per segment (rad/s)
    up: dict[str, np.ndarray]  # mean unit specific force per segment (sensor coordinates)


def _resample(t: np.ndarray, x: np.ndarray, grid: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(grid, t, x[:, k]) for k in range(x.shape[1])])


def blocks(streams: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list[Block]:
    """Rest and movement blocks of a recording; ``streams[segment] = (time, acc, gyr)``."""
    start = max(s[0][0] for s in streams.values())
    end = min(s[0][-1] for s in streams.values())
    if end - start < 1.0:
        raise InputError("the sensors overlap by less than 1 s", remedy="check the clocks")
    grid = np.arange(start, end, 1.0 / GRID_HZ)
    win = max(1, int(SMOOTH_S * GRID_HZ))
    rate, up = {}, {}
    for seg, (t, acc, gyr) in streams.items():
        rate[seg] = uniform_filter1d(np.linalg.norm(_resample(t, gyr, grid), axis=1), win)
        up[seg] = _resample(t, acc, grid)
    moving = np.max(np.vstack(list(rate.values())), axis=0) > MOVING_RAD_S
    moving = binary_closing(moving, np.ones(int(REP_GAP_S * GRID_HZ)), border_value=0) | moving
    still = binary_closing(~moving, np.ones(int(TWITCH_S * GRID_HZ)), border_value=0) | ~moving
    moving = ~still
    edges = np.flatnonzero(np.diff(moving.astype(int))) + 1
    out = []
    for i0, i1 in zip(np.r_[0, edges], np.r_[edges, len(grid)], strict=True):
        sl = slice(i0, i1)
        mean_up = {s: a[sl].mean(axis=0) for s, a in up.items()}
        out.append(
            Block(
                start=float(grid[i0]),
                end=float(grid[i1 - 1]),
                moving=bool(moving[i0]),
                rate={s: float(r[sl].mean()) for s, r in rate.items()},
                up={s: u / (np.linalg.norm(u) or 1.0) for s, u in mean_up.items()},
            )
        )
    return out


def _static_match(step: CalibrationStep, block: Block, protocol: Protocol) -> bool:
    if block.moving or block.end - block.start < max(1.0, 0.5 * step.duration_s):
        return False
    for seg, axis in step.vertical_axis.items():
        if seg not in block.up:
            continue
        nominal_up = protocol.segments[seg].nominal_mounting().T @ axis_vector(axis)
        if np.degrees(np.arccos(np.clip(nominal_up @ block.up[seg], -1, 1))) > POSE_TOLERANCE_DEG:
            return False
    return True


def _functional_match(step: CalibrationStep, block: Block) -> bool:
    if not block.moving:
        return False
    fastest = max(block.rate.values())
    movers = [s for s in step.axis if s in block.rate]
    if not movers or min(block.rate[s] for s in movers) < LEAD_FRACTION * fastest:
        return False
    if step.optional:
        others = [r for s, r in block.rate.items() if s not in step.segments]
        return all(r < QUIET_FRACTION * fastest for r in others)
    return True


def find_steps(
    streams: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], protocol: Protocol
) -> dict[str, tuple[float, float] | None]:
    """Time range (s) of each calibration step, ``None`` for an optional step not performed."""
    found: dict[str, tuple[float, float] | None] = {}
    bl = blocks(streams)
    pos = 0  # index of the first block not yet used
    t_used = -np.inf
    for step in protocol.calibration:
        if step.time_range is not None:
            found[step.name] = step.time_range
            t_used = step.time_range[1]
            pos = next((i for i, b in enumerate(bl) if b.start >= t_used - 0.5), len(bl))
            continue
        if step.kind == "static":
            hit = next(
                (i for i in range(pos, len(bl)) if _static_match(step, bl[i], protocol)), None
            )
        else:
            hit = next((i for i in range(pos, len(bl)) if _functional_match(step, bl[i])), None)
        if hit is None:
            if step.optional:
                found[step.name] = None
                continue
            after = f" after {t_used:.1f} s" if np.isfinite(t_used) else ""
            raise InputError(
                f"calibration step '{step.name}' ({step.kind}) not found{after}",
                protocol.path,
                f"calibration step {step.name}",
                "check the recording holds it in protocol order, or give its time_range",
            )
        b = bl[hit]
        if step.kind == "static":  # keep the middle of the pose, away from its edges
            trim = min(0.5, 0.2 * (b.end - b.start))
            found[step.name] = (b.start + trim, b.end - trim)
        else:
            found[step.name] = (b.start, b.end)
        t_used = b.end
        pos = hit + 1
    return found
