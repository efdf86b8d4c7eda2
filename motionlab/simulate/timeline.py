"""The recording's timeline: calibration steps, then tasks, with rests in between, as one C³ motion.

Layout: ``rest, step₁, rest, step₂, …, rest, task₁, rest, …, task_K, rest``. Calibration steps keep
their protocol durations; the tasks share what is left of ``duration`` in proportion to their
``duration_s``. A rest holds the pose the previous block ended in for ``rest_s`` seconds. When the
next block starts in another pose (sitting down before the sit-to-stand task, standing up after a
seated step), a C³ blend (:func:`~motionlab.simulate.motion.smoothstep`) over ``blend_s``
seconds follows, right before the next block, and the rest is that much longer. So every rest
holds ``rest_s`` seconds of stillness after the previous block, and static steps are perfectly
still from start to end.

Every block works in the frame of a *feet reference* (position on the floor and heading) that is
carried from one block to the next, so walking moves the subject through the room.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motionlab.errors import InputError
from motionlab.protocol import Protocol
from motionlab.simulate.body import Body
from motionlab.simulate.motion import (
    CH,
    DEG,
    Block,
    envelope,
    posture_of,
    rest_block,
    smoothstep,
    static_block,
    wrap,
)
from motionlab.simulate.tasks import functional_block, mixed, task_block

_XY = [CH["root_x"], CH["root_y"]]
POSE_TOLERANCE = 1e-3  # rad or m: a smaller difference between two poses is no change of pose


def _to_global(local: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Block-local channels in the room frame (modifies and returns ``local``)."""
    out = local
    c, s = np.cos(origin[2]), np.sin(origin[2])
    x, y = local[:, _XY[0]].copy(), local[:, _XY[1]].copy()
    out[:, _XY[0]] = origin[0] + c * x - s * y
    out[:, _XY[1]] = origin[1] + s * x + c * y
    out[:, CH["heading"]] += origin[2]
    return out


def _to_local(row: np.ndarray, origin: np.ndarray) -> np.ndarray:
    out = row.copy()
    c, s = np.cos(origin[2]), np.sin(origin[2])
    dx, dy = row[_XY[0]] - origin[0], row[_XY[1]] - origin[1]
    out[_XY[0]], out[_XY[1]] = c * dx + s * dy, -s * dx + c * dy
    out[CH["heading"]] -= origin[2]
    return out


#: knee adduction coupled to flexion: this many rad times sin(flexion) (4° at 90°)
KNEE_ADDUCTION_COUPLING = 4 * DEG
#: internal tibial rotation coupled to flexion (rad per rad, the screw-home mechanism)
KNEE_ROTATION_COUPLING = 0.12
KNEE_MODELS = ("simple", "anatomical")
# The anatomical knee (``knee_model="anatomical"``; docs/simulator.md says where each number
# comes from). Screw-home: the tibia rotates externally in the last ~20-30° of extension and
# internally as the knee flexes, steeply near extension and little beyond (Wilson et al. 2000,
# J Biomech 33:465: internal rotation coupled to passive flexion in every specimen); in gait
# the bone-pin range of internal/external rotation is ≈ 8-10° (Lafortune et al. 1992, J Biomech
# 25:347; Benoit et al. 2006, Gait Posture 24:152), of which this coupling gives 7.6° over
# the 4-61° of a stride. Adduction (varus) grows with flexion to 3.5° at the swing peak; with
# the gait's own 3° of ab/adduction the bone-pin range in gait of ≈ 6° (Lafortune 1992: 6.4°).
#: screw-home rotation: ``KNEE_SCREW_HOME · tanh(flexion / KNEE_SCREW_HOME_SCALE)`` (rad) ...
KNEE_SCREW_HOME = 8 * DEG
KNEE_SCREW_HOME_SCALE = 15 * DEG
#: ... plus this many rad of internal rotation per rad of flexion beyond it
KNEE_ROTATION_SLOPE = 0.03
#: adduction ``KNEE_ADDUCTION_PEAK · (sin(flexion) / sin 60°)²`` (rad): 3.5° at 60° of flexion
KNEE_ADDUCTION_PEAK = 3.5 * DEG
#: variation of the anatomical knee while walking: for one flexion angle a real knee takes
#: several ab/adduction and rotation positions, within and between strides (Benoit et al. 2007,
#: Clin Orthop Relat Res 454:81): the couplings' gains vary by this fraction (RMS) and the
#: secondary angles by this many rad (RMS), at :data:`KNEE_VARIATION_HZ`
KNEE_VARIATION_GAIN = 0.2
KNEE_VARIATION_OFFSET = 1.8 * DEG
KNEE_VARIATION_HZ = (0.5, 4.0)


