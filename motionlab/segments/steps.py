"""Find the protocol's calibration steps in one continuous recording.

Rest and movement are told apart by the gyroscope of all sensors on a common 50 Hz grid,
low-passed at ``LOWPASS_HZ`` (soft-tissue wobble after impacts rings at 10-20 Hz), less each
sensor's bias (the median over its quietest samples, up to ``MAX_BIAS_RAD_S``: consumer MEMS
gyroscopes are specified to ±20°/s zero-rate offset before calibration, e.g. the InvenSense
MPU-6050); its norm is taken, the fastest sensor's at each sample. A movement starts where that
rate exceeds ``MOVING_RAD_S`` and lasts until it falls below ``STILL_RAD_S`` (hysteresis: the
slow start and end of a movement, and the turning points between its repetitions, belong to it).
Pauses shorter than ``MIN_REST_S`` are closed (pauses of up to about 1 s between repetitions
belong to the step; a rest of 2 s between movements keeps them apart), and moves
shorter than ``TWITCH_S`` during a pose do not end it. Steps are then matched in protocol order:

- a static step takes the next rest block that lasts at least half its ``duration_s`` (≥ 1 s) and
  in which every named segment's sensor sees gravity within ``POSE_TOLERANCE_DEG`` of the nominal
  placement's vertical axis (so standing and sitting are told apart). The placement is a hint:
  when no rest fits it, the next rest long enough whose vertical axes turned from the static
  steps found before by the angles the protocol's axes say is taken, and the contradicted
  segments are warned about (:func:`placement_warnings`);
- a functional step takes the next movement block in which the step's segments turn fastest
  (the fastest of them at least ``LEAD_FRACTION`` of the fastest sensor's mean rate, and each
  of them at least ``MOVE_FRACTION`` of it). An optional step may not have been recorded at
  all, so a block must also look like it: some sensor outside its segments nearly still (not a
  whole-body task such as walking; segments carried along, like the shank in a straight-leg
  hip flexion, may move), a length within ``DURATION_RANGE`` × its ``duration_s``, every named
  segment turning about its named axis (within ``AXIS_TOLERANCE_DEG`` of the nominal
  placement's, or, whatever the mounting, lying to the verticals the static steps before it
  measured in the sensor as the step's axis lies to theirs: :func:`_axes_as_measured`), and
  segments named with the same axis turning as one (their rates within ``RIGID_TOLERANCE`` of
  each other: the knee locked in a straight-leg hip flexion, not flexing as in gait). With the
  nominal placement alone, the knee protocol's straight-leg hip flexions recorded with the
  sensors strapped any way round were refused, and the shank took its flexion axis from the
  seated knee flexion, turned by the tibia's screw-home rotation (:mod:`.grades`).

A step's ``time_range`` in the protocol overrides detection. Required steps that are not found
raise one :class:`InputError` naming all of them, what the recording holds (:func:`describe`)
and a shipped protocol that fits it (:func:`fitting_protocols`); an ambiguous functional step
raises too (not the last one, which the tasks may repeat): the movement block right after the
chosen one also fits the step, moves no other segment, fits no later step and turns about the
same axis (within ``SAME_AXIS_DEG``), and both last about the step's duration (0.5-2×), e.g. a
movement done twice.

Task blocks (:func:`find_tasks`) are the blocks after the last calibration step (or, for a
recording of a stand and movement that ends with its stand, before it: :func:`task_window`),
matched to the protocol's tasks in order: a task held still takes a long enough rest, the
others the movement blocks (moves shorter than ``MIN_TASK_S`` left out and blocks joined across
the shortest rests while there are more blocks than tasks); a task's ``time_range`` overrides
detection. Two rules keep a calibration movement from being taken for a task:

- the functional steps not found after the last step found come, in the protocol's order,
  before the tasks: the movement blocks that fit them by what does not depend on the sensors'
  placement (their segments leading and some other segment still, their length, segments named
  with one axis turning as one) are theirs, not a task's (:func:`calibration_stretches`). An
  optional step recorded but not accepted (its axes checked against the nominal placement
  only, as before :func:`_axes_as_measured`, or a knee bent in a straight-leg swing) used to
  become the first task: the knee protocol's two hip flexions, joined, were its walk;
- a walking task takes, of its blocks, those in which both legs move (:func:`walking`; where
  both sides have leg sensors), and with none it is refused in one line naming the task and
  the leg that moved alone, rather than given a window without a stride.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import binary_closing, label, maximum

from motionlab.dsp import butter, sosfiltfilt
from motionlab.errors import InputError
from motionlab.kinematics.segment_types import kind_side
from motionlab.protocol import PACKAGED, CalibrationStep, Protocol, axis_vector, load_protocol
from motionlab.segments.functional import functional_axis
from motionlab.timebase import interp_columns

GRID_HZ = 50.0
LOWPASS_HZ = 2.0
MOVING_RAD_S = 0.15
STILL_RAD_S = 0.08
MIN_REST_S = 1.5
TWITCH_S = 0.3
BIAS_QUANTILE = 0.1
BIAS_MAX_S = 6.0  # the quietest samples that give the bias: at most this long (s)
MAX_BIAS_RAD_S = 0.35
POSE_TOLERANCE_DEG = 50.0
LEAD_FRACTION = 0.6
QUIET_FRACTION = 0.3
MOVE_FRACTION = 0.15
DURATION_RANGE = (0.4, 2.5)
AXIS_TOLERANCE_DEG = 45.0
RIGID_TOLERANCE = 0.25
MIN_TASK_S = 2.0
#: a walking task's block: the slower leg's fastest segment turns at least this share of the
#: faster leg's mean rate (:func:`walking`)
WALK_SIDES_FRACTION = 0.3
LEG_KINDS = ("thigh", "shank", "foot")
SAME_AXIS_DEG = 20.0
MIN_RECORDING_S = 1.0
#: a rest shorter than this (s) is no pose: not a static step, not named in a message
SHORTEST_POSE_S = 1.0
#: the least trunk movement (s) besides its rest a trunk calibration takes its axes from
#: (:mod:`motionlab.segments.trunk_axes`)
TRUNK_MOVEMENT_S = 2.0
TRUNK_MOVING_DEG_S = 5.0  # a trunk sensor turning faster than this (deg/s) moves

Streams = dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass
class Block:
    start: float
    end: float
    moving: bool
    rate: dict[str, float]  # mean low-passed gyro norm per segment (rad/s)
    up: dict[str, np.ndarray]  # mean unit specific force per segment (sensor coordinates)
    norms: dict[str, np.ndarray]  # low-passed gyro norm per segment on the 50 Hz grid (rad/s)


def _rate(t: np.ndarray, gyr: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Low-passed gyro norm (rad/s) on ``grid``, less the bias: the median over the quietest
    ``BIAS_QUANTILE`` of the samples, at most ``BIAS_MAX_S`` of them (a rest does not grow with
    the recording: in a 10-min walk a tenth of the samples is mostly walking), when it is small
    enough to be one (``MAX_BIAS_RAD_S``)."""
    slow = sosfiltfilt(butter(2, LOWPASS_HZ, fs=GRID_HZ), interp_columns(grid, t, gyr), 0)
    norm = np.linalg.norm(slow, axis=1)
    quiet = min(BIAS_QUANTILE, BIAS_MAX_S * GRID_HZ / len(norm))
    bias = np.median(slow[norm <= np.quantile(norm, quiet)], axis=0)
    if np.linalg.norm(bias) < MAX_BIAS_RAD_S:
        norm = np.linalg.norm(slow - bias, axis=1)
    return norm


