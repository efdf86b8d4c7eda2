"""The clock sync of a session (:func:`synchronise`): which method times each sensor, and the
corrections applied to its stamps (:func:`unsynchronise` restores them).

The impact lag (:mod:`.impacts`) is tried on the sync tree's pairs (:mod:`.pairs`) first.

*Without heel strikes* (no reliable impact lag: arm, elbow, lumbar and the clinical tasks, whose
timing is as before) each sensor is put on its parent's corrected clock by the joint-centre fit
(:func:`choose` keeps it); a pair joined by the spine (pelvis, lumbar, thorax) by its spine
rule (a short movement in shorter blocks, a looser residual limit: :mod:`.joint_centre`).

*With heel strikes* every sensor's clock is solved at once on the root's
(:mod:`motionlab.clocknet`): the impact lags of every pair of sensors and the joint-centre fits
of every pair of neighbours, all on the recorded clocks, in one weighted least squares with a
floor under each standard error, a prior on each sensor's own delay of its transient envelope,
and the measurements that break the loops set aside one at a time (data snooping). Why not the
per-pair choice it replaced (joint centre when both agree, else the impact lag): on simulated
walks the joint-centre fits of pelvis–thigh were 7-68 ms off with claimed standard errors of
0.1 ms, the knee's 0.1-6 ms, and the impact lags of one shank can all be shifted together by its
own tissue resonance (bench/gait.py seed 1 asymmetric: all four of shank_r's by 7.3 ms, its knee
joint centre 1.1 ms off), so a per-pair rule picked a wrong answer either way. A shift shared by
all of one sensor's impact lags cancels around every loop of impact lags: only that sensor's
joint-centre fit shows it, and where the two disagree the data cannot tell which is wrong; the
solution then weighs them by their priors (``ENVELOPE_SD_S``, ``HIP_CENTRE_FLOOR_S``,
:data:`motionlab.clocknet.CENTRE_FLOOR_S`) and the sensor's line says that they disagree.
Seed 1 asymmetric: shank_r 5.2 ms off instead of 7.9 ms, the other sensors within 0.9 ms. Each
network :class:`ClockFit` is against the root sensor (``method`` ``network``) and says in
``other`` what timed the sensor, what was set aside and what disagrees; it is applied when the
correction at the recording's ends exceeds ``MIN_CORRECTION_S`` and its own standard error. A
sensor that no reliable measurement ties to the others follows its tree parent's clock.

*Parts of the body no sensor joins* (the legs without a pelvis sensor, :func:`.pairs.sync_forest`)
are timed against each other only by the heel strikes across them, in the same network solve,
and a part is taken onto the root's clock only when every one of its sensors is known there to
``LINK_MAX_SE_S``; else it is solved on its own root's clock, whose fit says why it is
:data:`~motionlab.results.NOT_LINKED`, and the gait numbers that compare the legs are withheld
(:func:`motionlab.kinematics.gait.legs_not_linked`). Before, only the root's part was timed: a
simulated 400-s walk without its pelvis sensor read 10.2 % step-time asymmetry (0.7 % now, and
with the pelvis). Without heel strikes (the arms without a thorax sensor) each part is its own.

*Clocks the vendor synchronised* (every sensor's ``attrs["vendor_clock_sync"]`` set by its
reader to one and the same value: an Xsens DOT export's ``SyncStatus: Synced``, the MTw files of
one Awinda recording or the legacy exports of one recording of one master device
(:func:`motionlab.io.xsens.mark_one_recording`), one time column for all the sensors of an APDM
CSV, an OpenSense ``.sto`` or
a generic CSV; docs/ingest.md, "Sensors on one clock"): the fits are made as a check and none is
applied (status :data:`VENDOR_KEPT`, the data's answer kept in the fit), and the legs are on one
clock without a pelvis sensor. The DOT app's
synchronisation is far finer than a joint-centre fit through soft tissue: on a real seated knee
recording (two DOTs, ``SyncStatus: Synced``, first stamps one sample apart) the fit asked for
+27 ± 2 ms.

*The heel strikes must agree with the knees' joint centres.* On a real walk the envelopes of one
heel strike do not peak together: on the 16-IMU recording, whose sensors share one radio clock,
the heel-strike lags between sensors were 36-88 ms, and on a 35-s cut of it the network put
thigh_l 61 ms and shank_l 10 ms off the pelvis's clock, 50 ms apart at the knee, where the
knee's joint centre put them 1 ms apart (its residual refused it; on that recording the joint
centres lay within 5 ms of one clock). So the network's clocks are taken only when every knee
pair of the tree has a joint-centre fit (also one refused for its residual or its standard
error) within ``CORROBORATE_S`` of them (:func:`_uncorroborated`); otherwise no sensor is
corrected and each fit says which pair disagreed; so too where the network times one sensor of
such a pair and not the other (the real walk resampled to 50 Hz: thigh_l +72 ms, its shank
untimed and following it, hip_l 72 ms out of step). The hips' joint centres are no check (7-68
ms off on simulated walks, above). On the simulated walks the check changes nothing
(bench/real_world.py walk seeds 0-19, bench/gait.py and bench/clock_network.py: identical
tables); on 42 cuts of the real walk (24-45 s of walking after a stand) none is corrected, where
five were before (thigh_l 60-74 ms, thigh_r −418 and −436 ms: a lag one step away).
"""

