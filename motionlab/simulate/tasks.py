"""Movement generators for protocol tasks and functional calibration steps.

Each generator returns a :class:`~motionlab.simulate.motion.Block` (see that module for the
channel layout and the envelope that makes every block C³ at its ends). Task kinds are matched by
keywords (:func:`task_block`); an unknown kind gets a mixed everyday movement (:func:`mixed`) and
the chosen generator is recorded in the truth.
"""

from __future__ import annotations

import numpy as np

from motionlab.kinematics.segment_types import kind_side
from motionlab.simulate.body import Body
from motionlab.simulate.motion import (
    CH,
    DEG,
    Block,
    _tile,
    cycles,
    envelope,
    envelope_integral,
    gait_block,
    legs_sagittal,
    posture,
    posture_of,
    static_block,
)


def _base(body: Body, options: dict, **joints_deg: float) -> np.ndarray:
    """Starting pose: sitting if the task's instructions say so, else standing; plus joints."""
    p = posture(body, posture_of(str(options.get("instructions", ""))))
    for ch, deg in joints_deg.items():
        for s in "rl":
            p[CH[ch.replace("*", s)]] = deg * DEG
    return p


def _reps(reps: int, duration: float, period: float) -> int:
    return reps if reps > 0 else max(1, int(round(duration / period)))


def _legs(out, body: Body, kappa, beta, gamma) -> None:
    """Write a symmetric feet-flat leg pose (arrays in rad) into the channel matrix ``out``."""
    fwd, up, hip, ankle = legs_sagittal(body, kappa, beta, gamma)
    out[:, CH["root_x"]], out[:, CH["root_z"]] = fwd, up
    out[:, CH["tilt_z"]] = -gamma
    for s in "rl":
        out[:, CH[f"knee_{s}_0"]] = kappa
        out[:, CH[f"hip_{s}_0"]] = hip
        out[:, CH[f"ankle_{s}_0"]] = ankle


def squat(body: Body, name, phase, duration, reps, options) -> Block:
    """Squats to ``depth_deg`` knee flexion (default 90°) with trunk lean and arms forward."""
    reps = _reps(reps, duration, 4.0)
    depth = float(options.get("depth_deg", 90.0)) * DEG
    stand = posture(body, "standing")

    def fn(tau):
        one, _ = cycles(tau, duration, reps)
        k = depth * one
        out = _tile(stand, tau)
        _legs(out, body, k, 0.35 * k, 0.40 * k)
        out[:, CH["lumbar_0"]] = 0.15 * k
        for s in "rl":
            out[:, CH[f"shoulder_{s}_0"]] = 0.9 * k
        return out

    return Block(name, "squat", phase, duration, fn, generator="squat")


def sit_to_stand(body: Body, name, phase, duration, reps, options) -> Block:
    """Rising from a chair and sitting down again; trunk lean peaks as the seat is left."""
    reps = _reps(reps, duration, 5.0)
    sit = posture(body, "sitting")

    def fn(tau):
        one, _ = cycles(tau, duration, reps)
        mid = 4 * one * (1 - one)
        out = _tile(sit, tau)
        _legs(out, body, 90 * DEG * (1 - one), 12 * DEG * mid, 30 * DEG * mid)
        out[:, CH["lumbar_0"]] = (10 * DEG) * (1 - one) + 15 * DEG * mid
        for s in "rl":
            out[:, CH[f"elbow_{s}_0"]] = 30 * DEG * (1 - one)
        return out

    return Block(name, "sit_to_stand", phase, duration, fn, generator="sit_to_stand")


