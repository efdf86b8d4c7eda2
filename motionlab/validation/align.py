"""Spatial alignment of the IMU and optical systems: two constant rotations, estimated together.

For each sensor ``i`` with IMU orientation ``A_i(t)`` (sensor → earth) and optical orientation
``B_i(t)`` (cluster or rigid body → lab), synchronised on one clock::

    A_i(t) = Y_i ⊗ B_i(t) ⊗ X_i

with ``Y_i`` the lab → earth rotation and ``X_i`` the sensor → cluster rotation (the sensor's axes
in cluster coordinates). This is the hand-eye / robot-world problem AX = YB (Ricci 2015, eq. 4.7;
Zhuang, Roth & Sudhakar 1994, IEEE TRA 10:549). Modes:

- ``full``: one ``Y`` shared by all sensors (a 9-D estimate: every sensor has the same earth frame);
- ``heading``: only the vertical is shared, ``Y_i = Rz(ψ_i) ⊗ Y`` with a heading ``ψ_i`` per
  sensor (``ψ_0 = 0``), for 6-D estimates whose heading is arbitrary per sensor;
- ``none``: ``Y = X = I`` (the reference is already aligned to the sensor, as in BROAD).

Closed-form initial guess: relative rotations over a short lag obey
``log(A_i(t)* A_i(t+τ)) = R(X_i)ᵀ log(B_i(t)* B_i(t+τ))``, so ``X_i`` is the weighted Wahba/
Procrustes fit of those rotation vectors (Park & Martin 1994, IEEE TRA 10:717); ``Y_i`` is then
the quaternion mean (Markley 2007) of ``A_i X_i* B_i*``. Refinement: nonlinear least squares
(scipy.optimize.least_squares, soft-L1 loss) over the rotation vectors of
``A_i* ⊗ Y_i ⊗ B_i ⊗ X_i`` on at most ``max_samples`` samples per sensor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.results import AlignmentRotation, SpatialAlignment
from motionlab.segments.frames import wahba

MODES = ("full", "heading", "none")
_Z = np.array([0.0, 0.0, 1.0])
LAG_S = 0.2
MAX_SAMPLES = 1000
LOSS_SCALE_DEG = 2.0
#: below this conditioning a sensor turned about one axis only, and its sensor-to-cluster
#: rotation about that axis is not determined (a wheelchair's sensor, turning about the
#: vertical: 0.001-0.002; real trunk sensors 0.05-0.41, a real rig's segments 0.24-0.64)
MIN_CONDITIONING = 0.01


@dataclass
class Alignment:
    """The estimated rotations: ``lab_to_earth`` (Y), per-sensor heading (rad, heading mode)
    and ``sensor_to_cluster`` (X_i), with the RMS residual angle per sensor (deg)."""

    mode: str
    lab_to_earth: np.ndarray
    sensor_to_cluster: dict[str, np.ndarray]
    heading: dict[str, float] = field(default_factory=dict)
    residual_rms_deg: dict[str, float] = field(default_factory=dict)
    conditioning: dict[str, float] = field(default_factory=dict)

    def earth_from_lab(self, label: str) -> np.ndarray:
        """``Y_i``: the lab → earth rotation seen by sensor ``label``."""
        psi = self.heading.get(label, 0.0)
        return rot.mul(rot.from_axis_angle(_Z, psi), self.lab_to_earth)

    def reference(self, label: str, q_optical: np.ndarray) -> np.ndarray:
        """The optical orientation of ``label`` as a sensor → earth orientation, ``Y B X``."""
        y = self.earth_from_lab(label)
        return rot.mul(rot.mul(y, q_optical), self.sensor_to_cluster[label])

    def record(self) -> SpatialAlignment:
        """The record stored in ``results.validation.alignment`` (degrees, each quaternion with
        its scalar part ≥ 0)."""

        def entry(q: np.ndarray) -> AlignmentRotation:
            q = rot.normalize(q) * (1.0 if q[0] >= 0 else -1.0)
            return AlignmentRotation(q, float(np.degrees(rot.angle(q))))

        return SpatialAlignment(
            mode=self.mode,
            lab_to_earth=entry(self.lab_to_earth),
            sensor_to_cluster={k: entry(v) for k, v in self.sensor_to_cluster.items()},
            heading_deg={k: float(np.degrees(v)) for k, v in self.heading.items()},
            residual_rms_deg=dict(self.residual_rms_deg),
            conditioning=dict(self.conditioning),
        )


def initial_x(a: np.ndarray, b: np.ndarray, lag: int) -> tuple[np.ndarray | None, float]:
    """Closed-form ``X`` from relative rotations over ``lag`` samples, and its conditioning.

    Conditioning is the smallest over the largest singular value of the rotation-vector
    scatter (0: rotation about one axis only, X is then not determined about it); a sensor that
    hardly turned (a still pelvis under a moving trunk) has no ``X`` to find: ``None`` and
    conditioning 0, so that its agreements are withheld, not the whole validation refused.
    """
    da = rot.to_rotvec(rot.mul(rot.conj(a[:-lag]), a[lag:]))
    db = rot.to_rotvec(rot.mul(rot.conj(b[:-lag]), b[lag:]))
    ok = np.isfinite(da).all(axis=1) & np.isfinite(db).all(axis=1)
    ok &= np.linalg.norm(da, axis=1) > np.radians(2.0)
    if ok.sum() < 3:
        return None, 0.0
    m = wahba(db[ok], da[ok])
    sv = np.linalg.svd(da[ok], compute_uv=False)
    return rot.from_matrix(m), float(sv[-1] / sv[0])


def align(
    pairs: dict[str, tuple[np.ndarray, np.ndarray]],
    mode: str = "full",
    rate: float = 100.0,
    max_samples: int = MAX_SAMPLES,
) -> Alignment:
    """Estimate ``Y`` (and headings) and every ``X_i`` from synchronised orientations.

    ``pairs`` maps a sensor label to ``(A (N, 4), B (N, 4))`` on one time grid at ``rate`` Hz
    (NaN where either is missing). See the module docstring for the modes.
    """
    if mode not in MODES:
        raise InputError(
            f"unknown alignment mode {mode!r}",
            where="argument mode",
            remedy="full, heading or none",
            argument="mode",
        )
    labels = list(pairs)
    if mode == "none":
        out = Alignment(mode, rot.IDENTITY.copy(), {k: rot.IDENTITY.copy() for k in labels})
        out.residual_rms_deg = _residuals(out, pairs)
        return out
    lag = max(1, int(round(LAG_S * rate)))
    x0, y0, cond = {}, {}, {}
    turned = []  # a sensor that hardly turned gives no Y
    for label, (a, b) in pairs.items():
        x, cond[label] = initial_x(a, b, lag)
        turned += [label] if x is not None else []
        x0[label] = x if x is not None else rot.IDENTITY.copy()
        ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        y0[label] = rot.mean(rot.mul(rot.mul(a[ok], rot.conj(x0[label])), rot.conj(b[ok])))
    if not turned:
        raise InputError(
            "too little rotation to align the IMU with the optical data",
            where="spatial alignment",
            remedy="record movements about several axes, or use mode='none'",
            argument="mode",
        )
    labels = turned + [k for k in labels if k not in turned]  # the first one sets the headings
    first = labels[0]
    if mode == "full":
        y_init = rot.mean(np.array([y0[k] for k in turned]))
        psi0 = {}
    else:
        y_init = y0[first]
        up = np.array([0.0, 0.0, 1.0])  # each one's heading against the first: its twist
        turns = {k: rot.mul(y0[k], rot.conj(y_init))[None] for k in labels[1:]}
        psi0 = {k: float(rot.twist_angle(q, up)[0]) for k, q in turns.items()}
    samples = {}
    for label, (a, b) in pairs.items():
        ok = np.flatnonzero(np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1))
        pick = ok[np.linspace(0, len(ok) - 1, min(len(ok), max_samples)).astype(int)]
        samples[label] = (a[pick], b[pick])
    heads = list(psi0)

    def unpack(theta: np.ndarray):
        y = rot.mul(rot.from_rotvec(theta[:3]), y_init)
        psi = {k: psi0[k] + theta[3 + i] for i, k in enumerate(heads)}
        base = 3 + len(heads)
        xs = {
            k: rot.mul(x0[k], rot.from_rotvec(theta[base + 3 * i : base + 3 * i + 3]))
            for i, k in enumerate(labels)
        }
        return y, psi, xs

    def residuals(theta: np.ndarray) -> np.ndarray:
        y, psi, xs = unpack(theta)
        out = []
        for k in labels:
            a, b = samples[k]
            yk = rot.mul(rot.from_axis_angle(_Z, psi.get(k, 0.0)), y)
            e = rot.mul(rot.conj(a), rot.mul(rot.mul(yk, b), xs[k]))
            out.append(rot.to_rotvec(e).ravel())
        return np.concatenate(out)

    theta0 = np.zeros(3 + len(heads) + 3 * len(labels))
    sol = least_squares(
        residuals,
        theta0,
        jac_sparsity=_sparsity(labels, heads, {k: len(v[0]) for k, v in samples.items()}),
        tr_solver="lsmr",
        loss="soft_l1",
        f_scale=np.radians(LOSS_SCALE_DEG),
    )
    y, psi, xs = unpack(sol.x)
    out = Alignment(mode, y, xs, {first: 0.0, **psi} if mode == "heading" else {}, {}, cond)
    out.residual_rms_deg = _residuals(out, pairs)
    return out


def _sparsity(labels: list[str], heads: list[str], n: dict[str, int]) -> csr_matrix:
    """Which parameters move which residuals: Y all, a heading and an X only their sensor's."""
    rows, cols, start = [], [], 0
    for i, k in enumerate(labels):
        own = [0, 1, 2, *([3 + heads.index(k)] if k in heads else [])]
        own += range(3 + len(heads) + 3 * i, 6 + len(heads) + 3 * i)
        rows.append(np.repeat(np.arange(start, start + 3 * n[k]), len(own)))
        cols.append(np.tile(own, 3 * n[k]))
        start += 3 * n[k]
    shape = (start, 3 + len(heads) + 3 * len(labels))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    return csr_matrix((np.ones(len(rows), dtype=int), (rows, cols)), shape=shape)


def _residuals(al: Alignment, pairs: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict:
    out = {}
    for label, (a, b) in pairs.items():
        err = np.degrees(rot.angle_between(a, al.reference(label, b)))
        out[label] = float(np.sqrt(np.nanmean(err**2))) if np.isfinite(err).any() else float("nan")
    return out