from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np

from motionlab.binding import sensor_for_segment
from motionlab.clocknet import CENTRE_FLOOR_S, IMPACTS, NETWORK, solve_network
from motionlab.clocksync.common import MAX_OFFSET_S, MIN_CORRECTION_S, PerStream
from motionlab.clocksync.impacts import REGULAR_STEPS, TOO_SHORT, envelope, impact_clock
from motionlab.clocksync.joint_centre import POOR_FIT, estimate_clock, signals
from motionlab.clocksync.pairs import joint_pairs, sync_forest
from motionlab.io.clock import SHARED_CLOCK
from motionlab.kinematics.segment_types import kind_side
from motionlab.protocol import Protocol
from motionlab.results import NOT_LINKED, RELIABLE, VENDOR_KEPT, ClockFit
from motionlab.session import Session

# allowance for the errors of an impact lag that its block scatter does not show (medians
# 0.2-0.9 ms on simulated walks, see :mod:`.impacts`): within it plus twice the standard errors, the
# joint-centre fit is kept; 3 ms let pelvis-thigh fits 3.4 ms off through on bench/gait.py seed 0
IMPACT_BIAS_S = 0.0015

# two fits each refused on its own (the joint centre for its residual, the heel strikes for
# steps as regular as the search) whose clocks lie this close (s) over the whole recording are
# taken together: a lag one step away lies hundreds of ms off, a model error of the joint
# centre 7-68 ms. On a simulated 1-h walk the knee's two agreed within 2.2 ms of each other
# (1.5 ms of the truth) where the clocks were 240 ms apart at its end, and the knee had been
# left 120-240 ms out of step
TOGETHER_S = 0.005

# The network solve's priors (motionlab.clocknet). Tuned on simulated walks, bench/gait.py seeds 5-9
# (both variants) and bench/real_world.py walk seeds 10-14, for the smallest worst-case clock error
# left on shank_r-shank_l, the knees and the hips (a 3 ms knee floor gave smaller medians but a
# larger worst case; a 2 ms hip floor, or 1 ms for the pelvis's and thighs' envelope delays, let
# wrong joint centres through: 5-8 ms); reported on seeds 0-4 and 0-9 (bench/clock_network.py).
# Tuned before the simulated legs rang after heel strikes as a real walk's: with that ringing
# (preset ``skin``) the pelvis-thigh heel-strike lags are biased by up to 13 ms and the hips
# read 0.4-0.7° worse on average, up to 4.4° on one walk (docs/simulator.md, "The legs ring
# after heel strikes"; not yet solved).
# The standard deviation of a sensor's own delay of its heel-strike envelope (s) by segment kind:
# the shank's own tissue resonance shifted all of its impact lags by up to 7 ms, the other
# sensors' by ≤ 0.7 ms (the others: motionlab.clocknet.ENVELOPE_BIAS_S, 0.5 ms)
ENVELOPE_SD_S = {"shank": 0.0015, "foot": 0.0015}
# and the floor of a joint-centre fit's offset error (s): its model error locked to the stride,
# 0.1-6 ms at the knee, up to 31 ms at the hip on simulated walks (claimed errors ≈ 0.05 ms);
# elsewhere motionlab.clocknet.CENTRE_FLOOR_S (2 ms)
HIP_CENTRE_FLOOR_S = 0.005