def moving_mask(rate: np.ndarray) -> np.ndarray:
    """Movement on the 50 Hz grid from the fastest sensor's rate (rad/s), with hysteresis,
    pauses under ``MIN_REST_S`` closed and moves under ``TWITCH_S`` dropped."""
    runs, n = label(rate > STILL_RAD_S)
    if n == 0:
        return np.zeros(len(rate), bool)
    peaks = np.asarray(maximum(rate, runs, np.arange(1, n + 1)))
    moving = np.isin(runs, np.flatnonzero(peaks > MOVING_RAD_S) + 1)
    moving |= binary_closing(moving, np.ones(int(MIN_REST_S * GRID_HZ)), border_value=0)
    still = binary_closing(~moving, np.ones(int(TWITCH_S * GRID_HZ)), border_value=0) | ~moving
    return ~still


def longest_s(streams: Streams) -> float:
    """Duration (s) of the longest stream: under ``MIN_RECORDING_S`` the recording is too
    short to tell rest from movement (:func:`blocks` refuses it)."""
    return max(s[0][-1] - s[0][0] for s in streams.values())


def cut_short(streams: Streams) -> str:
    """The segments whose data start later or end earlier than the others' by more than
    :data:`SHORTEST_POSE_S` (lost packets or samples not a number at either end), in words
    (``"; thigh_r has data only from 12.0 s (the others from 0.0 s)"``), or ``""``: the
    steps and tasks are looked for where every segment has data (:func:`blocks`)."""
    first = min(s[0][0] for s in streams.values())
    last = max(s[0][-1] for s in streams.values())
    out = []
    for seg, (t, _, _) in streams.items():
        if t[0] - first > SHORTEST_POSE_S:
            out.append(f"{seg} has data only from {t[0]:.1f} s (the others from {first:.1f} s)")
        if last - t[-1] > SHORTEST_POSE_S:
            out.append(f"{seg} has data only until {t[-1]:.1f} s (the others {last:.1f} s)")
    return "".join(f"; {x}" for x in out)


def blocks(streams: Streams) -> list[Block]:
    """Rest and movement blocks of a recording; ``streams[segment] = (time, acc, gyr)``."""
    start = max(s[0][0] for s in streams.values())
    end = min(s[0][-1] for s in streams.values())
    if end - start < MIN_RECORDING_S:
        longest = longest_s(streams)
        if longest < MIN_RECORDING_S:
            raise InputError(
                f"the recording lasts {longest:.2f} s",
                remedy="calibration needs at least a stand of a few seconds, then the task",
            )
        raise InputError("the sensors overlap by less than 1 s", remedy="check the clocks")
    grid = np.arange(start, end, 1.0 / GRID_HZ)
    rate = {seg: _rate(t, gyr, grid) for seg, (t, _, gyr) in streams.items()}
    up = {seg: interp_columns(grid, t, acc) for seg, (t, acc, _) in streams.items()}
    moving = moving_mask(np.max(np.vstack(list(rate.values())), axis=0))
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
                norms={s: r[sl] for s, r in rate.items()},
            )
        )
    return out


