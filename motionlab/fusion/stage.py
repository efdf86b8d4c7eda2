"""The fusion stage's computation: every chosen sensor's orientation by one estimator.

:func:`motionlab.stages.fuse` (``motionlab fuse`` and ``motionlab run``) calls
:func:`fuse_session` and stores what it returns in ``session.results.fusion``. Each
sensor's :class:`~motionlab.results.FusionEntry` holds the estimator's ``name``, ``quat``
((N, 4), sensor → ENU earth, on the sensor's own time stamps, which are passed to the
estimator so that packet-loss gaps are bridged), its ``params``, whether the ``magnetometer``
was used, and what the estimator reports besides: ``gyro_bias``, ``rest``, ``mag_disturbed``,
the marker ``scenario``, and ``gaps_bridged_s`` (the gaps it ran across).

An estimator with accelerometer-bias states (the default) also gives the entry's ``acc_bias``,
the bias that a sensor-to-segment calibration takes off the accelerometer at its rests
(:func:`calibration_acc_bias`: the 6-D smoother again, with the wider prior
:data:`CALIBRATION_ACC_BIAS_INIT`, over the rests and the movement next to them only, where
that movement can level the rests, :func:`levels_its_rests`).

Samples that are not numbers (NaN, ±inf in a channel fused) are not left to spread: a run of
them up to :data:`NAN_BRIDGE_MAX_S` (from the last finite sample before to the first after, as
ingest fills time gaps up to its ``--gap-max`` default) is bridged by holding the last finite
sample, and listed in the entry's ``nan_bridged_s``. Ingest drops longer runs in the
accelerometer or gyroscope, which leaves the packet-loss gap they are
(:func:`motionlab.timebase.drop_nan_runs`; :func:`motionlab.stages.prepare` for a session
file). One that reaches the fusion all the same (a session not prepared, or the magnetometer of
a 9-D fusion) is refused (:class:`~motionlab.errors.InputError` naming the sensor, the channels
and the time span), as the orientation there would be a guess. An estimate that is not finite
everywhere (a filter driven to NaN by implausible values such as 1e308) is refused too, with its
first bad time and share: no NaN orientation reaches the joint angles and metrics.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.fusion import _mekf_blocks, registry
from motionlab.fusion.rest import fusion_rest
from motionlab.results import ClockFit, FusionEntry
from motionlab.rotations import rotate
from motionlab.session import Session
from motionlab.timebase import NAN_BRIDGE_MAX_S, joined_spans, long_nan_runs, runs

Progress = Callable[[list[str], str], Iterable[str]]

#: prior standard deviation (m/s²) of the accelerometer bias estimated for a calibration's rests
CALIBRATION_ACC_BIAS_INIT = 0.5
#: movement (s) on either side of each rest over which that bias is estimated
CALIBRATION_WINDOW_S = 45.0
#: mean tilt (deg) of a rest's vertical over the movement next to it above which that movement's
#: inclination is not carried to the rest (:func:`levels_its_rests`)
CALIBRATION_MAX_TILT_DEG = 30.0
#: rests whose gravity directions (sensor frame) differ by this much (deg) are different poses,
#: which determine the bias through the gyroscope whatever the movement between them
CALIBRATION_POSES_DEG = 30.0
#: a movement whose headings (a horizontal sensor axis of the rests, in the earth frame) have a
#: mean resultant length above this keeps a bias's horizontal part pointing one way in the earth
#: frame, as the walker's own speed change at the walk's start does: it cannot tell them apart
#: (:func:`levels_its_rests`)
CALIBRATION_MAX_HEADING_CONCENTRATION = 0.6


def fusable(session: Session, labels: list[str] | None = None) -> list[str]:
    """The sensors (of ``labels``, default all) that have a gyroscope and an accelerometer; an
    :class:`InputError` for a label the session lacks."""
    if isinstance(labels, str):  # one label, not its letters
        labels = [labels]
    chosen = list(session.sensors) if labels is None else list(labels)
    unknown = [k for k in chosen if k not in session.sensors]
    if unknown:
        raise InputError(
            f"no sensor '{unknown[0]}' in the session",
            where="sensors",
            remedy=f"name sensors of the session: {', '.join(session.sensors) or 'none'}",
            argument="sensors",
        )
    return [
        k
        for k in chosen
        if session.sensors[k].gyr is not None and session.sensors[k].acc is not None
    ]


def fuse_session(
    session: Session,
    name: str = "default",
    params: dict[str, str] | None = None,
    sensors: list[str] | None = None,
    *,
    force: bool = False,
    path: str | Path | None = None,
    references: dict[str, Any] | None = None,
    magnetometer: bool = True,
    progress: Progress | None = None,
) -> dict[str, FusionEntry]:
    """Run estimator ``name`` on ``sensors``: one :class:`FusionEntry` per sensor, not stored
    (:func:`motionlab.stages.fuse` stores them).

    Parameters
    ----------
    session
        The session (its ``results.fusion`` is only read, for entries already there).
    name, params
        Registered estimator and its parameters as text (``{"beta": "0.1"}``), checked before
        any work.
    sensors
        Sensor labels (default: every sensor with gyroscope and accelerometer).
    force
        Replace existing entries; without it an existing entry is an :class:`InputError`
        naming ``path`` (the session file).
    references
        Marker reference vectors per sensor label (IMU + marker fusion).
    magnetometer
        Use the magnetometer where the sensor has one (``False``: 6-D, arbitrary heading).
    progress
        ``progress(labels, text)`` wraps the iteration over the sensors (a progress bar).

    Returns
    -------
    dict
        Sensor label → its entry (module docstring), in the order fused.
    """
    est = registry.get(name)
    params = dict(params or {})
    registry.make_params(est, params)  # fail on a bad parameter before any work
    sensors = fusable(session) if sensors is None else list(sensors)
    store = session.results.fusion
    for label in sensors:
        if label in store and not force:
            raise InputError(
                "already holds a fusion result",
                path,
                f"results/fusion/{label}",
                "add force=True to replace it",
                argument="force",
            )
    text = f"fusing ({est.name}{'' if magnetometer else ', 6-D'})"
    if est.name == registry.DEFAULT_ESTIMATOR and _mekf_blocks.compiled() is False:
        text += " - compiling it for this machine first (once after installing; 20-30 s)"
    done: dict[str, FusionEntry] = {}
    for label in progress(sensors, text) if progress else sensors:
        s = session.sensors[label]
        mag = s.mag if magnetometer else None
        ref = (references or {}).get(label)
        bridged = bridged_spans(label, s.time, {"gyr": s.gyr, "acc": s.acc, "mag": mag}, path)
        res = registry.estimate(
            est.name, s.gyr, s.acc, mag, s.rate_hz, references=ref, time=s.time,
            filled_spans=filled_spans(s, path), **params,
        )  # fmt: skip
        _check_finite(label, est.name, s.time, res.quat, path)
        resampled = res.extra.get("resampled")  # packet-loss gaps the estimator ran across
        done[label] = FusionEntry(
            res.name,
            res.quat,
            res.params,
            magnetometer=mag is not None,
            scenario=res.extra.get("scenario"),
            gaps_bridged_s=None if resampled is None else resampled["spans_s"],
            nan_bridged_s=bridged or None,
            gyro_bias=res.gyro_bias,
            rest=res.rest,
            mag_disturbed=res.mag_disturbed,
            acc_bias=_calibration_bias(res, s, params),
            gaps_missed_deg=res.extra.get("gaps_missed_deg"),
        )
    return done


def calibration_acc_bias(
    gyr: np.ndarray,
    acc: np.ndarray,
    rate: float,
    time: np.ndarray | None = None,
    filled: Any = None,
    window_s: float | None = None,
    **params: Any,
) -> np.ndarray:
    """The accelerometer bias (N, 3) m/s², sensor frame, that a sensor-to-segment calibration
    takes off the accelerometer at its rests (:func:`motionlab.segments.corrected_acc`).

    The 6-D smoother's bias states (:mod:`motionlab.fusion.mekf`, ``params`` as for the fusion)
    with the prior widened to :data:`CALIBRATION_ACC_BIAS_INIT`. A stand's own accelerometer
    cannot tell its inclination from a bias; the movement next to it can (a walk's horizontal
    bias turns with its turns and averages out) and the gyroscope carries that inclination to
    the stand. The fusion's own prior (0.1 m/s²) keeps the rests' orientation close to their
    accelerometer, which is what is most accurate for the orientation on the real BROAD
    benchmark (0.5 there: mean total 1.59 → 1.70°); at that prior the stand keeps most of its
    tilt (simulated stand + walk, seeds 20–25: 0.74° against 0.81° without bias states), and
    with it a constant offset in every angle calibrated there. With 0.5 the calibration sees
    the bias the movement determines (0.45°). Measured in ``bench/real_world.py``: worst knee
    flexion RMSE of seeds 0–9 2.52 → 1.79°, worst knee ab/adduction 3.12 → 2.86°. On the raw
    accelerometer (``acc_lowpass_tau`` 0): the pre-filter's movement carries its first pass's
    bias (the rest of it, turned with the sensor, is averaged out), which anchored the bias to
    that pass (simulated walks, ``tests/test_fusion_accbias.py``: stand tilt 0.54 → 0.92°).
    ``filled``: the gaps ingest filled in ``time`` (:func:`filled_spans`), as for the fusion.

    The smoother only sees the bias at rests (in motion its rows leave the bias out, see
    :mod:`motionlab.fusion.mekf`), so it runs only over every rest and ``window_s`` (default
    :data:`CALIBRATION_WINDOW_S`) of the movement on either side, overlapping windows joined.
    The windows are then joined through the bias they share (:func:`_joined_bias`), as the
    whole recording's smoother joins rests in different poses or headings; between two
    windows the bias is interpolated linearly, before the first and after the last it is held.
    Without rests the bias is 0 (what the whole smoother gives).

    A window whose movement cannot level its rests (:func:`levels_its_rests`: one pose, and the
    sensor spends the movement far from it, as a forearm in free arm movement) gives no bias:
    its samples are joined, interpolated or held from the other windows as between windows,
    and the bias is 0 where no window gives one (the recording as it is, which the fused
    orientation at 0.1 m/s² also keeps at its rests).
    """
    n = len(gyr)
    p = registry.make_params(registry.get("smoother"), params)
    rest = fusion_rest(
        gyr, acc, rate, p.rest_gyr_threshold, p.rest_acc_threshold, p.rest_min_duration
    )
    pad = int(round((CALIBRATION_WINDOW_S if window_s is None else window_s) * rate))
    spans = _merged_windows(runs(rest), pad, n)
    wider = dict(params) | {"acc_bias_init": CALIBRATION_ACC_BIAS_INIT, "acc_lowpass_tau": 0.0}
    bias = np.zeros((n, 3))
    ends, kept = [], []
    for lo, hi in spans:
        res = registry.estimate(
            "smoother", gyr[lo:hi], acc[lo:hi], None, rate,
            time=None if time is None else time[lo:hi], filled_spans=filled, **wider,
        )  # fmt: skip
        if not levels_its_rests(res.quat, acc[lo:hi], rest[lo:hi]):
            continue
        kept.append((lo, hi))
        bias[lo:hi] = res.extra["acc_bias"]
        end_s = (hi - 1) / rate if time is None else float(time[hi - 1])  # gaps: the stamps
        ends.append((end_s, bias[hi - 1].copy(), res.extra["acc_bias_end_cov"]))
    if len(kept) > 1:
        rw = float(p.acc_bias_rw)
        for (lo, hi), joined in zip(kept, _joined_bias(ends, rw), strict=True):
            bias[lo:hi] += joined - bias[hi - 1]
    if kept and (kept[0][0] > 0 or kept[-1][1] < n or len(kept) > 1):
        known = np.concatenate([np.arange(lo, hi) for lo, hi in kept])
        for i in range(3):
            bias[:, i] = np.interp(np.arange(n), known, bias[known, i])
    return bias


def levels_its_rests(quat: np.ndarray, acc: np.ndarray, rest: np.ndarray) -> bool:
    """Whether the movement of one window of :func:`calibration_acc_bias` may tell its rests
    their inclination, and so their accelerometer bias.

    ``quat`` (N, 4) is the window's orientation (sensor → ENU), ``acc`` (N, 3) m/s² its
    accelerometer, ``rest`` (N,) its rest samples. The bias states take whatever makes the
    rests agree with the inclination the movement's accelerometer gives; that inclination
    assumes the linear acceleration averages out. A limb's own rotational acceleration does
    not: the centripetal part points along the segment to the joint it turns about, fixed in
    the sensor frame (simulated ``skin`` sessions, mean over the recording: 0.24–0.49 m/s²
    along a forearm in free arm movement, 0.4–0.9 along a walking thigh, 1.3–2.3 along a
    shank). While the segment stays near its rest pose (a walk: thighs and shanks 16–21°
    from it on average over each window) that acceleration reads mostly along gravity; a
    segment that spends the movement far from it (a forearm 81–83°, an upper arm 39–41°)
    reads it as a horizontal force of one sign in the sensor frame, which the bias states
    can take for a bias: in free arm movement the pass gained nothing (stand gravity against
    the true vertical, seeds 0–9, 50 sensors: 0.88° raw, 0.87° less the bias, worst 1.99 →
    3.04°; docs/kinematics.md, "Where the movement cannot level the stand").

    True when the rests hold two poses (gravity directions at least
    :data:`CALIBRATION_POSES_DEG` apart: the gyroscope ties them, whatever the movement
    between), or when the rests' vertical, turned by ``quat``, is on average no more than
    :data:`CALIBRATION_MAX_TILT_DEG` from the earth's vertical over the moving samples **and**
    the movement turns the sensor's heading (:func:`heading_concentration` at most
    :data:`CALIBRATION_MAX_HEADING_CONCENTRATION`). A bias is fixed in the sensor frame; the
    walker's own acceleration at the start of a walk (from standing to about 1.3 m/s within a
    stride or two) and its slowing down at the end are fixed in the earth frame, along the
    way the walker goes. Only where the heading turns do the two part; on a straight walk the
    pass takes one for the other. On real short walks (``bench/real_short_walks.py``: the
    16-IMU walk cut to a stand and 10-25 s of straight walking, headings' mean resultant
    length 0.98-1.00 for every leg sensor, 0.70 with one turn near the end) the pass put
    0.3-0.5 m/s² of "bias" on every thigh and shank, each along its own segment's forward
    axis, where the whole recording (a stand, a seated rest, 45 s of walking with turns)
    gives 0.14 m/s² at most, and knee flexion moved by 2-3° with it; simulated walks round an
    ellipse turn as they go (0.5 over a 25-s recording, 0.06 over 74 s) and keep their bias.
    A window without rests or without movement is true (nothing to judge)."""
    rest = np.asarray(rest, dtype=bool)
    ups = [acc[a:b].mean(axis=0) for a, b in runs(rest)]
    ups = [u / np.linalg.norm(u) for u in ups if np.linalg.norm(u) > 0]
    if not ups or rest.all():
        return True
    cos_poses = np.cos(np.radians(CALIBRATION_POSES_DEG))
    if any(float(a @ b) < cos_poses for i, a in enumerate(ups) for b in ups[i + 1 :]):
        return True
    up = np.mean(ups, axis=0)
    up /= np.linalg.norm(up)
    q = np.asarray(quat, dtype=float)[~rest]
    vertical = rotate(q, np.broadcast_to(up, (len(q), 3)))[:, 2]
    tilt = np.degrees(np.arccos(np.clip(vertical, -1.0, 1.0)))
    if not np.nanmean(tilt) <= CALIBRATION_MAX_TILT_DEG:
        return False
    return heading_concentration(q, up) <= CALIBRATION_MAX_HEADING_CONCENTRATION


def heading_concentration(quat: np.ndarray, up: np.ndarray) -> float:
    """How much one way a sensor heads over a movement: the mean resultant length (0-1) of the
    earth-frame heading angles of a sensor axis perpendicular to ``up`` (the rests' vertical,
    sensor frame), turned by ``quat`` (N, 4, sensor → ENU). 1 for a movement that never turns
    (a straight walk), 0 for headings spread evenly (walking round and round, or there and
    back); NaN without samples."""
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    axis = np.cross(up, np.eye(3)[int(np.argmin(np.abs(up)))])
    axis /= np.linalg.norm(axis)
    h = rotate(np.asarray(quat, dtype=float), np.broadcast_to(axis, (len(quat), 3)))
    if not len(h):
        return float("nan")
    return float(np.abs(np.mean(np.exp(1j * np.arctan2(h[:, 1], h[:, 0])))))


def _joined_bias(ends: list[tuple[float, np.ndarray, np.ndarray]], rw: float) -> list[np.ndarray]:
    """The bias (3,) of each window given all windows: ``ends`` holds each window's end time
    (s), its bias there and that bias's covariance (3 × 3, m²/s⁴; at a window's last sample the
    filter's posterior holds all of the window's data), each from the prior
    ``N(0, CALIBRATION_ACC_BIAS_INIT² I)``. Each window's information on the bias,
    ``J = C⁻¹ − P₀⁻¹`` (negative parts, numerical, dropped) and ``h = C⁻¹ a``, reaches another
    window weakened by the bias's random walk ``rw`` (m/s²/√s) over the time between them,
    ``J (I + rw² Δt J)⁻¹``; the prior is counted once. The windows' attitudes are taken as
    independent: the movement's accelerometer ties each window's inclination down by itself."""
    p0_inv = np.eye(3) / CALIBRATION_ACC_BIAS_INIT**2
    info = []
    for t, a, cov in ends:
        c_inv = np.linalg.inv(cov)
        w, v = np.linalg.eigh(0.5 * (c_inv + c_inv.T) - p0_inv)
        j = (v * np.maximum(w, 0.0)) @ v.T
        mean = np.linalg.lstsq(j, c_inv @ a, rcond=1e-12)[0] if w.max() > 0 else np.zeros(3)
        info.append((t, j, mean))
    out = []
    for t, _, _ in ends:
        big_j, big_h = p0_inv.copy(), np.zeros(3)
        for s, j, mean in info:
            jj = j @ np.linalg.inv(np.eye(3) + rw**2 * abs(t - s) * j)
            jj = 0.5 * (jj + jj.T)
            big_j += jj
            big_h += jj @ mean
        out.append(np.linalg.solve(big_j, big_h))
    return out


def _merged_windows(rests: np.ndarray, pad: int, n: int) -> list[tuple[int, int]]:
    """``[lo, hi)`` sample spans: each ``[start, stop)`` of ``rests`` widened by ``pad`` on
    both sides (within ``0 … n``), overlapping or touching spans joined."""
    widened = np.clip(np.asarray(rests, dtype=np.int64).reshape(-1, 2) + [-pad, pad], 0, n)
    return [(int(lo), int(hi)) for lo, hi in joined_spans(widened)]


def filled_spans(stream: Any, path: str | Path | None = None) -> np.ndarray | None:
    """The gaps ingest filled in ``stream`` (``qc["filled_spans_s"]``, ``[start_s, end_s]``
    on the recorded clock), on the stream's time: moved by the clock sync where it was applied
    (``attrs["clock_sync"]``); ``None`` for a stream that does not list them. A list that is
    not finite ``[start, end]`` pairs (a damaged session file) is an :class:`InputError`."""
    spans = stream.qc.get("filled_spans_s")
    if spans is None:
        return None
    try:
        spans = np.asarray(spans, dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        spans = np.full((1, 2), np.nan)
    if not np.isfinite(spans).all() or (spans[:, 1] < spans[:, 0]).any():
        raise InputError(
            "its list of filled gaps (qc filled_spans_s) is not [start_s, end_s] pairs",
            path,
            f"sensor {stream.label}",
            "ingest the recording again",
        )
    sync = stream.attrs.get("clock_sync")
    return ClockFit(**sync).corrected_time(spans) if sync is not None else spans


def _calibration_bias(res: Any, s: Any, params: dict[str, str]) -> np.ndarray | None:
    """:func:`calibration_acc_bias` for a result with accelerometer-bias states (none when
    the estimator has none or they are switched off)."""
    if res.extra.get("acc_bias") is None or not float(res.params.get("acc_bias_init", 0.0)):
        return None
    kept = {k: v for k, v in params.items() if k != "acc_bias_init"}
    return calibration_acc_bias(s.gyr, s.acc, s.rate_hz, s.time, filled_spans(s), **kept)


def bridged_spans(
    label: str, time: np.ndarray, channels: dict[str, np.ndarray | None], path: Any
) -> list[list[float]]:
    """``[first, last]`` time (s) of every run of samples non-finite in any of ``channels``,
    each no longer than :data:`NAN_BRIDGE_MAX_S` from the finite sample before to the one
    after; a longer run raises :class:`InputError` naming the sensor, channels and span (ingest
    drops such runs of the accelerometer and gyroscope: this is a session not prepared, or a
    magnetometer's run, which the 6-D fusion leaves out)."""
    t = np.asarray(time, dtype=float)
    used = {k: np.asarray(a) for k, a in channels.items() if a is not None}
    bad = np.zeros(len(t), dtype=bool)
    for a in used.values():
        bad |= ~np.isfinite(a.reshape(len(a), -1)).all(axis=1)
    if not bad.any():
        return []
    long = long_nan_runs(t, list(used.values()), NAN_BRIDGE_MAX_S)
    if long:
        a, b = long[0]
        names = [k for k, arr in used.items() if not np.isfinite(arr[a:b]).all()]
        more = f"; {len(long) - 1} more run(s)" if len(long) > 1 else ""
        remedy = (
            "fuse without the magnetometer (the default), or trim the recording to the part "
            "with data"
            if names == ["mag"]
            else "export the recording again, or trim it to the part with data (see "
            "'motionlab info', QC)"
        )
        raise InputError(
            f"{'/'.join(names)} not a number from {t[a]:.2f} s to {t[b - 1]:.2f} s "
            f"({b - a} samples, {100 * bad.mean():.1f} % of the recording{more}): fusion "
            f"bridges at most {NAN_BRIDGE_MAX_S:g} s",
            path,
            f"sensor {label}",
            remedy,
        )
    return [[float(t[a]), float(t[b - 1])] for a, b in runs(bad)]


def _check_finite(label: str, name: str, time: np.ndarray, quat: np.ndarray, path: Any) -> None:
    """Refuse an orientation that is not finite at every sample, with where it starts."""
    finite = np.isfinite(quat).all(axis=1)
    if finite.all():
        return
    first = int(np.argmin(finite))
    share = 100 * (1 - finite.mean())
    span = "for this sensor" if not finite.any() else (
        f"for {share:.1f} % of the samples, from {float(time[first]):.2f} s on"
    )  # fmt: skip
    raise InputError(
        f"fusion ({name}) gives no finite orientation {span}",
        path,
        f"sensor {label}",
        "its data hold non-finite or implausible values: see 'motionlab info' (QC)",
    )