# the most (s) the heel strikes' clocks of a knee pair may differ from the pair's own
# joint-centre fit (see the module notes): the real one-clock walk's knee disagreed by 49 ms;
# on simulated walks (bench/real_world.py seeds 0-4, 74 s) the knees' two clocks lay within
# 12 ms of each other
CORROBORATE_S = 0.030

# the largest standard error (s) of a sensor's clock in a part of the body no sensor joins to the
# root's (the legs without a pelvis sensor) for the heel strikes across to link it: 3 ms of one
# leg's clock against the other's is 1 % of step-time asymmetry at 110 steps/min
LINK_MAX_SE_S = 0.003


def synchronise(
    session: Session, protocol: Protocol, max_offset_s: float = MAX_OFFSET_S
) -> list[ClockFit]:
    """Put the protocol's sensors on one clock, in place (see the module docstring).

    Each corrected stream's ``time`` is replaced and ``attrs["clock_sync"]`` records the fit (so
    the recorded stamps can be restored); returns every fit, in the order made. The stage
    (:func:`motionlab.stages.sync`) stores them in ``session.results.clock_sync``.

    With heel strikes (a reliable impact lag between any two sensors) every sensor's clock is
    solved at once on the root sensor's (:func:`motionlab.clocknet.solve_network`) from the
    impact lags of all pairs and the joint-centre fits of all neighbours, measurements that
    break the loops set aside; each fit then has ``method`` ``network`` and says in ``other``
    what timed it. Without (arm, elbow, lumbar, clinical tasks) the sync tree as before: each
    sensor against its reference's corrected clock by the joint centre.
    """
    unsynchronise(session)
    forest = sync_forest(session, protocol)
    tree = [pair for _, pairs in forest for pair in pairs]  # every part's pairs, part by part
    segments = list(dict.fromkeys(seg for root, pairs in forest
                                  for seg in (root, *(s for p in pairs for s in p))))  # fmt: skip
    label = {seg: sensor_for_segment(session, seg) for seg in segments} if len(segments) > 1 else {}

    signals_of, envelope_of = PerStream(signals), PerStream(envelope)  # once per sensor

    def lag(a: str, b: str) -> ClockFit:
        sensors = session.sensors
        return impact_clock(sensors[label[a]], sensors[label[b]], max_offset_s, envelope_of)

    def centre(a: str, b: str, spine: bool = False) -> ClockFit:
        sensors = session.sensors  # the clocks corrected so far
        return estimate_clock(sensors[a], sensors[b], max_offset_s, signals_of, spine)

    # heel strikes: a reliable impact lag on a pair of the trees (of the parts' roots when no
    # part has a pair: the two shanks alone)
    part_of = {seg: root for root, pairs in forest for seg in (root, *(d for _, d in pairs))}
    across = [(a, b) for i, a in enumerate(segments) for b in segments[i + 1 :]
              if part_of[a] != part_of[b]]  # fmt: skip
    impacts = {(a, b): lag(a, b) for a, b in (tree or across) if label}
    if any(_reliable(f) for f in impacts.values()):  # heel strikes: every pair, all at once
        pairs = [(a, b) for i, a in enumerate(segments) for b in segments[i + 1 :]]
        impacts = {p: impacts[p] if p in impacts else lag(*p) for p in pairs}  # in this order
        fits = _synchronise_network(session, protocol, forest, label, impacts, centre)
    else:
        fits = _synchronise_tree(session, forest, label, impacts, centre)
    vendor = {session.sensors[lab].attrs.get(SHARED_CLOCK) for lab in label.values()}
    if label and len(vendor) == 1 and None not in vendor:  # every sensor on one clock a file shows
        unsynchronise(session)
        said = ", ".join(sorted(vendor))
        fits = [replace(f, status=f"{VENDOR_KEPT} ({said}); the data's fit "
                        + ("would have moved it" if f.status == "applied" else f"said: {f.status}"))
                for f in fits]  # fmt: skip
    return fits


