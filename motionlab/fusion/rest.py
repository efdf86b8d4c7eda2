"""Rest windows tolerant of a gyroscope bias, for the sensor calibration and the estimators.

:func:`motionlab.fusion.detect.rest_mask` tests the moving RMS of the angular rate against a
threshold (2 °/s by default). An uncalibrated gyroscope can carry a bias of the same size, so
here the detector runs on the bias-compensated rate and the bias is re-estimated from the rest
samples it finds: a fixed-point iteration started from the most common mean rate of the quiet
0.5 s blocks (:func:`_quiet_mode`), from the median of the whole recording and from zero; the
start finding most rest wins. A
steady turn is indistinguishable from a bias by the gyroscope and accelerometer alone, so a
bias above ``max_bias`` (5 °/s, more than MEMS gyroscopes show after factory trim) is not
accepted. Inputs: gyr (N, 3) rad/s, acc (N, 3) m/s² or None, rate Hz.

The estimators take their rests from :func:`fusion_rest`: the plain detector while the bias is
small, the bias-tolerant one when it is not. With the ``harsh`` simulated preset (gyroscope
biases of 2 °/s per axis, 3-6 °/s in norm) the plain detector found no rest on most sensors, and
a pelvis that barely moves in a lumbar session kept a bias 1 °/s off for 200 s.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from motionlab.fusion.detect import acc_quiet, rest_mask

#: the largest gyroscope bias (rad/s) the estimators' rest detector takes off: an uncalibrated
#: MEMS gyroscope (10 °/s; the sensor calibration's own bound, 5 °/s, is for a trimmed one)
FUSION_MAX_BIAS = np.deg2rad(10.0)


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
    acc_still: np.ndarray | None = None,
) -> np.ndarray:
    """Samples (N,) bool at rest, judged on the bias-compensated angular rate.

    Parameters are those of :func:`~motionlab.fusion.detect.rest_mask` (thresholds in rad/s and
    m/s² on 0.5 s moving RMS, ``min_duration`` in s). Without ``acc`` only the gyroscope is
    tested. ``max_bias`` (rad/s) bounds the norm of the bias the rest samples may imply.
    ``acc_still``: the accelerometer's half of the test when the caller has it
    (:func:`~motionlab.fusion.detect.acc_quiet`); it does not change with the bias, so it is
    computed once for every bias tried.
    """
    if acc_still is None:
        acc_still = (np.ones(len(gyr), dtype=bool) if acc is None
                     else acc_quiet(acc, rate, acc_threshold, 0.5))  # fmt: skip

    def detect(bias: np.ndarray) -> np.ndarray:
        return rest_mask(gyr - bias, acc, rate, gyr_threshold, acc_threshold, 0.5, min_duration,
                         acc_still)  # fmt: skip

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


def fusion_rest(
    gyr: np.ndarray,
    acc: np.ndarray,
    rate: float,
    gyr_threshold: float = np.deg2rad(2.0),
    acc_threshold: float = 0.5,
    min_duration: float = 1.5,
) -> np.ndarray:
    """Samples (N,) bool at rest, for an estimator's zero-rate and bias updates.

    :func:`find_rest` (biases up to :data:`FUSION_MAX_BIAS`) when the bias its rests imply is
    over half ``gyr_threshold``; below that the plain :func:`~motionlab.fusion.detect.rest_mask`
    (a still sensor's rate then stays under the threshold, and what it finds is unchanged).
    Thresholds as :func:`~motionlab.fusion.detect.rest_mask` (rad/s, m/s², s).
    """
    gyr = np.asarray(gyr, dtype=float)
    acc = np.asarray(acc, dtype=float)
    still = acc_quiet(acc, rate, acc_threshold, 0.5)
    tolerant = find_rest(gyr, acc, rate, gyr_threshold, acc_threshold, min_duration,
                         max_bias=FUSION_MAX_BIAS, acc_still=still)  # fmt: skip
    if tolerant.any() and np.linalg.norm(gyr[tolerant].mean(axis=0)) > gyr_threshold / 2:
        return tolerant
    return rest_mask(gyr, acc, rate, gyr_threshold, acc_threshold, 0.5, min_duration, still)