def _shortest_s(step: CalibrationStep) -> float:
    """The shortest rest (s) a static step takes: half its ``duration_s``, at least a pose."""
    return max(SHORTEST_POSE_S, 0.5 * step.duration_s)


def _static_match(step: CalibrationStep, block: Block, protocol: Protocol) -> bool:
    if block.moving or block.end - block.start < _shortest_s(step):
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
    rates = [block.rate[s] for s in step.axis if s in block.rate]
    if not rates or max(rates) < LEAD_FRACTION * fastest or min(rates) < MOVE_FRACTION * fastest:
        return False
    if step.optional:
        others = [r for s, r in block.rate.items() if s not in step.segments]
        return not others or any(r < QUIET_FRACTION * fastest for r in others)
    return True


def _rigid(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two segments' rates (rad/s, same grid) agree while they move: one rigid body."""
    on = np.maximum(a, b) > MOVING_RAD_S
    if on.sum() < 3:
        return True
    return float(np.median(np.abs(a[on] - b[on]) / np.maximum(a[on], b[on]))) < RIGID_TOLERANCE


def _shaped_like(step: CalibrationStep, block: Block, streams: Streams) -> bool:
    """Whether a block has the functional step's length and its segments named with the same
    axis turn as one: what is left of :func:`_looks_like` without the placement (the axes)."""
    low, high = DURATION_RANGE
    if not low * step.duration_s <= block.end - block.start <= high * step.duration_s:
        return False
    named = [s for s in step.axis if s in streams]
    for a, b in zip(named[:-1], named[1:], strict=True):
        if step.axis[a] == step.axis[b] and not _rigid(block.norms[a], block.norms[b]):
            return False
    return True


def _looks_like(step: CalibrationStep, block: Block, protocol: Protocol, streams: Streams) -> bool:
    """Whether a block that fits an optional step by its rates also has the step's length,
    axes and rigid segments (see the module docstring)."""
    if not _shaped_like(step, block, streams):
        return False
    named = [s for s in step.axis if s in streams]
    for seg in named:
        t, _, gyr = streams[seg]
        sel = (t >= block.start) & (t <= block.end)
        if sel.sum() < 10:
            return False
        axis = functional_axis(gyr[sel])[0]
        nominal = protocol.segments[seg].nominal_mounting().T @ axis_vector(step.axis[seg])
        if abs(float(axis @ nominal)) < np.cos(np.radians(AXIS_TOLERANCE_DEG)):
            return False
    return True


def _axes_as_measured(
    step: CalibrationStep,
    block: Block,
    statics: list[tuple[CalibrationStep, Block]],
    streams: Streams,
) -> bool:
    """What :func:`_looks_like` asks of an optional step's axes, whatever the sensors' mounting:
    each named segment turning about an axis that lies to the verticals the static steps found
    before measured in its sensor (the stand's long axis of the thigh and the shank) as the
    step's axis lies to those steps' axes (a straight-leg hip flexion's z across the stand's y,
    and across the sitting thigh's x), within ``AXIS_TOLERANCE_DEG``; plus the step's length and
    its rigid segments (:func:`_shaped_like`). Needs at least one such vertical."""
    if not _shaped_like(step, block, streams):
        return False
    checked = 0
    for seg in (s for s in step.axis if s in streams):
        t, _, gyr = streams[seg]
        sel = (t >= block.start) & (t <= block.end)
        if sel.sum() < 10:
            return False
        axis = functional_axis(gyr[sel])[0]
        for other, b in statics:
            if seg not in other.vertical_axis or seg not in b.up:
                continue
            expected = np.arccos(
                abs(axis_vector(step.axis[seg]) @ axis_vector(other.vertical_axis[seg]))
            )
            up = b.up[seg] / np.linalg.norm(b.up[seg])
            measured = np.arccos(np.clip(abs(float(axis @ up)), 0.0, 1.0))
            if abs(np.degrees(measured - expected)) > AXIS_TOLERANCE_DEG:
                return False
            checked += 1
    return checked > 0


def _fmt(b: Block) -> str:
    return f"{b.start:.1f}-{b.end:.1f} s"


def _same_axis(step: CalibrationStep, a: Block, b: Block, streams) -> bool:
    """Whether the step's first segment turns about the same sensor axis in blocks a and b."""
    t, _, gyr = streams[next(s for s in step.axis if s in streams)]
    axes = []
    for blk in (a, b):
        sel = (t >= blk.start) & (t <= blk.end)
        if sel.sum() < 10:
            return False
        axes.append(functional_axis(gyr[sel])[0])
    return abs(float(axes[0] @ axes[1])) > np.cos(np.radians(SAME_AXIS_DEG))


def _check_unambiguous(
    step: CalibrationStep,
    hit: int,
    bl: list[Block],
    later: list[CalibrationStep],
    protocol,
    streams,
) -> None:
    """Refuse a functional step whose next movement block is a second candidate for it.

    Not for the last step: the tasks that follow may well repeat it (the lumbar protocol does).
    """
    if not later:
        return
    nxt = next((i for i in range(hit + 1, len(bl)) if bl[i].moving), None)
    if nxt is None or not _functional_match(step, bl[nxt]):
        return
    fastest = max(bl[nxt].rate.values())
    if any(
        r >= QUIET_FRACTION * fastest for s, r in bl[nxt].rate.items() if s not in step.segments
    ):
        return  # other segments move too: a task, not this step again
    if any(s.kind == "functional" and _functional_match(s, bl[nxt]) for s in later):
        return

    def fits(b: Block) -> bool:
        return 0.5 * step.duration_s <= b.end - b.start <= 2.0 * step.duration_s

    if fits(bl[hit]) and fits(bl[nxt]) and _same_axis(step, bl[hit], bl[nxt], streams):
        raise InputError(
            f"calibration step '{step.name}' is ambiguous: two candidate windows, "
            f"{_fmt(bl[hit])} and {_fmt(bl[nxt])}",
            protocol.path,
            f"calibration step {step.name}",
            "give the step's time_range in the protocol (e.g. time_range: "
            f"[{bl[nxt].start:.1f}, {bl[nxt].end:.1f}] for the second one)",
        )


def _axis_words(v: np.ndarray) -> str:
    """The signed sensor axis a unit vector is closest to (``+x``), or its components."""
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) >= np.cos(np.radians(30.0)):
        return f"sensor {'+' if v[k] > 0 else '-'}{'xyz'[k]}"
    return "sensor ({:+.2f}, {:+.2f}, {:+.2f})".format(*v)