def _synchronise_tree(session: Session, forest, label, impacts, centre) -> list[ClockFit]:
    """Each sensor against its reference's corrected clock, down each part's sync tree, by the
    joint centre (``centre(reference label, label)``; ``impacts``: the tree pairs' refused
    impact lags, kept in ``other``). A sensor whose own
    fit is not reliable but whose reference was corrected gets the reference's correction: its
    recorded timing relative to its neighbour is kept (a thigh moved while its shank stayed
    would misalign the knee by the thigh's whole correction). A part's root other than the
    first has a :data:`~motionlab.results.NOT_LINKED` fit: nothing ties it to the first."""
    fits = []
    moved: dict[str, ClockFit] = {}  # label: the correction its stamps got
    main = label[forest[0][0]] if label else ""
    t0, _ = _middle(session, main) if label else (0.0, 0.0)
    why = "no sensor joins it to {} and no reliable heel-strike lag ties their clocks"
    for ref_seg, seg in _forest_order(forest) if label else []:
        if ref_seg is None:  # a part's root
            fits.append(_not_linked(main, label[seg], t0, why.format(main)))
            continue
        ref, lab = label[ref_seg], label[seg]
        # the pair's impact lag was measured on the raw clocks; none is reliable (no heel strikes)
        fit = choose(
            centre(ref, lab, _spine(ref_seg, seg)), impacts[(ref_seg, seg)], moved.get(ref)
        )
        fits.append(fit)
        # the fit is against the reference's corrected clock: "consistent with one clock" means
        # the sensor already agrees with it; an unreliable fit tells nothing, so the sensor keeps
        # its recorded timing relative to its reference and follows the reference's correction
        use = fit if fit.status == "applied" else None
        if fit.status.startswith("not reliable"):
            use = moved.get(ref)
        if use is not None:
            _apply(session, lab, use)
            moved[lab] = use
    return fits


def _apply(session: Session, label: str, fit: ClockFit) -> None:
    stream = session.sensors[label]
    attrs = dict(stream.attrs, clock_sync=asdict(fit))
    session.sensors[label] = replace(stream, time=fit.corrected_time(stream.time), attrs=attrs)


def _synchronise_network(
    session: Session, protocol: Protocol, forest, label, impacts, centre
) -> list[ClockFit]:
    """Every sensor's clock at once from all pairwise measurements on the raw clocks
    (:func:`motionlab.clocknet.solve_network`; ``centre(label, label)``: a joint-centre fit).
    A sensor that no reliable measurement ties to
    the root follows its reference's clock (its recorded timing against it is kept). A part of
    the body no sensor joins to the root's (``forest``, :func:`.pairs.sync_forest`) is on the
    root's clock only when the heel strikes tie it well (:func:`_solve_parts`); else its
    sensors are solved on its own root's clock and that root's fit says why it is
    :data:`~motionlab.results.NOT_LINKED`."""
    tree = [pair for _, pairs in forest for pair in pairs]
    edges = [(a, b) for a, b in joint_pairs(session, protocol) if a in label and b in label]
    centres = {(a, b): centre(label[a], label[b]) for a, b in edges}
    pool = [f for f in [*impacts.values(), *centres.values()] if _reliable(f)]
    envelope_sd = {lab: ENVELOPE_SD_S[kind_side(seg)[0]] for seg, lab in label.items()
                if kind_side(seg)[0] in ENVELOPE_SD_S}  # fmt: skip
    floor = {frozenset((label[a], label[b])): _centre_floor(a, b) for a, b in edges}
    root = label[forest[0][0]]
    t0, span = _middle(session, root)
    part = {label[seg]: label[r] for r, pairs in forest for seg in (r, *(d for _, d in pairs))}

    def solve(fits: list[ClockFit], on: str) -> dict:
        return solve_network(fits, on, t0, envelope_sd, floor)

    solved, unlinked, clock_on = _solve_parts(pool, part, root, solve)
    # label: (NetworkClock or None, follows, the sensor whose clock it is on)
    clocks: dict[str, tuple] = {r: (None, "", r) for r in [root, *unlinked]}
    clocks.update({k: (v, "", clock_on[k]) for k, v in solved.items()})
    # the heel strikes' clocks must agree with every joint centre's that measured its pair: where
    # one does not, the envelopes did not peak together and none is taken
    contradicted = []
    for a, b in tree:
        if label[a] in solved or label[b] in solved:
            contradicted.append(_uncorroborated(clocks, label, centres, a, b))
    contradicted = [why.removeprefix("not reliable: ") for why in contradicted if why]
    why_all = ""  # every sensor's status says why the heel strikes were not taken, and where
    if contradicted:
        why_all = ("not reliable: the heel strikes were not taken, a joint centre did not "
                   f"confirm them ({'; '.join(contradicted)})")  # fmt: skip
        clocks = {r: (None, "", r) for r in part.values()}
        unlinked = {
            r: f"no sensor joins it to {root} and the heel strikes were not taken (a "
            "knee's joint centre disagreed with them)"
            for r in part.values()
            if r != root
        }
    for ref_seg, seg in tree:  # not tied to the root: the reference's clock (tree order)
        if label[seg] not in clocks:
            clock, _, on = clocks[label[ref_seg]]
            clocks[label[seg]] = (clock, label[ref_seg], on)
    fits = []
    for _, seg in _forest_order(forest):
        lab = label[seg]
        if lab in unlinked:  # a part's root, or the first of sensors tied only to each other
            fits.append(_not_linked(root, lab, t0, unlinked[lab]))
            continue
        clock, follows, on = clocks[lab]
        fit = _network_fit(on, lab, clock, follows, t0, span, why_all)
        fits.append(fit)
        if fit.status == "applied" or (follows and clock is not None):
            _apply(session, lab, replace(fit, status="applied") if follows else fit)
    return fits


