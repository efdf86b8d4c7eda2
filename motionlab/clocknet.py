"""All sensors' clocks at once from every pairwise clock measurement, with loop-consistency checks.

:mod:`motionlab.clocksync` measures the clock of one sensor against another's in two ways: the
joint centre two neighbouring segments share (``estimate_clock``) and the lag of the heel-strike
transients any two leg or pelvis sensors see (``impact_clock``). Five leg and pelvis sensors give
10 impact lags and 4 joint-centre fits for 4 unknown offsets (and drifts): the measurements are
redundant, and one that disagrees with the loops it closes can be found and set aside.

**Model.** Every sensor ``k`` reads ``T + o_k + d_k (T − T₀)`` at the root sensor's time ``T``
(``o_root = d_root = 0``). A pairwise fit of ``b`` against ``a`` (offset ``y`` at its own
``t_mid``, drift ``δ``) measures

    y = o_b − o_a + (d_b − d_a)(t_mid − T₀) [+ β_b − β_a for an impact lag],   δ = d_b − d_a,

with variance its own standard error squared plus a floor for the errors its scatter does not
show (``CENTRE_FLOOR_S``: the joint-centre model error locked to the stride; ``PAIR_FLOOR_S``).
``β_k`` is sensor ``k``'s own delay of its transient envelope: on simulated walks a shank's
tissue resonance shifted *every* impact lag of that shank by the same 2-7 ms (seed 1 asymmetric:
−7.3 ms on all four of shank_r's), which no loop of impact lags can show, since the delay cancels
around every loop. Each ``β_k`` has a prior ``0 ± ENVELOPE_BIAS_S`` (the caller gives shanks a
larger one); only a joint-centre fit of that sensor can contradict it.

**Weighted least squares with data snooping** (Baarda 1968): solve, compute every measurement's
standardised residual ``w = r / σ_r`` (``σ_r²`` the residual's own variance, the diagonal of
``Σ_y − A Σ_x Aᵀ``; a measurement no other closes a loop with has ``σ_r ≈ 0`` and cannot be
tested), set aside the one with the largest ``|w|`` above ``REJECT_W``, and solve again until
none is. Two exceptions: a measurement whose residual is correlated beyond ``SEPARABLE`` with
another's is not set aside, since an error in either would look the same (a shank's knee joint
centre against that shank's envelope prior: the data cannot tell which is wrong, so both are kept
and the solution weighs them); and the envelope priors are priors, never set aside. Kept
measurements and priors with ``|w|`` above ``DISPUTE_W`` are reported as disagreeing, so the
clinician sees where a clock rests on a judgement between two signals.

Measured (bench/clock_network.py, motionlab.clocksync's priors): on bench/gait.py's seed 1
asymmetric walk shank_r is left 5.2 ms off (the per-pair choice it replaces: 7.9 ms), the
other sensors within 0.9 ms.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from motionlab.results import ClockFit

JOINT_CENTRE, IMPACTS, NETWORK = "joint centre", "impacts", "network"  # ClockFit.method
# floors on the standard error of one measurement's offset (s): the errors its block scatter
# does not show; with the priors, tuned on simulated walks (bench/gait.py seeds 5-9, both
# variants; bench/real_world.py walk seeds 10-14), reported on seeds 0-4 and 0-9
CENTRE_FLOOR_S = 0.002  # joint centre: its model error is locked to the stride
PAIR_FLOOR_S = 0.0005  # impact lag of one pair, beyond the sensors' envelope delays
ENVELOPE_BIAS_S = 0.0005  # prior standard deviation of one sensor's envelope delay β_k (by
# default; motionlab.clocksync gives shanks and feet their own, larger one)
DRIFT_FLOOR = 5e-6  # floor on the standard error of one measurement's drift
REJECT_W = 3.0  # set aside a measurement whose standardised residual exceeds this
DISPUTE_W = 2.0  # a kept measurement (or prior) beyond this is reported as disputed
SEPARABLE = 0.9  # two residuals correlated beyond this cannot tell which measurement is wrong
TESTABLE = 0.05  # a residual whose variance is below this share of σ² cannot be tested


@dataclass
class NetworkClock:
    """One sensor's clock on the root's: it reads ``T + offset_s + drift (T − t_mid_s)`` at root
    time ``T`` (s), with standard errors; ``used``: (method, other sensor) of each measurement
    that timed it; ``rejected`` and ``disputed``: one phrase per measurement set aside, or kept
    though it disagrees (clinician-readable, :meth:`summary`)."""

    offset_s: float
    drift: float
    t_mid_s: float
    offset_se_s: float
    drift_se: float
    used: list[tuple[str, str]] = field(default_factory=list)  # (method, other sensor)
    rejected: list[str] = field(default_factory=list)
    disputed: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """``timed by heel strikes with pelvis, thigh_l; joint centre with thigh_r; set aside:
        ...; disagreeing, kept and weighed (cannot tell which is wrong): ...``."""
        by: dict[str, list[str]] = {}
        for method, other in self.used:
            by.setdefault(method, []).append(other)
        words = {IMPACTS: "heel strikes with", JOINT_CENTRE: "joint centre with"}
        parts = [
            "timed by " + "; ".join(f"{words.get(m, m)} {', '.join(o)}" for m, o in by.items())
        ]
        if self.rejected:
            parts.append("set aside: " + "; ".join(self.rejected))
        if self.disputed:
            parts.append("disagreeing, kept and weighed (cannot tell which is wrong): "
                         + "; ".join(self.disputed))  # fmt: skip
        return "; ".join(parts)


@dataclass
class _Row:
    """One offset measurement (with its drift row) or one envelope prior."""

    fit: ClockFit | None  # None: the envelope prior of ``sensor``
    sensor: str
    active: bool = True
    w: float = 0.0  # standardised residual
    r: float = 0.0  # residual (s)
    twins: set[int] = field(default_factory=set)  # rows an error here cannot be told from
    needed: bool = False  # the only measurement that ties a sensor: not set aside


def solve_network(
    fits: Sequence[ClockFit],
    root: str,
    t0: float | None = None,
    envelope_sd: Mapping[str, float] | None = None,
    centre_floor: Mapping[frozenset[str], float] | None = None,
) -> dict[str, NetworkClock]:
    """Every sensor's clock on ``root``'s from reliable pairwise ``fits`` (see the module
    docstring); sensors that no chain of fits ties to ``root`` are left out.

    ``fits``: :class:`ClockFit` of ``sensor`` against ``reference`` with ``method`` ``joint
    centre`` or ``impacts``; ``t0`` the root time (s) the offsets refer to (default: the mean
    of the fits' ``t_mid_s``); ``envelope_sd``: prior standard deviation (s) of a sensor's
    envelope delay (default ``ENVELOPE_BIAS_S``); ``centre_floor``: floor (s) of the joint-centre
    fit of a pair ``frozenset({a, b})`` (default ``CENTRE_FLOOR_S``).
    """
    envelope_sd, centre_floor = dict(envelope_sd or {}), dict(centre_floor or {})

    def floor(f: ClockFit) -> float:
        if f.method != JOINT_CENTRE:
            return PAIR_FLOOR_S
        return centre_floor.get(frozenset((f.reference, f.sensor)), CENTRE_FLOOR_S)

    fits = [f for f in fits if np.isfinite(f.offset_se_s) and np.isfinite(f.drift_se)]
    reach = _reachable(fits, root)
    fits = [f for f in fits if f.reference in reach and f.sensor in reach]
    if t0 is None:
        t0 = float(np.mean([f.t_mid_s for f in fits])) if fits else 0.0
    unknown = sorted(reach - {root})
    if not unknown:
        return {}
    rows = [_Row(f, f.sensor) for f in fits]
    impact_sensors = sorted(
        {s for f in fits if f.method == IMPACTS for s in (f.reference, f.sensor)}
    )
    rows += [_Row(None, s) for s in impact_sensors]
    index = {s: i for i, s in enumerate(unknown)}  # o_k at 2i, d_k at 2i + 1
    beta = {s: 2 * len(unknown) + i for i, s in enumerate(impact_sensors)}
    n = 2 * len(unknown) + len(impact_sensors)
    while True:
        x, cov, a, sigma, y = _solve(rows, index, beta, n, t0, floor, envelope_sd)
        on = [k for k, row in enumerate(rows) if row.active]
        # covariance of the offset rows' residuals: Σ_y − A Σ_x Aᵀ
        cr = np.diag(sigma[on] ** 2) - a[on] @ cov @ a[on].T
        sd_r = np.sqrt(np.clip(np.diag(cr), 0.0, None))
        testable = sd_r > np.sqrt(TESTABLE) * sigma[on]
        sd_r = np.where(testable, sd_r, 1.0)
        r = y[on] - a[on] @ x
        w = np.where(testable, r / sd_r, 0.0)
        rho = cr / np.outer(sd_r, sd_r)
        for i, k in enumerate(on):
            rows[k].w, rows[k].r = float(w[i]), float(r[i])
            # an error here would look the same there: cannot tell which of them is wrong
            rows[k].twins = {on[j] for j in np.flatnonzero(testable & (np.abs(rho[i]) > SEPARABLE))
                             if j != i}  # fmt: skip
        candidates = [k for k in on if abs(rows[k].w) > REJECT_W and rows[k].fit is not None
                      and not rows[k].twins and not rows[k].needed]  # fmt: skip
        if not candidates:
            break
        best = max(candidates, key=lambda k: abs(rows[k].w))
        rows[best].active = False
        if not _reachable([r.fit for r in rows if r.active and r.fit], root) >= reach:
            rows[best].active, rows[best].needed = True, True  # the only tie of a sensor
    out = {}
    for s, i in index.items():
        o, d = 2 * i, 2 * i + 1
        out[s] = NetworkClock(float(x[o]), float(x[d]), t0, float(np.sqrt(cov[o, o])),
                              float(np.sqrt(cov[d, d])))  # fmt: skip
    for k, row in enumerate(rows):
        if not row.active:  # its misfit on the solution without it
            row.r = float(y[k] - a[k] @ x)
        disputed = row.active and abs(row.w) > DISPUTE_W
        if row.fit is None:
            if disputed and row.sensor in out:
                out[row.sensor].disputed.append(
                    f"its own heel-strike timing ({1e3 * _beta(x, beta, row.sensor):+.1f} ms)"
                )
            continue
        f = row.fit
        for me, other in ((f.sensor, f.reference), (f.reference, f.sensor)):
            if me not in out:
                continue
            what = f"{'heel strikes' if f.method == IMPACTS else f.method} with {other}"
            if row.active:
                out[me].used.append((f.method, other))
                if disputed:
                    out[me].disputed.append(f"{what} ({1e3 * row.r:+.1f} ms)")
            else:
                out[me].rejected.append(f"{what} ({1e3 * row.r:+.1f} ms, {abs(row.w):.1f} SE "
                                        "off the others)")  # fmt: skip
    return out


def _beta(x: np.ndarray, beta: dict[str, int], sensor: str) -> float:
    return float(x[beta[sensor]]) if sensor in beta else 0.0


def _solve(rows, index, beta, n, t0, floor, envelope_sd):
    """Weighted least squares over the active rows; returns the solution, its covariance, and
    every row's design vector, standard deviation and value (offset rows, in ``rows`` order)."""
    a = np.zeros((len(rows), n))
    sigma, y = np.ones(len(rows)), np.zeros(len(rows))
    drift_a, drift_s, drift_y = [], [], []
    for k, row in enumerate(rows):
        if row.fit is None:
            a[k, beta[row.sensor]] = 1.0
            sigma[k] = envelope_sd.get(row.sensor, ENVELOPE_BIAS_S)
            continue
        f = row.fit
        d = np.zeros(n)
        for s, sign in ((f.sensor, 1.0), (f.reference, -1.0)):
            if s in index:
                a[k, 2 * index[s]] += sign
                a[k, 2 * index[s] + 1] += sign * (f.t_mid_s - t0)
                d[2 * index[s] + 1] += sign
            if f.method == IMPACTS:
                a[k, beta[s]] += sign
        sigma[k] = float(np.hypot(f.offset_se_s, floor(f)))
        y[k] = f.offset_s
        if row.active:
            drift_a.append(d)
            drift_s.append(float(np.hypot(f.drift_se, DRIFT_FLOOR)))
            drift_y.append(f.drift)
    on = np.array([r.active for r in rows])
    design = np.vstack([a[on], np.array(drift_a).reshape(-1, n)])
    scale = np.r_[sigma[on], drift_s]
    values = np.r_[y[on], drift_y]
    weighted = design / scale[:, None]
    info = weighted.T @ weighted
    cov = np.linalg.pinv(info)
    x = cov @ (weighted.T @ (values / scale))
    return x, cov, a, sigma, y


def _reachable(fits: Sequence[ClockFit], root: str) -> set[str]:
    """Sensors tied to ``root`` by a chain of ``fits`` (``root`` included)."""
    seen, todo = {root}, [root]
    while todo:
        node = todo.pop()
        for f in fits:
            for a, b in ((f.reference, f.sensor), (f.sensor, f.reference)):
                if a == node and b not in seen:
                    seen.add(b)
                    todo.append(b)
    return seen