def placement_warnings(step: CalibrationStep, block: Block, protocol: Protocol) -> list[str]:
    """One warning per segment whose measured vertical axis in ``block`` contradicts the hint
    (not for a segment whose sensor may sit in any orientation: there the hint is a default)."""
    out = []
    for seg, axis in step.vertical_axis.items():
        if seg not in block.up or protocol.segments[seg].any_orientation:
            continue
        nominal_up = protocol.segments[seg].nominal_mounting().T @ axis_vector(axis)
        if np.degrees(np.arccos(np.clip(nominal_up @ block.up[seg], -1, 1))) > POSE_TOLERANCE_DEG:
            out.append(
                f"{seg}: {_axis_words(block.up[seg])} points up in the {step.name} pose, the "
                f"protocol says {_axis_words(nominal_up).removeprefix('sensor ')}; using the data"
            )
    return out


def _fits_without_hint(
    step: CalibrationStep, block: Block, earlier: list[tuple[CalibrationStep, Block]]
) -> bool:
    """A rest long enough for a static step whose vertical axes are consistent with the static
    steps found before it: a segment named in both turned between them by the angle between
    the two steps' segment axes (standing → sitting: the thigh by 90°), whatever its mounting."""
    if block.moving or block.end - block.start < _shortest_s(step):
        return False
    for other, b in earlier:
        for seg, axis in step.vertical_axis.items():
            if seg not in other.vertical_axis or seg not in block.up:
                continue
            expected = np.arccos(
                np.clip(axis_vector(axis) @ axis_vector(other.vertical_axis[seg]), -1, 1)
            )
            measured = np.arccos(np.clip(block.up[seg] @ b.up[seg], -1, 1))
            if abs(np.degrees(measured - expected)) > POSE_TOLERANCE_DEG:
                return False
    return True


def unfound_step(name: str, protocol: Protocol, single_pose: str = "") -> str:
    """Why calibration step ``name`` has no span (the console's, the report's words): not used
    by a single-pose calibration (``single_pose``: its step), optional, or required and missing
    (the grades then say what that costs)."""
    if single_pose:
        return "not used (single-pose calibration)"
    optional = any(s.name == name and s.optional for s in protocol.calibration)
    return "not found (optional)" if optional else "not found (required: see the grades)"


def describe(bl: list[Block]) -> str:
    """What a recording holds, in words: its rests and movements, and which axes point up."""
    parts = [
        f"{'movement' if b.moving else 'rest'} {_fmt(b)} ({b.end - b.start:.1f} s)"
        for b in bl
        if b.end - b.start >= (TWITCH_S if b.moving else SHORTEST_POSE_S)
    ]
    if len(parts) > 8:
        parts = parts[:7] + [f"... {len(parts) - 7} more"]
    rest = next((b for b in bl if not b.moving), None)
    text = "the recording holds " + (", ".join(parts) or "no rest or movement")
    if rest is not None:
        ups = ", ".join(f"{s} {_axis_words(u).removeprefix('sensor ')}" for s, u in rest.up.items())
        text += f"; the sensor axis pointing up in the first still moment ({_fmt(rest)}): {ups}"
    return text


#: ``pose_check(step, span)``: why the rest at ``span`` (s) is not static ``step``'s pose, or None
PoseCheck = Callable[[CalibrationStep, tuple[float, float]], str | None]