def knee_coupling(flexion: np.ndarray, model: str = "simple") -> tuple[np.ndarray, np.ndarray]:
    """(adduction, internal rotation) in rad coupled to knee ``flexion`` (rad) by ``model``.

    ``simple``: :data:`KNEE_ADDUCTION_COUPLING` · sin(flexion) and :data:`KNEE_ROTATION_COUPLING`
    · flexion (proportional, so a movement-fitted axis absorbs most of it as a turned axis).
    ``anatomical``: the screw-home curve and the varus of the anatomical knee (above), which no
    fixed axis can follow: at 0, 10, 20, 30 and 60° of flexion the rotation is 0, 5.0, 7.6, 8.6
    and 9.8° (7.6° over the 4-61° of a stride) and the adduction 0, 0.1, 0.5, 1.2 and 3.5°.
    """
    k = np.asarray(flexion, dtype=float)
    if model == "anatomical":
        add = KNEE_ADDUCTION_PEAK * (np.sin(k) / np.sin(60 * DEG)) ** 2
        rot_int = KNEE_SCREW_HOME * np.tanh(k / KNEE_SCREW_HOME_SCALE) + KNEE_ROTATION_SLOPE * k
        return add, rot_int
    return KNEE_ADDUCTION_COUPLING * np.sin(k), KNEE_ROTATION_COUPLING * k


def knee_variation(t: np.ndarray, seed: int, side: str) -> np.ndarray:
    """Variation (N, 4) of one knee over time ``t`` (s), each column a sum of three sinusoids of
    random frequency (:data:`KNEE_VARIATION_HZ`) and phase scaled to unit RMS (peaks below 2.5):
    gains of the adduction and rotation couplings, offsets of adduction and rotation."""
    rng = np.random.default_rng([seed, 7, "rl".index(side)])
    f = rng.uniform(*KNEE_VARIATION_HZ, size=(3, 4))
    ph = rng.uniform(0.0, 2 * np.pi, size=(3, 4))
    return np.sum(np.sin(2 * np.pi * f * t[:, None, None] + ph), axis=1) * np.sqrt(2.0 / 3.0)