def _solve_parts(pool: list[ClockFit], part: dict[str, str], root: str, solve) -> tuple[
        dict, dict[str, str], dict[str, str]]:  # fmt: skip
    """The network clocks (``solve(fits, root)``) of every sensor, ``{part's root: why it is
    not linked}`` for the parts of the body (``part``: ``{label: its part's root}``) whose
    clocks the heel strikes do not tie to ``root``'s well: no reliable lag across, or the
    part's sensors known only to more than ``LINK_MAX_SE_S`` on the root's clock. Their lags
    across are then left out, the rest solved again, and each such part solved on its own
    root's clock (its sensors' clocks against its root's). Sensors of a part that nothing ties
    to its root but that are tied to each other are solved on the first one's clock, which is
    then not linked too (a walk whose pelvis no heel strike times: the knees still need each
    thigh and shank on one clock). The third dict: ``{label: the sensor whose clock its
    solution is on}``."""
    unlinked: dict[str, str] = {}
    while True:
        fits = [f for f in pool if part[f.reference] not in unlinked
                and part[f.sensor] not in unlinked]  # fmt: skip
        solved = solve(fits, root)
        weak = {}
        for r in dict.fromkeys(part.values()):
            if r == root or r in unlinked:
                continue
            members = [lab for lab, p in part.items() if p == r]
            se = [solved[lab].offset_se_s for lab in members if lab in solved]
            if r not in solved:
                weak[r] = (f"no sensor joins it to {root} and no reliable heel-strike lag ties "
                           "their clocks")  # fmt: skip
            elif max(se) > LINK_MAX_SE_S:
                weak[r] = (f"no sensor joins it to {root} and the heel strikes tie their clocks "
                           f"only to ± {1e3 * max(se):.1f} ms ({1e3 * LINK_MAX_SE_S:g} ms "
                           "needed)")  # fmt: skip
        if not weak:
            break
        unlinked.update(weak)
    on = {lab: root for lab in solved}
    for r in unlinked:
        own = [f for f in pool if part[f.reference] == r and part[f.sensor] == r]
        found = solve(own, r)
        solved.update(found)
        on.update(dict.fromkeys(found, r))
    # sensors of a part that nothing ties to its root but that reliable measurements tie to
    # each other (the legs by their heel strikes, none of them to the pelvis): each such group
    # on its first sensor's clock, that sensor not linked to the part's root
    for r in [root, *unlinked]:
        loose = [lab for lab, p in part.items() if p == r and lab != r and lab not in solved]
        ties = [f for f in pool if f.reference in loose and f.sensor in loose]
        for lab in loose:
            if lab in solved:
                continue
            found = solve(ties, lab)
            if found:
                solved.update(found)
                on.update(dict.fromkeys(found, lab))
                unlinked[lab] = (
                    f"no reliable heel-strike lag or joint-centre fit ties it to {r}; the "
                    f"heel strikes and joint centres tie {', '.join(found)} to it"
                )
    return solved, unlinked, on