def find_steps(
    streams: Streams,
    protocol: Protocol,
    warnings: list[str] | None = None,
    suggest: bool = True,
    pose_check: PoseCheck | None = None,
) -> dict[str, tuple[float, float] | None]:
    """Time range (s) of each calibration step, ``None`` for an optional step not performed.

    A static step is first matched with the nominal placement's vertical axes (so standing and
    sitting are told apart); when no rest fits them, the next rest long enough is taken and the
    axes measured in it are used, with one line per contradicted segment added to ``warnings``
    (the placement is a hint). A rest ``pose_check`` rejects is passed over (a seated rest
    before a stand and a walk, :mod:`.walk_checks`). Required steps still missing are named all
    at once in one :class:`InputError`, with what the recording holds, the rests rejected and
    why, and (``suggest``) a shipped protocol that fits it.
    """
    found: dict[str, tuple[float, float] | None] = {}
    bl = blocks(streams)
    rejected: dict[tuple[str, int], str | None] = {}  # (step, block): why it is not the pose

    def accepted(step: CalibrationStep, i: int) -> bool:
        if pose_check is None:
            return True
        if (step.name, i) not in rejected:
            rejected[step.name, i] = pose_check(step, _pose_span(bl[i]))
        return not rejected[step.name, i]

    missing: list[CalibrationStep] = []
    statics: list[tuple[CalibrationStep, Block]] = []  # static steps found so far
    pos = 0  # index of the first block not yet used
    t_used = -np.inf
    for k, step in enumerate(protocol.calibration):
        if step.time_range is not None:
            found[step.name] = step.time_range
            t_used = step.time_range[1]
            pos = next((i for i, b in enumerate(bl) if b.start >= t_used - 0.5), len(bl))
            continue
        if step.kind == "static":
            hit = next(
                (
                    i
                    for i in range(pos, len(bl))
                    if _static_match(step, bl[i], protocol) and accepted(step, i)
                ),
                None,
            )
            if hit is None and not step.optional:
                rests = (
                    i
                    for i in range(pos, len(bl))
                    if _fits_without_hint(step, bl[i], statics) and accepted(step, i)
                )
                hit = next(rests, None)
                if hit is not None and warnings is not None:
                    warnings.extend(placement_warnings(step, bl[hit], protocol))
        else:
            hit = next(
                (
                    i
                    for i in range(pos, len(bl))
                    if _functional_match(step, bl[i])
                    and (
                        not step.optional
                        or _looks_like(step, bl[i], protocol, streams)
                        or _axes_as_measured(step, bl[i], statics, streams)
                    )
                ),
                None,
            )
        if hit is None:
            if not step.optional:
                missing.append(step)
            found[step.name] = None
            continue
        b = bl[hit]
        if step.kind == "static":
            statics.append((step, b))
            found[step.name] = _pose_span(b)
        else:
            _check_unambiguous(step, hit, bl, protocol.calibration[k + 1 :], protocol, streams)
            found[step.name] = (b.start, b.end)
        t_used = b.end
        pos = hit + 1
    if missing:
        names = ", ".join(f"'{s.name}' ({s.kind})" for s in missing)
        longest = max((b.end - b.start for b in bl if not b.moving), default=0.0)
        needs = "".join(
            f"; '{s.name}' needs the {s.pose} pose held still for at least {_shortest_s(s):.1f} s"
            # a rest that prints as long enough is said exactly ("2.5 s" short of 2.5 s)
            + (f" (the longest rest is {longest:.2f} s)" if 0 < longest < _shortest_s(s) else "")
            for s in missing
            if s.kind == "static"
        )
        fits = fitting_protocols(streams, protocol) if suggest else []
        reasons = [why for why in rejected.values() if why]
        why = f"; {'; '.join(dict.fromkeys(reasons))}" if reasons else ""
        raise InputError(
            f"calibration step{'s' if len(missing) > 1 else ''} {names} not found; "
            f"{describe(bl)}{needs}{why}{cut_short(streams)}",
            protocol.path,
            "calibration",
            _remedy(fits, suggest, any(_is_pose(b) for b in bl), _record(missing, protocol)),
        )
    return found


def _record(missing: list[CalibrationStep], protocol: Protocol) -> str:
    """How to record the first missing static step: its pose, how long, and where (a stand
    of a stand-and-walk recording before or after the walk); empty without one."""
    step = next((s for s in missing if s.kind == "static"), None)
    if step is None:
        return ""
    where = (
        "before or after the walk" if stand_and_walk(protocol)
        else "before or after the movement" if pose_then_movement(protocol)
        else "before the task"
    )  # fmt: skip
    return f"record the {step.pose} pose held still for {step.duration_s:.0f} s {where}"


def _pose_span(b: Block) -> tuple[float, float]:
    """The span (s) a static step takes of rest ``b``: its middle, away from its edges."""
    trim = min(0.5, 0.2 * (b.end - b.start))
    return (b.start + trim, b.end - trim)


def _is_pose(b: Block) -> bool:
    """A rest long enough to be a pose (:data:`SHORTEST_POSE_S`)."""
    return not b.moving and b.end - b.start >= SHORTEST_POSE_S