def elbow_flexion(body: Body, name, phase, duration, reps, options) -> Block:
    """Elbow flexion 5°→140° on both sides, with pronation/supination drifting ±40°."""
    reps = _reps(reps, duration, 3.0)
    stand = _base(body, options, **{"elbow_*_0": 5.0})

    def fn(tau):
        one, _ = cycles(tau, duration, reps)
        _, slow = cycles(tau, duration, max(1, reps // 2))
        out = _tile(stand, tau)
        for s in "rl":
            out[:, CH[f"elbow_{s}_0"]] = stand[CH[f"elbow_{s}_0"]] + 135 * DEG * one
            out[:, CH[f"elbow_{s}_2"]] = 40 * DEG * slow
            out[:, CH[f"shoulder_{s}_0"]] = 10 * DEG * one
        return out

    return Block(name, "elbow_flexion", phase, duration, fn, generator="elbow_flexion")


def hand_to_mouth(body: Body, name, phase, duration, reps, options) -> Block:
    """A cup from the table to the mouth and back, right and left arm in turn, ``reps`` times each.

    From the hand on the table (elbow flexed 80°, shoulder 15°) to the mouth (elbow 130°,
    shoulder flexed 35° and abducted 15°, forearm supinated 20°): within the ranges of drinking
    from a cup (Safaee-Rad et al. 1990, Arch Phys Med Rehabil 71:505: elbow 70-130°, forearm
    40° pronation to 60° supination).
    """
    reps = _reps(reps, duration, 3.0)
    rest = _base(body, options, **{"elbow_*_0": 80.0, "shoulder_*_0": 15.0})

    def fn(tau):
        f = reps / duration  # per arm
        e = envelope(tau, duration, min(0.4, 0.25 / f))
        wave = np.sin(2 * np.pi * f * tau)  # right arm while positive, left while negative
        out = _tile(rest, tau)
        for s, sign in (("r", 1.0), ("l", -1.0)):
            m = e * np.maximum(sign * wave, 0.0) ** 4  # C³ where the arms take turns
            out[:, CH[f"elbow_{s}_0"]] = rest[CH[f"elbow_{s}_0"]] + 50 * DEG * m
            out[:, CH[f"shoulder_{s}_0"]] = rest[CH[f"shoulder_{s}_0"]] + 20 * DEG * m
            out[:, CH[f"shoulder_{s}_1"]] = -15 * DEG * m
            out[:, CH[f"elbow_{s}_2"]] = -20 * DEG * m
        return out

    return Block(name, "hand_to_mouth", phase, duration, fn, generator="hand_to_mouth")


def pronation(body: Body, name, phase, duration, reps, options) -> Block:
    """Forearm pronation/supination ±80° with the elbow held at 90°."""
    reps = _reps(reps, duration, 2.5)
    stand = _base(body, options, **{"elbow_*_0": 90.0})

    def fn(tau):
        _, sym = cycles(tau, duration, reps)
        out = _tile(stand, tau)
        for s in "rl":
            out[:, CH[f"elbow_{s}_2"]] = 80 * DEG * sym
        return out

    return Block(name, "pronation_supination", phase, duration, fn, generator="pronation")


def reaching(body: Body, name, phase, duration, reps, options) -> Block:
    """Forward reaches, right and left arm in turn, with trunk flexion, rotation and bending."""
    reps = _reps(reps, duration, 3.0)
    stand = _base(body, options, **{"elbow_*_0": 60.0})

    def fn(tau):
        f = reps / duration
        e = envelope(tau, duration, min(0.4, 0.25 / f))
        reach = e * np.sin(np.pi * f * tau) ** 2
        alt = np.cos(0.5 * np.pi * f * tau) ** 2
        out = _tile(stand, tau)
        for s, w in (("r", alt), ("l", 1 - alt)):
            m = reach * w
            out[:, CH[f"shoulder_{s}_0"]] = 85 * DEG * m
            out[:, CH[f"shoulder_{s}_2"]] = -10 * DEG * m
            out[:, CH[f"elbow_{s}_0"]] = stand[CH[f"elbow_{s}_0"]] - 50 * DEG * m
            out[:, CH[f"elbow_{s}_2"]] = 50 * DEG * m
        side = reach * (2 * alt - 1)  # +1 right reach, -1 left reach
        # a healthy reach within arm's length moves the trunk little (Cirstea & Levin 2000:
        # the elbow protocol's limits, 10° forward and turned, 8° sideways): 20° of lean (15°
        # lumbar, 5° pelvis) gave the demo's simulated healthy subject a trunk compensation
        out[:, CH["lumbar_0"]] = 6 * DEG * reach
        out[:, CH["lumbar_2"]] = 8 * DEG * side  # right reach turns the thorax to the left
        out[:, CH["lumbar_1"]] = -4 * DEG * side
        out[:, CH["tilt_z"]] = -2 * DEG * reach
        return out

    return Block(name, "reaching", phase, duration, fn, generator="reaching")


def wandering(
    body: Body,
    ranges: list[tuple[str, float, float]],
    freq_hz: tuple[float, float],
    duration: float,
    rng: np.random.Generator,
):
    """Channel values over block time (the ``fn`` of a :class:`Block`): standing, and every
    channel of ``ranges`` (``(channel, centre, half range)``, deg) a frequency-modulated sinusoid
    ``centre + half · sin(2π f t + β sin(2π g t + φ))``, ``f`` drawn from ``freq_hz`` (Hz), ``g``
    from 0.03-0.10 Hz, ``β`` from 0.5-2, faded in and out at the block's ends."""
    stand = posture(body, "standing")
    n = len(ranges)
    f = rng.uniform(*freq_hz, n)
    g = rng.uniform(0.03, 0.10, n)
    beta = rng.uniform(0.5, 2.0, n)
    ph = rng.uniform(0, 2 * np.pi, (2, n))
    cols = [CH[c] for c, _, _ in ranges]
    centre = np.array([c for _, c, _ in ranges]) * DEG
    half = np.array([h for _, _, h in ranges]) * DEG
    ramp = min(1.5, duration / 4)

    def fn(tau):
        e = envelope(tau, duration, ramp)[:, None]
        t = tau[:, None]
        wave = np.sin(2 * np.pi * f * t + ph[0] + beta * np.sin(2 * np.pi * g * t + ph[1]))
        out = _tile(stand, tau)
        out[:, cols] += e * (centre + half * wave)
        return out

    return fn


def free_arm(body: Body, name, phase, duration, reps, options, seed: int = 0) -> Block:
    """Free arm movement, both arms independently, smooth and random (seeded).

    Elbow flexion 10-130°, pronation ±60° (positive = pronation), shoulder flexion 0-90°,
    abduction 0-40° and rotation ±30°, with a little trunk motion: every channel a frequency-
    modulated sinusoid ``sin(2π f t + β sin(2π g t + φ))`` (f 0.12-0.35 Hz) that reaches both ends
    of its range every cycle; incommensurate frequencies turn the elbow's axes through many
    directions in the room. Standing, arms hanging at the block's ends.
    """
    # (channel, centre, half range) in deg; centre ± half range is the channel's range
    ranges = [(f"elbow_{s}_0", 70.0, 60.0) for s in "rl"]
    ranges += [(f"elbow_{s}_2", 0.0, 60.0) for s in "rl"]
    ranges += [(f"shoulder_{s}_0", 45.0, 45.0) for s in "rl"]
    ranges += [(f"shoulder_{s}_1", -20.0, 20.0) for s in "rl"]
    ranges += [(f"shoulder_{s}_2", 0.0, 30.0) for s in "rl"]
    ranges += [("lumbar_0", 3.0, 5.0), ("lumbar_1", 0.0, 4.0), ("lumbar_2", 0.0, 8.0)]
    fn = wandering(body, ranges, (0.12, 0.35), duration, np.random.default_rng([seed, 7]))
    return Block(name, "free_arm", phase, duration, fn, generator="free_arm")


def trunk(
    body: Body, name, phase, duration, reps, options, planes=(0, 1, 2), pose: str = "standing"
) -> Block:
    """Lumbar flexion (0→60°), lateral bending (±25°) and axial rotation (±35°), in turn, from
    ``pose`` (standing or sitting), one continuous block."""
    reps = _reps(reps, duration * len(planes) / 3, 4.0)
    stand = posture(body, pose)
    part = duration / len(planes)

    def fn(tau):
        out = _tile(stand, tau)
        for i, plane in enumerate(planes):
            one, sym = cycles(tau - i * part, part, max(1, reps // len(planes)))
            if plane == 0:
                out[:, CH["lumbar_0"]] += 60 * DEG * one
                out[:, CH["tilt_z"]] -= 25 * DEG * one  # the pelvis tips forward over the hips
                for s in "rl":
                    out[:, CH[f"hip_{s}_0"]] += 25 * DEG * one
            elif plane == 1:
                out[:, CH["lumbar_1"]] += 25 * DEG * sym
                out[:, CH["tilt_x"]] -= 4 * DEG * sym
            else:
                out[:, CH["lumbar_2"]] += 35 * DEG * sym
                out[:, CH["rot_y"]] -= 8 * DEG * sym
        return out

    return Block(name, "trunk", phase, duration, fn, generator=f"trunk{list(planes)}")


#: The seated trunk movement of wheelchair users as the trunk data set's two people record it
#: (the three ``trunkmovement`` trials, ``bench/real_trunk.py``'s data: the product's lumbar and
#: trunk-against-chair angles and each sensor's speed, measured 2 Dec 2026; docs/simulator.md):
#: quick leans out and back of about a second each (``SEATED_LEAN_S``, the forward one 1.6
#: times as long), forward, to both sides and turning both ways, nearly back to back, the
#: lower-back sensor following most of the upper one: trunk against the chair 54 / 46-64 /
#: 59-75° forward / sideways / turning at the extremes (``SEATED_LEAN_DEG``), the lumbar
#: spine's share of the lean 0.43-0.59 / 0.25-0.35 / 0.34-0.40 (of its rate; of its extremes
#: 0.26-0.33 / 0.25-0.27 / 0.33-0.37: ``SEATED_LUMBAR_SHARE``); after the forward lean the
#: lumbar spine extends (13° then -10°, 18° then -9°: ``SEATED_REBOUND``) and the trunk leans
#: back against the chair (-11, -26 and -51° after 54°: ``SEATED_LEAN_BACK``). The real upper
#: back turns at 103-121°/s RMS (where over 20°/s), the lower back at 87-98°/s; these draws give
#: 107-127 and 75-86°/s.
SEATED_LEAN_S = (1.0, 1.5)
SEATED_GAP_S = (0.0, 0.3)  # between leans
SEATED_PAUSE_S = (0.3, 0.8)  # between rounds
SEATED_LEAN_DEG = {0: (40.0, 55.0), 1: (45.0, 65.0), 2: (55.0, 80.0)}
SEATED_LUMBAR_SHARE = {0: (0.4, 0.55), 1: (0.22, 0.3), 2: (0.32, 0.42)}
SEATED_REBOUND = (0.4, 1.0)
SEATED_LEAN_BACK = (0.0, 0.9)


def _bump(u: np.ndarray) -> np.ndarray:
    """0 → 1 → 0 over ``u`` in [0, 1] (``sin⁴ πu``: C³ at both ends), 0 outside."""
    inside = (u > 0.0) & (u < 1.0)
    return np.where(inside, np.sin(np.pi * np.clip(u, 0.0, 1.0)) ** 4, 0.0)


def seated_trunk(body: Body, name, phase, duration, seed: int = 0) -> Block:
    """Seated trunk movement as wheelchair users make it (:data:`SEATED_LEAN_S` and the other
    ``SEATED_*`` figures): rounds of quick leans, forward (the lumbar spine extending after it),
    to either side and turning either way, each side's order drawn per round; every lean
    split between the pelvis (its tilt on the seat, the hips flexing with a forward one) and
    the lumbar spine."""
    rng = np.random.default_rng([seed, 28])
    sit = posture(body, "sitting")
    ramp = min(0.5, duration / 4)
    # (start s, length s, plane, signed lean rad, lumbar share, the spine's and the seat's
    # lean back after a forward lean, as shares of it)
    events = []
    t = 0.0
    while not events or t < duration - 2 * ramp:
        sides, turns = rng.permutation([-1.0, 1.0]), rng.permutation([-1.0, 1.0])
        for plane, sign in ((0, 1.0), (1, sides[0]), (1, sides[1]), (2, turns[0]), (2, turns[1])):
            length = rng.uniform(*SEATED_LEAN_S) * (1.6 if plane == 0 else 1.0)
            lean = sign * rng.uniform(*SEATED_LEAN_DEG[plane]) * DEG
            share = rng.uniform(*SEATED_LUMBAR_SHARE[plane])
            back = (rng.uniform(*SEATED_REBOUND), rng.uniform(*SEATED_LEAN_BACK))
            events.append((t, length, plane, lean, share, *back))
            t += length + rng.uniform(*SEATED_GAP_S)
            if t >= duration - 2 * ramp:
                break
        t += rng.uniform(*SEATED_PAUSE_S)
    # the leans fill the block: their times taken to it (a round cut short keeps its leans)
    scale = (duration - 2 * ramp) / (events[-1][0] + events[-1][1])
    events = [(ramp + a * scale, b * scale, *rest) for a, b, *rest in events]
    lumbar = [CH["lumbar_0"], CH["lumbar_1"], CH["lumbar_2"]]
    pelvis = [CH["tilt_z"], CH["tilt_x"], CH["rot_y"]]
    pelvis_sign = (-1.0, 1.0, 1.0)  # the pelvis leans with the spine (tilt_z < 0: forward)

    def fn(tau):
        out = _tile(sit, tau)
        e = envelope(tau, duration, ramp)
        for start, length, plane, lean, share, rebound, back in events:
            u = (tau - start) / length
            spine, seat = share * lean * _bump(u), (1.0 - share) * lean * _bump(u)
            if plane == 0:  # lean forward (0-60 % of it), then sit back up, arching the back
                trunk, arch = _bump(u / 0.6), _bump((u - 0.4) / 0.6)
                spine = share * lean * (trunk - rebound * arch)
                seat = (1.0 - share) * lean * (trunk - back * arch)
                for s in "rl":
                    out[:, CH[f"hip_{s}_0"]] += e * seat
            out[:, lumbar[plane]] += e * spine
            out[:, pelvis[plane]] += e * pelvis_sign[plane] * seat
        return out

    return Block(name, "trunk", phase, duration, fn, generator="seated_trunk")


def mixed(body: Body, name, phase, duration, reps, options, seed: int = 0) -> Block:
    """Everyday movement: every joint a sum of slow sinusoids, turning 90° on the spot."""
    rng = np.random.default_rng(seed)
    stand = posture(body, "standing")
    n = len(stand)
    amp = np.zeros(n)
    for g, deg in (("knee", 25), ("hip", 20), ("elbow", 40), ("shoulder", 30), ("ankle", 8)):
        for s in "rl":
            amp[CH[f"{g}_{s}_0"]] = deg * DEG
            amp[CH[f"{g}_{s}_2"]] = deg * DEG / 4
    amp[[CH["lumbar_0"], CH["lumbar_1"], CH["lumbar_2"]]] = np.array([15, 8, 12]) * DEG
    freq = rng.uniform(0.15, 0.6, (2, n))
    phase0 = rng.uniform(0, 2 * np.pi, (2, n))
    ramp = min(1.0, duration / 4)

    def fn(tau):
        e = envelope(tau, duration, ramp)[:, None]
        wave = sum(np.sin(2 * np.pi * freq[i] * tau[:, None] + phase0[i]) for i in range(2)) / 2
        out = _tile(stand, tau) + e * amp * (0.5 + 0.5 * wave)
        for s in "rl":  # knees flex only as far as the legs allow: feet stay on the floor
            out[:, CH[f"elbow_{s}_1"]] = stand[CH[f"elbow_{s}_1"]]
        k = out[:, CH["knee_r_0"]]
        _legs(out, body, k, 0.4 * k, 0.3 * k)
        out[:, CH["heading"]] = (
            (np.pi / 2) * envelope_integral(tau, duration, ramp) / (duration - ramp)
        )
        return out

    return Block(name, "mixed", phase, duration, fn, (0.0, 0.0, np.pi / 2), generator="mixed")


def task_block(body: Body, task, phase: str, duration: float, seed: int) -> Block:
    """The generator that fits a task's ``kind`` (and name) by keywords."""
    key = f"{task.kind} {task.name} {task.options.get('plane', '')}".lower()
    reps, opts = task.repetitions, task.options
    pose_words = ("static", "standing", "sitting", "supine", "rest", "quiet")
    if any(w in key for w in ("gait", "walk", "turn")):
        return gait_block(body, task.name, phase, duration, opts, seed)
    if "free_arm" in key or "free" in key and "arm" in key:
        return free_arm(body, task.name, phase, duration, reps, opts, seed)
    if "squat" in key:
        return squat(body, task.name, phase, duration, reps, opts)
    if "sit" in key and ("stand" in key or "rise" in key) or "sts" in key.split():
        return sit_to_stand(body, task.name, phase, duration, reps, opts)
    if "reach" in key or "adl" in key:
        return reaching(body, task.name, phase, duration, reps, opts)
    if "pronation" in key or "supination" in key or "prosup" in key:
        return pronation(body, task.name, phase, duration, reps, opts)
    if any(w in key for w in ("mouth", "drink", "feed")):
        return hand_to_mouth(body, task.name, phase, duration, reps, opts)
    if any(w in key for w in ("elbow", "curl", "comb")):
        return elbow_flexion(body, task.name, phase, duration, reps, opts)
    if "lateral" in key or "side_bend" in key:
        return trunk(body, task.name, phase, duration, reps, opts, (1,))
    if "rotation" in key or "twist" in key:
        return trunk(body, task.name, phase, duration, reps, opts, (2,))
    if any(w in key for w in ("trunk", "lumbar", "spine", "back", "bend", "flexion")):
        planes = (0,) if "flex" in key or "forward" in key else (0, 1, 2)
        return trunk(body, task.name, phase, duration, reps, opts, planes)
    if any(w in key for w in pose_words):
        return static_block(body, task.name, task.kind, phase, duration, posture_of(key))
    return mixed(body, task.name, phase, duration, reps, opts, seed)


# --------------------------------------------------------------------- functional calibration

# (joint group kind, component) → (one-sided or symmetric, amplitude in deg, channels held)
_FUNCTIONAL = {
    ("knee", 0): ("one", 90.0, {}),
    ("knee", 1): ("sym", 5.0, {"knee_0": 20.0}),
    ("knee", 2): ("sym", 15.0, {"knee_0": 60.0}),
    ("hip", 0): ("one", 60.0, {}),
    ("hip", 1): ("sym", 20.0, {}),
    ("hip", 2): ("sym", 25.0, {}),
    ("ankle", 0): ("sym", 20.0, {}),
    ("ankle", 1): ("sym", 15.0, {}),
    ("ankle", 2): ("sym", 10.0, {}),
    ("elbow", 0): ("one", 130.0, {}),
    ("elbow", 1): ("sym", 3.0, {"elbow_0": 30.0}),
    ("elbow", 2): ("sym", 75.0, {"elbow_0": 90.0}),
    ("shoulder", 0): ("one", 90.0, {}),
    ("shoulder", 1): ("one", -80.0, {}),
    ("shoulder", 2): ("sym", 40.0, {"elbow_0": 90.0}),
    ("lumbar", 0): ("one", 50.0, {}),
    ("lumbar", 1): ("sym", 25.0, {}),
    ("lumbar", 2): ("sym", 30.0, {}),
}
_COMPONENT = {"z": 0, "x": 1, "y": 2}


def moving_joints(body: Body, step) -> list[tuple[str, int]]:
    """Joint channel groups and components a functional step moves (from its ``axis``).

    Of the segments named in ``axis``, those whose parent is not named (or is the pelvis) turn
    about their proximal joint; the axis letter gives the component (z flexion, x ab/adduction,
    y rotation). The pelvis alone turns on the spot (``('heading', 0)``).
    """
    moving = list(step.axis)
    default_axis = next(iter(step.axis.values()))
    out: list[tuple[str, int]] = []
    for seg in moving:
        parent, grp, _ = body.parent(seg)
        if grp is None or (parent in moving and parent != "pelvis"):
            continue
        grp = "lumbar" if grp == "lumbar_half" else grp
        entry = (grp, _COMPONENT[step.axis.get(seg, default_axis).lstrip("-")])
        if entry not in out:
            out.append(entry)
    return out or [("heading", 0)]


def functional_block(body: Body, step, seed: int) -> Block:
    """A functional calibration movement of one or more joints, ``repetitions`` times; a trunk
    step calibrated from free movement (``axis_method: trunk``, ``lumbar_seated``) is the trunk's
    three planes in one continuous block, in the step's pose."""
    if step.axis_method == "trunk":
        pose = posture_of(f"{step.pose} {step.instructions}")
        if pose == "sitting":
            return seated_trunk(body, step.name, "calibration", step.duration_s, seed)
        return trunk(body, step.name, "calibration", step.duration_s, step.repetitions, {},
                     pose=pose)  # fmt: skip
    joints = moving_joints(body, step)
    pose = posture_of(f"{step.pose} {step.instructions}")
    base = posture(body, pose)
    reps = step.repetitions or max(1, int(step.duration_s // 3))
    moves: list[tuple[str, float, int]] = []  # (one|sym, amplitude deg, column)
    for grp, comp in joints:
        if grp == "heading":
            moves.append(("sym", 30.0, CH["heading"]))
            continue
        kind, side = kind_side(grp) if grp != "lumbar" else ("lumbar", "")
        mode, amp, hold = _FUNCTIONAL[(kind, comp)]
        if (kind, comp) == ("knee", 0) and pose == "sitting":
            amp = -80.0  # seated: extend from 90° to 10°
        moves.append((mode, amp, CH[f"{grp}_{comp}"]))
        for ch, deg in hold.items():
            g, c = ch.rsplit("_", 1)
            base[CH[f"{g}_{side}_{c}" if side else f"{g}_{c}"]] = deg * DEG
        if pose == "supine" and kind == "knee" and comp == 0:  # heel slides
            moves.append((mode, 0.5 * amp, CH[f"hip_{side}_0"]))
        if kind == "lumbar" and comp == 0 and "pelvis" in step.axis:  # the pelvis tips too
            moves.append((mode, -0.4 * amp, CH["tilt_z"]))
            moves += [(mode, 0.4 * amp, CH[f"hip_{s}_0"]) for s in "rl"]

    def fn(tau):
        one, sym = cycles(tau, step.duration_s, reps)
        out = _tile(base, tau)
        for mode, amp, col in moves:
            out[:, col] += amp * DEG * (one if mode == "one" else sym)
        return out

    name = "+".join(f"{g}:{c}" for g, c in joints)
    return Block(step.name, "functional", "calibration", step.duration_s, fn,
                 generator=f"functional:{name}:{pose}")  # fmt: skip