def _forest_order(forest) -> list[tuple[str | None, str]]:
    """Each part's root (as ``(None, root)``; not the first part's) then its tree's pairs."""
    out: list[tuple[str | None, str]] = []
    for i, (root, pairs) in enumerate(forest):
        out += ([(None, root)] if i else []) + list(pairs)
    return out


def _middle(session: Session, label: str) -> tuple[float, float]:
    """Mid-time and duration (s) of sensor ``label``'s recording."""
    time = session.sensors[label].time
    return float(np.mean(time[[0, -1]])), float(np.ptp(time))


def _not_linked(root: str, lab: str, t0: float, why: str) -> ClockFit:
    """The fit of a part's root sensor ``lab`` whose clock nothing tied to ``root``'s."""
    return ClockFit(root, lab, 0.0, 0.0, t0, np.inf, np.inf, np.nan, 0.0, f"{NOT_LINKED}: {why}",
                    NETWORK)  # fmt: skip


def _uncorroborated(clocks: dict, label: dict, centres: dict, ref_seg: str, seg: str) -> str:
    """For a tree pair of which the network timed at least one sensor: where the network's
    clocks (``clocks``: ``{label: (NetworkClock or None, follows, the sensor whose clock it is
    on)}``, ``None`` that sensor's own) put
    ``seg``'s sensor more than ``CORROBORATE_S`` from where the pair's own joint-centre fit
    does (``centres``, by segment pair; any fit that was made, also one its residual or its
    standard error refused), or time only one of the two, or the pair has no such fit, in
    words; empty when they agree (and for a hip, whose joint centre is no check)."""
    if {kind_side(ref_seg)[0], kind_side(seg)[0]} == {"pelvis", "thigh"}:
        return ""  # the hip's joint centre is no check (HIP_CENTRE_FLOOR_S)
    ons = {clocks[lab][2] for lab in (label[ref_seg], label[seg]) if lab in clocks}
    if len(ons) == 2:  # a joint's two sensors on clocks nothing ties: its angles need one
        return (f"not reliable: the heel strikes put {label[ref_seg]} and {label[seg]} on clocks "
                "nothing ties together, so their joint centre cannot confirm them")  # fmt: skip
    untimed = [lab for lab in (label[ref_seg], label[seg]) if lab not in clocks]
    if untimed:  # it would follow the other's correction: nothing left to compare
        timed = label[seg] if untimed[0] == label[ref_seg] else label[ref_seg]
        return (f"not reliable: the heel strikes time {timed} but not {untimed[0]}, so their "
                "joint centre cannot confirm them")  # fmt: skip
    ref_clock, clock = clocks[label[ref_seg]][0], clocks[label[seg]][0]
    fit = centres.get((ref_seg, seg))
    sign = 1.0
    if fit is None:
        fit, sign = centres.get((seg, ref_seg)), -1.0
    if fit is None or not np.isfinite(fit.residual):  # no fit made (too little shared signal)
        return (f"not reliable: no joint-centre fit of {label[ref_seg]} and {label[seg]} to "
                "confirm the heel strikes")  # fmt: skip

    def at(c) -> float:
        return 0.0 if c is None else c.offset_s + c.drift * (fit.t_mid_s - c.t_mid_s)

    heel, centre = at(clock) - at(ref_clock), sign * fit.offset_s
    if abs(heel - centre) <= CORROBORATE_S:
        return ""
    return (f"not reliable: the heel strikes put {label[seg]} {1e3 * heel:+.0f} ms from "
            f"{label[ref_seg]}, their joint centre {1e3 * centre:+.0f} ms")  # fmt: skip