def _remedy(fits: list[str], suggested: bool, has_rest: bool, record: str = "") -> str:
    """What to do about missing steps: a shipped protocol that fits, or why none does; with
    ``record`` (:func:`_record`) how to record the missing pose first."""
    check = "check the recording holds the steps in protocol order, or give their time_range"
    lead = f"{record}, or " if record else ""
    if fits:
        names = " or ".join(repr(f) for f in fits)
        return f"the shipped protocol {names} fits this recording; or {lead}{check}"
    if not suggested:
        return f"{lead}{check}"
    if not has_rest:
        return (
            "no shipped protocol fits a recording without a rest (each starts with a pose held "
            f"still for a few seconds, mostly a stand): {lead or 'record one before the task, or '}"
            f"{check}"
        )
    return f"no shipped protocol fits this recording either; {lead}{check}"


def _trunk_moves(streams: Streams, protocol: Protocol) -> bool:
    """Whether the lumbar joint's sensors turn (either faster than ``TRUNK_MOVING_DEG_S``) for
    ``TRUNK_MOVEMENT_S`` or more: what a trunk calibration needs besides its rest, at most
    (the calibration counts the thorax's turning relative to the pelvis only)."""
    joint = next((j for j in protocol.joints.values() if j.type == "lumbar"), None)
    if joint is None or joint.proximal not in streams or joint.distal not in streams:
        return False
    t = streams[joint.distal][0]
    rates = []
    for seg in (joint.proximal, joint.distal):
        ts, _, gyr = streams[seg]
        rates.append(np.degrees(np.linalg.norm(interp_columns(t, ts, gyr), axis=1)))
    moving = np.maximum(*rates) > TRUNK_MOVING_DEG_S
    return bool(len(t) > 1 and moving.sum() * np.median(np.diff(t)) >= TRUNK_MOVEMENT_S)


def fitting_protocols(streams: Streams, protocol: Protocol) -> list[str]:
    """Shipped protocols (other than ``protocol``) whose required segments, the two segments of
    at least one joint, whose steps and whose tasks after them this recording has."""
    out = []
    for path in sorted(PACKAGED.glob("*.yaml")):
        other = load_protocol(path)
        if other.name == protocol.name:
            continue
        needed = [s for s, spec in other.segments.items() if spec.required]
        if any(s not in streams for s in needed) or not any(
            j.proximal in streams and j.distal in streams for j in other.joints.values()
        ):
            continue
        if any(s.axis_method == "trunk" for s in other.calibration):
            # a rest anywhere and free movement (segments/trunk_axes.py): OpenSense's 4-s
            # calibration pose was told 'lumbar_seated' fits, which then found 0.8 s of movement
            if _trunk_moves(streams, other):
                out.append(other.name)
            continue
        mine = {s: streams[s] for s in other.segments if s in streams}
        try:
            steps = find_steps(mine, other, None, False)
            after, before = task_window(mine, other, steps)
            find_tasks(mine, other, after, suggest=False, steps=steps, before_s=before)
        except InputError:
            continue
        out.append(other.name)
    return out


def find_tasks(
    streams: Streams,
    protocol: Protocol,
    after_s: float = -np.inf,
    suggest: bool = True,
    steps: dict[str, tuple[float, float] | list[float] | None] | None = None,
    before_s: float = np.inf,
) -> dict[str, tuple[float, float]]:
    """Time range (s) of each protocol task: blocks after ``after_s`` (and ending by
    ``before_s``: a walk before its stand, :func:`task_window`), in order.

    ``steps`` (the calibration's :func:`find_steps`, ``None`` for a step not found): the
    movements of the protocol's steps not found after the last one found come before the tasks
    and are left out of them (:func:`calibration_stretches`), so that an optional step recorded
    but not accepted is not taken for the first task.

    A task held still (:attr:`~motionlab.protocol.Task.is_pose`: quiet sitting or standing)
    takes the middle of the first rest after the tasks before it that lasts at least half its
    ``duration_s`` (at least ``SHORTEST_POSE_S``) and leaves a movement block before it for
    each movement task between it and the previous pose. The movement tasks between two poses
    take the movement blocks between them: with more blocks than tasks, moves shorter than
    ``MIN_TASK_S`` are left out, then the two blocks separated by the shortest rest are joined
    until the counts agree. A walking task (:attr:`~motionlab.protocol.Task.is_gait`) takes
    the blocks of its share in which both legs move (:func:`walking`), and where none does the
    recording is refused naming the task. Tasks with a ``time_range`` keep it and the blocks
    overlapping it are left out. Too few blocks are an :class:`InputError` naming what the
    recording holds and (``suggest``) a shipped protocol that fits it.
    """
    fixed = {t.name: t.time_range for t in protocol.tasks if t.time_range is not None}
    todo = [t for t in protocol.tasks if t.time_range is None]
    if not todo:
        return {t.name: fixed[t.name] for t in protocol.tasks}

    def free(b: Block) -> bool:
        return (
            b.start >= after_s
            and b.end <= before_s
            and not any(b.start < r[1] and b.end > r[0] for r in fixed.values())
        )

    found_blocks = blocks(streams)
    usable = [b for b in found_blocks if free(b)]
    if steps is not None:
        claimed = calibration_stretches(usable, protocol, steps, streams)
        usable = [b for b in usable if not any(b is c for _, c in claimed)]
    found: dict[str, tuple[float, float]] = {}
    cursor, i = -np.inf, 0
    while i < len(todo):
        j = next((k for k in range(i, len(todo)) if todo[k].is_pose), len(todo))
        moves = todo[i:j]
        until = np.inf
        if j < len(todo):  # the pose ends this run of movement tasks
            rest = _pose_rest(usable, todo[j], cursor, len(moves))
            if rest is None:
                _too_few(found_blocks, protocol, streams, [todo[j]], suggest, pose=True)
            until = rest.start
            found[todo[j].name] = _pose_span(rest)
        if moves:
            spans = [b for b in usable if b.moving and cursor <= b.start < until]
            shares = _joined(spans, len(moves))
            if len(shares) < len(moves):
                _too_few(found_blocks, protocol, streams, moves, suggest, found=len(shares))
            for task, share in zip(moves, shares, strict=True):
                if task.is_gait:
                    share = _walk_of(task, share, found_blocks, protocol)
                found[task.name] = (share[0].start, share[-1].end)
        if j < len(todo):
            cursor = rest.end
        i = j + 1
    return {t.name: found.get(t.name) or fixed[t.name] for t in protocol.tasks}


