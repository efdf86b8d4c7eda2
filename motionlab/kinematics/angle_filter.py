"""The joint angles' low-pass: human movement below the cut-off, a sensor's wobble above it.

The angle table (:func:`motionlab.stages.angles`) is low-passed at ``ANGLES_LOWPASS_HZ`` unless
the user (``--angle-lowpass``) or the protocol (``angle_lowpass_hz:``) asks otherwise (0 keeps
the angles as computed: a rig has no skin), and the metrics and gait curves take their angles at
the table's cut-off, or at ``ANGLES_LOWPASS_HZ`` where the table is as computed
(:func:`metrics_cutoff`, :func:`as_metrics_take`).

Why 6 Hz: walking kinematics lie below it (Winter 2009, Biomechanics and Motor Control of Human
Movement, 4th ed., §3.4.4; the optical gait labs' marker filters are of the same order), while a
sensor rocks on the skin after every heel strike at 10-20 Hz: an 8-10° dip for about 40 ms in a
real walk's knee flexion (``bench/real_people.py``), which is not the joint moving. On simulated
walks whose legs ring as a real walk's (preset ``skin``, ``bench/real_world.py --protocols walk
--seeds 0-9``) the low-pass took knee flexion from 1.94 / 2.27° to 1.45 / 1.87° mean RMSE (right
/ left) and hip flexion from 2.01 / 1.81° to 1.64 / 1.57° (docs/kinematics.md, "The angles
low-passed").
"""

from __future__ import annotations

import numpy as np

from motionlab.dsp import butter, padlen, sosfiltfilt
from motionlab.results import AngleTable
from motionlab.session import estimate_rate
from motionlab.timebase import runs

#: the angles' default low-pass (Hz; see the module docstring)
ANGLES_LOWPASS_HZ = 6.0
#: a step of the time stamps over more than this many sampling intervals ends a filtered run
GAP_STEPS = 1.5


def smoothed(
    values: np.ndarray,
    rate: float,
    cutoff: float = ANGLES_LOWPASS_HZ,
    time: np.ndarray | None = None,
) -> np.ndarray:
    """``values`` (deg) low-passed at ``cutoff`` Hz (at most 0.4 × ``rate``; zero-phase
    2nd-order Butterworth, forward and backward) over each run of finite samples, a run also
    ending where ``time`` (s, when given) steps over a gap of more than ``GAP_STEPS`` samples (a
    recording whose lost rows were left out, not filled with NaN); a run too short to filter is
    kept as it is, and NaN stays NaN; so is everything without a rate (a single instant) or with
    ``cutoff`` 0."""
    v = np.asarray(values, dtype=float)
    out = v.copy()
    if not (np.isfinite(rate) and rate > 0 and cutoff > 0):
        return out
    sos = butter(2, min(cutoff, 0.4 * rate), fs=rate)
    edge = padlen(sos)
    keep = np.isfinite(v)
    starts = np.zeros(len(v), bool)
    if time is not None and len(v) > 1:
        starts[1:] = np.diff(np.asarray(time, dtype=float)) > GAP_STEPS / rate
    for a, b in runs(keep):
        cuts = [a, *(a + 1 + np.flatnonzero(starts[a + 1 : b])), b]
        for c, d in zip(cuts[:-1], cuts[1:], strict=True):
            if d - c > edge:
                out[c:d] = sosfiltfilt(sos, v[c:d])
    return out


def smoothed_table(
    table: dict[str, np.ndarray], cutoff: float = ANGLES_LOWPASS_HZ
) -> dict[str, np.ndarray]:
    """An angle table (``time_s`` and degree columns) with every column :func:`smoothed`."""
    time = np.asarray(table["time_s"], dtype=float)
    rate = estimate_rate(time)
    return {k: v if k == "time_s" else smoothed(v, rate, cutoff, time) for k, v in table.items()}


def metrics_cutoff(lowpass_hz: float) -> float:
    """The cut-off (Hz) the metrics and gait curves take their angles at, for an angle table
    low-passed at ``lowpass_hz``: the table's own, or :data:`ANGLES_LOWPASS_HZ` where the table
    is as computed (0)."""
    return float(lowpass_hz) if lowpass_hz > 0 else ANGLES_LOWPASS_HZ


def as_metrics_take(angles: AngleTable, column: str) -> np.ndarray:
    """``column`` of a stored angle table (deg) as the metrics and gait curves take it: as it is
    where the table is low-passed, else low-passed at :data:`ANGLES_LOWPASS_HZ`."""
    x = np.asarray(angles.data[column], dtype=float)
    if angles.lowpass_hz > 0:
        return x
    time = np.asarray(angles.time, dtype=float)
    return smoothed(x, estimate_rate(time), ANGLES_LOWPASS_HZ, time)