def _network_fit(
    root: str, lab: str, clock, follows: str, t0: float, span: float, why: str = ""
) -> ClockFit:
    """The :class:`ClockFit` of one sensor's network solution (``method`` ``network``) on the
    root's clock; ``follows``: the sensor whose clock it takes when nothing ties it, or when
    ``why`` says why its own is not taken; ``t0`` and ``span`` the root's mid-time and
    duration (s)."""
    if follows:
        why = why or ("not reliable: no reliable heel-strike lag or joint-centre fit ties it to "
                      "the others")  # fmt: skip
        why = f"{why}; follows {follows}'s clock"
        if clock is None:
            return ClockFit(root, lab, 0.0, 0.0, t0, np.inf, np.inf, np.nan, 0.0, why, NETWORK)
        return ClockFit(root, lab, clock.offset_s, clock.drift, clock.t_mid_s, clock.offset_se_s,
                        clock.drift_se, np.nan, 0.0, why, NETWORK)  # fmt: skip
    # a correction smaller than its standard error is not applied; not twice it, as for one
    # pair: the priors' share of the error (a shank's 1.3 ms) would leave real 2-3 ms offsets
    # uncorrected (gait seed 0: shank_r 1.9 ms off)
    worst = float(np.hypot(clock.offset_se_s, clock.drift_se * span / 2))
    ends = np.abs(clock.offset_s) + np.abs(clock.drift) * span / 2
    status = "applied" if ends > max(MIN_CORRECTION_S, worst) else "consistent with one clock"
    return ClockFit(root, lab, clock.offset_s, clock.drift, clock.t_mid_s, clock.offset_se_s,
                    clock.drift_se, np.nan, 0.0, status, NETWORK, clock.summary())  # fmt: skip


def _spine(a: str, b: str) -> bool:
    """Whether segments ``a`` and ``b`` are joined by the spine (pelvis, lumbar, thorax): the
    joint-centre fit's spine rule (:func:`motionlab.clocksync.joint_centre.estimate_clock`)."""
    kinds = {kind_side(a)[0], kind_side(b)[0]}
    return len(kinds) == 2 and kinds <= {"pelvis", "lumbar", "thorax"}


def _reliable(fit: ClockFit) -> bool:
    return fit.status in RELIABLE


def choose(
    centre: ClockFit, impacts: ClockFit, reference_moved: ClockFit | None = None
) -> ClockFit:
    """The fit :func:`synchronise` uses for one pair, with the other's answer in ``other``;
    ``reference_moved``: the correction the reference's stamps got before ``centre`` was fitted
    against them (``impacts`` is on the raw clocks).

    The joint-centre fit when the impact lag is not reliable (no heel strikes: the arm, lumbar
    and clinical tasks) or when both are reliable and agree (their offsets within twice their
    combined standard error plus ``IMPACT_BIAS_S``: the joint centre is the more precise);
    the impact lag when it is reliable and the joint-centre fit is not or disagrees (its
    model error locked to the stride gave 7-68 ms wrong offsets with standard errors of
    0.1 ms on simulated walks); the joint-centre fit, applied, when the two were each refused
    for what the other does not suffer from (its residual; steps as regular as the search) and
    agree within ``TOGETHER_S`` over the recording (:func:`_together`).
    """
    if not _reliable(impacts):
        if not _reliable(centre) and _together(centre, _on_corrected(impacts, reference_moved)):
            ends = np.abs(centre.error_s(np.array([0.0, 2.0 * centre.t_mid_s])))
            status = "applied" if ends.max() > MIN_CORRECTION_S else "consistent with one clock"
            return replace(
                centre,
                status=status,
                other=f"{_summary(impacts)}; the two agree "
                f"within {1e3 * TOGETHER_S:g} ms: each refused alone, taken together",
            )
        # a recording too short for the heel-strike method (a seated trunk's 12 s) says nothing
        # of it: 'heel strikes: not enough shared recording' read as a fault of a seated trial
        ran = not impacts.status.startswith(TOO_SHORT)
        return replace(centre, other=_summary(impacts) if ran else "")
    gap = abs(centre.offset_s - impacts.offset_s)
    allowed = 2.0 * np.hypot(centre.offset_se_s, impacts.offset_se_s) + IMPACT_BIAS_S
    if _reliable(centre) and gap <= allowed:
        return replace(centre, other=_summary(impacts))
    why = "not reliable" if not _reliable(centre) else f"{1e3 * gap:.1f} ms away"
    return replace(impacts, other=f"{_summary(centre)} ({why})")