def pose_then_movement(protocol: Protocol) -> bool:
    """Whether the protocol's recording is poses held still and movement tasks only (``walk``,
    ``arm``): its poses may come before the movement or after it (:func:`task_window`)."""
    return (
        bool(protocol.tasks)
        and not any(task.is_pose for task in protocol.tasks)
        and all(step.kind == "static" for step in protocol.calibration)
    )


def stand_and_walk(protocol: Protocol) -> bool:
    """Whether the protocol's recording is poses and walking only (the ``walk`` protocol): then
    the movement a knee's axes come from is the walk's swings, where a thigh turns slower than
    its shank. Not where other tasks or functional steps move the leg too (the ``knee``
    protocol's hip flexions turn the thigh twice as fast as the shank)."""
    return pose_then_movement(protocol) and all(task.is_gait for task in protocol.tasks)


def task_window(
    streams: Streams, protocol: Protocol, steps: dict[str, tuple[float, float] | list[float] | None]
) -> tuple[float, float]:
    """The span (s) the tasks lie in: after the last calibration step found (``steps``, as
    :func:`find_steps` gives them), ``(end, inf)``. A recording of poses and movement only
    (:func:`pose_then_movement`: ``walk``, ``arm``) may end with its stand instead: where less
    than ``MIN_TASK_S`` of movement follows the stand and at least that much precedes it, the
    movement is before it, ``(-inf, start)`` (a walk stopped, then a stand, then the recording
    stopped)."""
    spans = [tuple(v) for v in steps.values() if v is not None]
    after = max((v[1] for v in spans), default=-np.inf)
    if not spans or not pose_then_movement(protocol):
        return after, np.inf
    first = min(v[0] for v in spans)
    moving = [b for b in blocks(streams) if b.moving]
    later = sum(b.end - max(b.start, after) for b in moving if b.end > after)
    earlier = sum(min(b.end, first) - b.start for b in moving if b.start < first)
    if later < MIN_TASK_S <= earlier:
        return -np.inf, first
    return after, np.inf


def calibration_stretches(
    usable: list[Block],
    protocol: Protocol,
    steps: dict[str, tuple[float, float] | list[float] | None],
    streams: Streams,
) -> list[tuple[CalibrationStep, Block]]:
    """The movement blocks of ``usable`` (those after the calibration) that belong to the
    protocol's functional steps not found after the last step found, each with its step.

    The protocol's order puts those steps between the last step found and the tasks, so they are
    matched in that order against the movement blocks of at least ``MIN_TASK_S``: a step takes
    the next block when the block fits it as :func:`find_steps` asks of an optional step, less
    what depends on the sensor's placement: the step's segments turning fastest and some other
    segment nearly still, the step's length within ``DURATION_RANGE``, and segments named with
    the same axis turning as one (a straight-leg hip flexion: not a walk, whose knees flex). A
    block that does not fit leaves the step as not recorded, and the next step is tried on it.
    """
    done = [k for k, s in enumerate(protocol.calibration) if steps.get(s.name) is not None]
    pending = [
        s
        for s in protocol.calibration[(done[-1] + 1 if done else 0) :]
        if s.kind == "functional" and s.time_range is None
    ]
    moves = iter(b for b in usable if b.moving and b.end - b.start >= MIN_TASK_S)
    out: list[tuple[CalibrationStep, Block]] = []
    block = next(moves, None)
    for step in pending:
        if block is None:
            break
        quiet = replace(step, optional=True)  # some other segment still, as for an optional step
        if _functional_match(quiet, block) and _shaped_like(step, block, streams):
            out.append((step, block))
            block = next(moves, None)
    return out