def couple(ch: np.ndarray, knee_model: str = "simple", t: np.ndarray | None = None,
           seed: int = 0, walking: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Couplings seen in real joints, added on top of every block.

    Knee (:func:`knee_coupling`), ``simple``: adduction grows with flexion
    (:data:`KNEE_ADDUCTION_COUPLING`, up to 4° at 90°) and the tibia rotates internally with
    flexion (:data:`KNEE_ROTATION_COUPLING`, 0.12° per degree, the screw-home mechanism). A
    flexion axis found from the movement (a functional axis) cannot tell a coupling proportional
    to flexion from a turned axis, so these put a definitional error into the functional
    calibrations (``bench/real_world.py --uncoupled-knee`` shows its size). ``anatomical``: the
    screw-home curve and varus of a real knee, varying from stride to stride while walking
    (``walking``, 0-1 over time ``t`` in s; drawn from ``seed``, :func:`knee_variation`), so a
    still pose stays still. Elbow: the carrying angle falls by 0.06° per degree of
    flexion. Modifies and returns ``ch``.
    """
    for s in "rl":
        add, rot_int = knee_coupling(ch[:, CH[f"knee_{s}_0"]], knee_model)
        if knee_model == "anatomical" and t is not None and walking is not None:
            v = knee_variation(t, seed, s) * walking[:, None]
            add = add * (1 + KNEE_VARIATION_GAIN * v[:, 0]) + KNEE_VARIATION_OFFSET * v[:, 2]
            rot_int = (
                rot_int * (1 + KNEE_VARIATION_GAIN * v[:, 1]) + KNEE_VARIATION_OFFSET * v[:, 3]
            )
        ch[:, CH[f"knee_{s}_1"]] += add
        ch[:, CH[f"knee_{s}_2"]] += rot_int
        ch[:, CH[f"elbow_{s}_1"]] -= 0.06 * ch[:, CH[f"elbow_{s}_0"]]
    return ch


@dataclass
class Timeline:
    """Blocks with start times (s) and feet-reference origins ``(x, y, heading)``."""

    blocks: list[Block]
    starts: np.ndarray
    origins: np.ndarray
    blend_s: float
    knee_model: str = "simple"
    seed: int = 0

    @property
    def duration(self) -> float:
        return float(self.starts[-1] + self.blocks[-1].duration)

    def _global(self, i: int, tau: np.ndarray) -> np.ndarray:
        return _to_global(self.blocks[i].fn(tau), self.origins[i])

    def channels(self, t: np.ndarray) -> np.ndarray:
        """Channel matrix (N, C) at true times ``t`` (s); the ends hold still beyond the record.

        The result is read-only and the last two are kept: sensors sampled at the same instants
        share one evaluation.
        """
        t = np.asarray(t, dtype=float)
        cache = self.__dict__.setdefault("_cache", [])
        for t_old, out in cache:
            if t_old.shape == t.shape and np.array_equal(t_old, t):
                return out
        out = self._channels(t)
        out.flags.writeable = False
        cache[:] = [*cache[-1:], (t.copy(), out)]
        return out

    def _channels(self, t: np.ndarray) -> np.ndarray:
        out = np.empty((len(t), len(CH)))
        idx = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.blocks) - 1)
        for i in np.unique(idx):
            m = idx == i
            out[m] = self._global(i, t[m] - self.starts[i])
        for i, block in enumerate(self.blocks[:-1]):
            if block.phase != "rest":
                continue
            b = self.starts[i + 1]
            w = min(self.blend_s, block.duration)
            m = (t >= b - w) & (t < b)
            if m.any():
                s = smoothstep((t[m] - (b - w)) / w)[:, None]
                out[m] = (1 - s) * out[m] + s * self._global(i + 1, t[m] - b)
        walking = np.zeros(len(t))
        if self.knee_model == "anatomical":
            for start, block in zip(self.starts, self.blocks, strict=True):
                if block.generator == "gait":  # the gait block's own envelope (motion.gait_block)
                    walking += envelope(t - start, block.duration, min(2.0, block.duration / 3))
        return couple(out, self.knee_model, t, self.seed, walking)

    def impacts(self, side: str | None = None) -> np.ndarray:
        """Heel-strike times (s) of all walking blocks (they excite the soft-tissue wobble), or
        of one leg's (``side`` ``"r"`` or ``"l"``)."""
        parts = [
            s + (b.impacts if side is None else b.impacts[b.impact_sides == side])
            for s, b in zip(self.starts, self.blocks, strict=True)
        ]
        return np.concatenate(parts) if parts else np.zeros(0)

    def steps(self) -> list[dict]:
        """Calibration steps and tasks with start and end times (s); rests left out."""
        return [
            {
                "name": b.name,
                "kind": b.kind,
                "phase": b.phase,
                "start_s": float(s),
                "end_s": float(s + b.duration),
                "generator": b.generator,
            }
            for s, b in zip(self.starts, self.blocks, strict=True)
            if b.phase != "rest"
        ]


def _pose_change(prev: Block, block: Block) -> bool:
    """Whether ``block`` starts in another pose than ``prev`` ends in (feet reference carried)."""
    end = _to_global(prev.fn(np.array([prev.duration + 1.0])), np.zeros(3))[0]
    diff = _to_local(end, np.asarray(prev.end, dtype=float)) - block.fn(np.array([-1.0]))[0]
    diff[CH["heading"]] = wrap(diff[CH["heading"]])
    return bool(np.max(np.abs(diff)) > POSE_TOLERANCE)


def _task_blocks(body: Body, tasks: list, total: float, seed: int) -> list[Block]:
    """The tasks sharing ``total`` seconds in proportion to their ``duration_s``."""
    if not tasks:
        return [mixed(body, "free", "task", total, 0, {}, seed)]
    weights = np.array([t.duration_s for t in tasks], dtype=float)
    weights = weights if weights.sum() > 0 else np.ones(len(tasks))
    weights = np.where(weights > 0, weights, weights[weights > 0].mean())
    share = total * weights / weights.sum()
    return [task_block(body, t, "task", float(d), seed) for t, d in zip(tasks, share, strict=True)]


def plan(
    protocol: Protocol,
    body: Body,
    duration: float,
    seed: int = 0,
    rest_s: float = 3.0,
    blend_s: float = 2.0,
    calibration: bool = True,
    heading_deg: float = 20.0,
    knee_model: str = "simple",
) -> Timeline:
    """Lay out the protocol's calibration steps and tasks over ``duration`` seconds.

    ``rest_s`` is the stillness after every block (and before the first), ``blend_s`` the time a
    change of pose between two blocks takes (see the module docstring); ``knee_model`` the
    knee's couplings (:func:`knee_coupling`).
    """
    steps = protocol.calibration if calibration else []
    moves: list[Block] = []
    for step in steps:
        if step.kind == "static":
            pose = posture_of(f"{step.pose} {step.instructions}")
            moves.append(static_block(body, step.name, "static", "calibration", step.duration_s,
                                      pose))  # fmt: skip
        else:
            moves.append(functional_block(body, step, seed))
    tasks = list(protocol.tasks)
    n_tasks = max(len(tasks), 1)
    trial = moves + _task_blocks(body, tasks, 10.0 * n_tasks, seed)  # poses only
    changes = sum(_pose_change(a, b) for a, b in zip(trial[:-1], trial[1:], strict=True))
    used = sum(b.duration for b in moves) + rest_s * (len(moves) + n_tasks + 1) + blend_s * changes
    left = duration - used
    if left < 3.0 * n_tasks - 1e-9:
        raise InputError(
            f"duration {duration:g} s is too short: calibration and rests take {used:g} s",
            where="argument duration",
            argument="duration",
            remedy=f"give at least {used + 3.0 * n_tasks:g} s or skip the calibration steps",
        )
    moves += _task_blocks(body, tasks, left, seed)

    blocks: list[Block] = []
    origins: list[np.ndarray] = []
    origin = np.array([0.0, 0.0, heading_deg * DEG])
    for block in moves:
        prev = blocks[-1] if blocks else None
        if prev is None:
            row, rest = block.fn(np.array([-1.0]))[0], rest_s
        else:
            end = _to_global(prev.fn(np.array([prev.duration + 1.0])), origins[-1])[0]
            row = _to_local(end, origin)
            rest = rest_s + (blend_s if _pose_change(prev, block) else 0.0)
        blocks += [rest_block(rest, row), block]
        origins += [origin.copy(), origin.copy()]
        dx, dy, dpsi = block.end
        c, s = np.cos(origin[2]), np.sin(origin[2])
        origin = origin + np.array([c * dx - s * dy, s * dx + c * dy, dpsi])
    last = _to_global(blocks[-1].fn(np.array([blocks[-1].duration + 1.0])), origins[-1])[0]
    blocks.append(rest_block(rest_s, _to_local(last, origin)))
    origins.append(origin)
    starts = np.concatenate([[0.0], np.cumsum([b.duration for b in blocks[:-1]])])
    return Timeline(blocks, starts, np.array(origins), blend_s, knee_model, seed)