def _on_corrected(fit: ClockFit, moved: ClockFit | None) -> ClockFit:
    """``fit``, made on the reference's recorded clock, against its clock corrected by
    ``moved`` (the sensor reads ``t + c(t)`` on the recorded clock, which reads ``t + m(t)``
    on the corrected one)."""
    if moved is None:
        return fit
    return replace(fit, offset_s=fit.offset_s + float(moved.error_s(fit.t_mid_s)),
                   drift=fit.drift + moved.drift)  # fmt: skip


def _together(centre: ClockFit, impacts: ClockFit) -> bool:
    """Whether a joint-centre fit refused only for its residual and a heel-strike fit refused
    only for regular steps give clocks within ``TOGETHER_S`` of each other from the start of
    the recording (0 s) to twice its middle."""
    soft = centre.status.startswith(POOR_FIT) and impacts.status.startswith(REGULAR_STEPS)
    if not soft or not (np.isfinite(centre.offset_se_s) and np.isfinite(impacts.offset_se_s)):
        return False
    t = np.array([0.0, centre.t_mid_s, 2.0 * centre.t_mid_s])
    return bool(np.abs(centre.error_s(t) - impacts.error_s(t)).max() <= TOGETHER_S)


def _summary(fit: ClockFit) -> str:
    """``heel strikes: +12.3 ms ± 0.4 ms, applied`` (or the status alone when no offset); the
    impact method named by what it times, for the report's reader."""
    method = "heel strikes" if fit.method == IMPACTS else fit.method
    if not np.isfinite(fit.offset_se_s):
        return f"{method}: {fit.status}"
    return (f"{method}: {1e3 * fit.offset_s:+.1f} ± {1e3 * fit.offset_se_s:.1f} ms, "
            f"{fit.status}")  # fmt: skip


def unsynchronise(session: Session) -> None:
    """Restore every sensor's recorded stamps (undo :func:`synchronise`), in place; the
    stage's record (``session.results.clock_sync``) is left to the stage."""
    for label, stream in list(session.sensors.items()):
        if "clock_sync" in stream.attrs:
            fit = ClockFit(**stream.attrs["clock_sync"])
            attrs = {k: v for k, v in stream.attrs.items() if k != "clock_sync"}
            session.sensors[label] = replace(
                stream, time=fit.recorded_time(stream.time), attrs=attrs
            )


def describe(fit: ClockFit) -> str:
    """One line: ``shank_r vs thigh_r (impacts): +12.3 ms, drift −21 ppm (± 0.4 ms, 9 ppm) —
    applied; joint centre: ...`` (the other method's answer last); for a network fit
    ``shank_r on pelvis's clock (every pair at once): ... — applied; timed by heel strikes with
    ...; set aside: ...`` (what timed it, what was set aside and why); for a part's root that
    nothing tied to the root's clock ``thigh_l against thigh_r's clock: not linked: ...``."""
    head = f"{fit.sensor} vs {fit.reference} ({fit.method}):"
    if fit.method == NETWORK:
        head = f"{fit.sensor} on {fit.reference}'s clock (every pair at once):"
    if fit.status.startswith(NOT_LINKED):  # a part of the body on a clock of its own
        return f"{fit.sensor} against {fit.reference}'s clock: {fit.status}"
    other = f"; {fit.other}" if fit.other else ""
    if not np.isfinite(fit.offset_se_s):
        moving = f" ({fit.moving_s:.0f} s of shared movement)" if fit.moving_s > 0 else ""
        return f"{head} {fit.status}{moving}{other}"
    return (
        f"{head} {1e3 * fit.offset_s:+.1f} ms, drift {1e6 * fit.drift:+.0f} ppm "
        f"(± {1e3 * fit.offset_se_s:.1f} ms, {1e6 * fit.drift_se:.0f} ppm) — {fit.status}" + other
    )


def _centre_floor(a: str, b: str) -> float:
    """Floor (s) of the joint-centre fit's offset error between segments ``a`` and ``b``."""
    kinds = {kind_side(a)[0], kind_side(b)[0]}
    return HIP_CENTRE_FLOOR_S if kinds == {"pelvis", "thigh"} else CENTRE_FLOOR_S