def _leg_sides(block: Block) -> dict[str, float]:
    """The mean rate (rad/s) of each side's fastest leg segment (thigh, shank, foot) in a block."""
    out: dict[str, float] = {}
    for seg, rate in block.rate.items():
        kind, side = kind_side(seg)
        if side and kind in LEG_KINDS:
            out[side] = max(out.get(side, 0.0), rate)
    return out


def walking(block: Block) -> bool:
    """Whether a movement block can be a walk: where the legs of both sides have sensors, both
    move, the slower side's fastest segment at least ``WALK_SIDES_FRACTION`` of the faster's
    mean rate (a calibration movement of one leg turns the other at 0-14 % of it, simulated
    walks 97-100 %, the real 16-IMU walk 99 %). With one side or none sensed it cannot tell: True.
    """
    sides = _leg_sides(block)
    if len(sides) < 2 or max(sides.values()) == 0:
        return True
    return min(sides.values()) >= WALK_SIDES_FRACTION * max(sides.values())


def _walk_of(
    task, share: list[Block], found_blocks: list[Block], protocol: Protocol
) -> list[Block]:
    """The blocks of ``share`` from the first to the last in which both legs move
    (:func:`walking`); none is an :class:`InputError` naming the task and what moved instead."""
    walks = [k for k, b in enumerate(share) if walking(b)]
    if walks:
        return share[walks[0] : walks[-1] + 1]
    words = {"r": "right", "l": "left"}
    parts = []
    for b in share:
        sides = _leg_sides(b)
        fast, slow = max(sides, key=sides.get), min(sides, key=sides.get)
        parts.append(
            f"at {_fmt(b)} only the {words.get(fast, fast)} leg moves (the "
            f"{words.get(slow, slow)} at {100 * sides[slow] / sides[fast]:.0f} % of its rate)"
        )
    raise InputError(
        f"task '{task.name}' ({task.kind}) not found where the protocol's order puts it: "
        f"{' and '.join(parts)}, as in a calibration movement of one leg, where a walk moves "
        f"both; {describe(found_blocks)}",
        protocol.path,
        "tasks",
        "record the walk after the calibration, pausing a few seconds between tasks, or give "
        "the task's time_range",
    )


def _pose_rest(usable: list[Block], task, after: float, moves_before: int) -> Block | None:
    """The first rest after ``after`` (s) long enough for pose ``task`` with at least
    ``moves_before`` movement blocks between ``after`` and it."""
    shortest = max(SHORTEST_POSE_S, 0.5 * task.duration_s)
    seen = 0
    for b in usable:
        if b.start < after:
            continue
        if b.moving:
            seen += 1
        elif b.end - b.start >= shortest and seen >= moves_before:
            return b
    return None


def _joined(spans: list[Block], wanted: int) -> list[list[Block]]:
    """Movement blocks cut down to ``wanted`` shares (each a run of blocks): moves under
    ``MIN_TASK_S`` left out when enough are longer, then neighbours across the shortest rest
    joined."""
    if len(spans) > wanted:  # short moves between tasks: getting up, sitting down
        long = [b for b in spans if b.end - b.start >= MIN_TASK_S]
        spans = long if len(long) >= wanted else spans
    shares = [[b] for b in spans]
    while len(shares) > wanted:
        gaps = [shares[i + 1][0].start - shares[i][-1].end for i in range(len(shares) - 1)]
        i = int(np.argmin(gaps))
        shares[i : i + 2] = [shares[i] + shares[i + 1]]
    return shares


def _too_few(found_blocks, protocol, streams, tasks, suggest, found=0, pose=False) -> None:
    """Refuse: the recording holds ``found`` movement blocks for ``tasks`` (with ``pose``, no
    rest for the held task ``tasks[0]``)."""
    names = ", ".join(t.name for t in tasks)
    remedy = (
        "record the task after the calibration, pausing a few seconds between tasks, or "
        "give each task's time_range"
    )
    fits = fitting_protocols(streams, protocol) if suggest else []
    if not any(b.moving for b in found_blocks):  # a calibration pose on its own
        remedy = (
            "the recording is one still pose with no movement to take angles from (a "
            "calibration pose on its own, e.g. OpenSense's calibration trial): give the "
            "recording of the movement, starting with this pose held still"
        )
    elif fits:
        shipped = " or ".join(map(repr, fits))
        remedy = f"the shipped protocol {shipped} fits this recording; or {remedy}"
    if pose:
        shortest = max(SHORTEST_POSE_S, 0.5 * tasks[0].duration_s)
        what = (
            f"found no rest of at least {shortest:.1f} s for the held task '{names}' after the "
            "calibration and the tasks before it"
        )
    else:
        what = (
            f"found {found} movement block(s) after the calibration for {len(tasks)} "
            f"task(s) ({names})"
        )
    raise InputError(f"{what}; {describe(found_blocks)}", protocol.path, "tasks", remedy)


def reference_step(protocol: Protocol, proximal: str, distal: str) -> str | None:
    """First static step naming the proximal segment's vertical axis and the distal's as the
    same or not at all: the reference pose of the joint (e.g. standing)."""
    for step in protocol.calibration:
        va = step.vertical_axis
        if (
            step.kind == "static"
            and proximal in va
            and va.get(distal, va[proximal]) == va[proximal]
        ):
            return step.name
    return None
