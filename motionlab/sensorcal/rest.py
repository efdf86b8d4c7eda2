"""Rest windows for calibration, tolerant of a gyroscope bias.

:func:`motionlab.fusion.detect.rest_mask` tests the moving RMS of the angular rate against a
threshold (2 °/s by default). An uncalibrated gyroscope can carry a bias of the same size, so
here the detector runs on the bias-compensated rate and the bias is re-estimated from the rest
samples it finds: a fixed-point iteration started from the most common mean rate of the quiet
0.5 s blocks (:func:`_quiet_mode`), from the median of the whole recording and from zero; the
start finding most rest wins. A
steady turn is indistinguishable from a bias by the gyroscope and accelerometer alone, so a
bias above ``max_bias`` (5 °/s, more than MEMS gyroscopes show after factory trim) is not
accepted. Inputs: gyr (N, 3) rad/s, acc (N, 3) m/s² or None, rate Hz.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from motionlab.fusion.detect import rest_mask


def _quiet_mode(gyr: np.ndarray, rate: float, threshold: float) -> np.ndarray | None:
    """The bias suggested by the quiet blocks: the densest cluster of their mean rates.

    The recording is cut into 0.5 s blocks; a block is quiet when the RMS deviation of the rate
    from its block mean is below ``threshold``. At rest every block mean is the bias, so they
    gather in one cluster (radius ``threshold / 2``), while the block means of a smooth movement
    spread out. Returns the median of that cluster, or None without quiet blocks.
    """
    w = max(2, int(round(0.5 * rate)))
    n = len(gyr) // w
    if n == 0:
        return None
    blocks = gyr[: n * w].reshape(n, w, 3)
    means = blocks.mean(axis=1)
    spread = np.sqrt(np.mean(np.sum((blocks - means[:, None]) ** 2, axis=2), axis=1))
    quiet = means[spread < threshold]
    if not len(quiet):
        return None
    counts = cKDTree(quiet).query_ball_point(quiet, threshold / 2, return_length=True)
    centre = quiet[int(np.argmax(counts))]
    return np.median(quiet[np.linalg.norm(quiet - centre, axis=1) < threshold / 2], axis=0)


def find_rest(
    gyr: np.ndarray,
    acc: np.ndarray | None,
    rate: float,
    gyr_threshold: float = np.deg2rad(2.0),
    acc_threshold: float = 0.5,
    min_duration: float = 1.5,
    max_bias: float = np.deg2rad(5.0),
    iterations: int = 5,
) -> np.ndarray:
    """Samples (N,) bool at rest, judged on the bias-compensated angular rate.

    Parameters are those of :func:`~motionlab.fusion.detect.rest_mask` (thresholds in rad/s and
    m/s² on 0.5 s moving RMS, ``min_duration`` in s). Without ``acc`` only the gyroscope is
    tested. ``max_bias`` (rad/s) bounds the norm of the bias the rest samples may imply.
    """
    acc_in = np.zeros_like(gyr) if acc is None else acc

    def detect(bias: np.ndarray) -> np.ndarray:
        return rest_mask(gyr - bias, acc_in, rate, gyr_threshold, acc_threshold, 0.5, min_duration)

    starts = [np.median(gyr, axis=0), np.zeros(3)]
    mode = _quiet_mode(gyr, rate, gyr_threshold)
    if mode is not None:
        starts.insert(0, mode)
    best = np.zeros(len(gyr), dtype=bool)
    for start in starts:
        mask = detect(start)
        for _ in range(iterations):
            if not mask.any():
                break
            new = detect(gyr[mask].mean(axis=0))
            if np.array_equal(new, mask):
                break
            mask = new
        if mask.sum() > best.sum() and np.linalg.norm(gyr[mask].mean(axis=0)) <= max_bias:
            best = mask
    return best
