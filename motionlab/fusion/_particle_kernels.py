"""Numba kernels of the quaternion particle filter (:mod:`motionlab.fusion.particle`).

Private. Particles are offsets ``Lᵢ`` with ``qᵢ = Lᵢ ⊗ G`` (G: the shared gyroscope integral);
every work array is allocated once, before the time loop of :func:`nb_filter`. One sample of the
loop is, in order:

1. propagate ``G`` with the bias-compensated rate;
2. collect the measurements' **information** about the earth-frame correction ``δ`` of the prior
   mean, ``q_true = exp(δ/2) ⊗ mean ⊗ G``: a 3×3 matrix ``J`` and a vector ``j`` (slots of
   ``info``), so that a particle's log-likelihood is ``jᵀδᵢ − ½ δᵢᵀJδᵢ``. A direction measured in
   the sensor frame whose earth-frame direction is known (gravity; any further reference vector
   is added the same way) enters through :func:`_info_vector`, the magnetometer's heading through
   :func:`_info_heading`;
3. move every particle by process noise and score it (:func:`_move_and_score`);
4. weights, effective sample size and the posterior mean (:func:`_weigh`);
5. gyroscope bias; divergence monitor (:func:`_monitor`) and reset, or resampling with
   regularisation; output.

Marker reference vectors (:mod:`motionlab.fusion.markers`; Liu 2010 §5.4) enter step 2 through
:func:`_info_vector` like gravity, with the roles of the two directions swapped: the body-fixed
vector seen through the prior mean is the direction to correct, the marker measurement the
target. When they reappear after being hidden for ``T`` s, every particle is first turned by a
vMF draw of spread ``MARKER_DRIFT · T`` (the error the IMU alone may have gathered), and when
they jump beyond their noise (:func:`~motionlab.fusion.markers.marker_jump`) the cloud is spread
about the prior mean, so that the markers can pick the cloud up.
"""

from __future__ import annotations

import numba
import numpy as np

from motionlab.fusion import _common as cm
from motionlab.fusion import resampling as rs
from motionlab.fusion import sphere as sph
from motionlab.fusion.markers import USED_ACC, USED_MAG, USED_MARKERS, marker_jump
from motionlab.fusion.registry import KernelParams

#: the float parameter vector ``prm``, packed from :class:`~.particle.ParticleParams` and the
#: reference gravity and field, the kernel bandwidth and the Bingham-band limit
PRM = KernelParams(
    "process_noise", "acc_sigma", "acc_rest_sigma", "acc_norm_gain", "acc_gate", "gravity",
    "mag_sigma", "mag_rest_sigma", "mag_norm_tolerance", "mag_dip_tolerance", "mag_gate_dip",
    "ref_norm", "ref_dip", "bias_tau", "bias_rest_tau", "bias_max", "init_sigma", "reset_angle",
    "reset_time", "reset_heading_time", "reset_tau", "reset_agree", "ess_threshold", "aux_alpha",
    "kernel_h", "bingham_zmax", "marker_drift",
)  # fmt: skip
PROCESS_NOISE, ACC_SIGMA, ACC_REST_SIGMA, ACC_NORM_GAIN, ACC_GATE, GRAVITY = range(6)
MAG_SIGMA, MAG_REST_SIGMA, MAG_NORM_TOLERANCE, MAG_DIP_TOLERANCE, MAG_GATE_DIP = range(6, 11)
REF_NORM, REF_DIP, BIAS_TAU, BIAS_REST_TAU, BIAS_MAX = range(11, 16)
INIT_SIGMA, RESET_ANGLE, RESET_TIME, RESET_HEADING_TIME, RESET_TAU, RESET_AGREE = range(16, 22)
ESS_THRESHOLD, AUX_ALPHA, KERNEL_H, BINGHAM_ZMAX, MARKER_DRIFT = range(22, 27)
# slots of ``info``: the upper triangle of J, then j
_JXX, _JXY, _JXZ, _JYY, _JYZ, _JZZ, _JX, _JY, _JZ = range(9)
# slots of the monitor's work array (earth-frame vectors under the posterior mean): low-passed acc
# and horizontal field direction; the tilt run's sums of acc and of the field (samples with a
# normal field norm), its field count and duration; the heading run's sum of horizontal field
# directions, count and duration
_LA, _LM, _SA, _SM, _NM, _TA, _SH, _NH, _TH = 0, 3, 5, 8, 11, 12, 13, 15, 16
N_MONITOR = 17


# ---------------------------------------------------------------- small in-place helpers


@numba.njit(cache=True, inline="always")
def _rotate(w: float, x: float, y: float, z: float, vx: float, vy: float, vz: float):
    """``R(q) v`` for the unit ``q = (w, x, y, z)``, as three scalars."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


@numba.njit(cache=True, inline="always")
def _rot(q: np.ndarray, vx: float, vy: float, vz: float, out: np.ndarray) -> None:
    """``out = R(q) v`` (sensor → earth for an orientation q)."""
    out[0], out[1], out[2] = _rotate(q[0], q[1], q[2], q[3], vx, vy, vz)


@numba.njit(cache=True, inline="always")
def _rot_inv(q: np.ndarray, vx: float, vy: float, vz: float, out: np.ndarray) -> None:
    """``out = R(q)ᵀ v`` (earth → sensor)."""
    out[0], out[1], out[2] = _rotate(q[0], -q[1], -q[2], -q[3], vx, vy, vz)


# ---------------------------------------------------------------- measurement information


@numba.njit(cache=True, inline="always")
def _info_vector(info, ux, uy, uz, rx, ry, rz, weight):
    """Add a direction measurement: ``u`` measured, in the earth frame under the prior mean, of a
    vector whose earth-frame direction is the unit ``r``, with information ``weight`` (1/rad²).

    ``exp(δ/2)`` turns ``u`` into ``r``: ``δ × u = r − u`` to first order, so
    ``j = weight·(u × r)`` and ``J = weight·(I − rrᵀ)`` (no information about a rotation about
    ``r``; ``r`` rather than the noisy ``u`` sets the direction). ``u`` is not normalised: for
    the accelerometer (``u = acc/g``) zero-mean linear accelerations then average out instead of
    pulling with their own magnitude.
    """
    info[_JXX] += weight * (1.0 - rx * rx)
    info[_JXY] -= weight * rx * ry
    info[_JXZ] -= weight * rx * rz
    info[_JYY] += weight * (1.0 - ry * ry)
    info[_JYZ] -= weight * ry * rz
    info[_JZZ] += weight * (1.0 - rz * rz)
    info[_JX] += weight * (uy * rz - uz * ry)
    info[_JY] += weight * (uz * rx - ux * rz)
    info[_JZ] += weight * (ux * ry - uy * rx)


@numba.njit(cache=True, inline="always")
def _info_heading(info, psi, weight):
    """Add a heading measurement: the rotation ``psi`` (rad) about earth-up that the prior mean
    needs (the magnetometer's field angle east of north), with information ``weight`` (1/rad²)."""
    info[_JZZ] += weight
    info[_JZ] += weight * psi


@numba.njit(cache=True)
def _mag_heading(mx, my, mz, prm, at_rest, flagged):
    """Heading correction ``ψ`` of the earth-frame field ``m`` under the prior mean, its weight
    (1/rad²) and whether the sample is gated.

    Gated when flagged by :func:`motionlab.fusion.detect.mag_disturbance` or when the dip is
    further than ``MAG_GATE_DIP`` from the reference; otherwise the weight ``1/σ²`` is divided by
    ``1 + (Δnorm/MAG_NORM_TOLERANCE)² + (Δdip/MAG_DIP_TOLERANCE)²``.
    """
    mn = np.sqrt(mx * mx + my * my + mz * mz)
    if mn < 1e-9 or mx * mx + my * my < 1e-18:
        return 0.0, 0.0, True
    psi = np.arctan2(mx, my)
    dd = np.arcsin(min(1.0, max(-1.0, -mz / mn))) - prm[REF_DIP]
    if flagged or abs(dd) > prm[MAG_GATE_DIP]:
        return psi, 0.0, True
    sigma = prm[MAG_REST_SIGMA] if at_rest else prm[MAG_SIGMA]
    dn = (mn - prm[REF_NORM]) / prm[MAG_NORM_TOLERANCE]
    weight = 1.0 / (sigma * sigma * (1.0 + dn * dn + (dd / prm[MAG_DIP_TOLERANCE]) ** 2))
    return psi, weight, False


# ---------------------------------------------------------------- particles


@numba.njit(cache=True)
def _move_and_score(state, parts, mean, info, half, lik):
    """Process noise ``Lᵢ ← Lᵢ ⊗ exp(n/2)`` (``half > 0``: components uniform in ±half, matched
    variance), then the log-likelihood ``jᵀδᵢ − ½ δᵢᵀJδᵢ`` of each particle's earth-frame offset
    ``δᵢ = 2 vec(Lᵢ ⊗ mean*)`` (hemisphere-aligned) into ``lik``; returns its maximum."""
    m0, m1, m2, m3 = mean[0], mean[1], mean[2], mean[3]
    jxx, jxy, jxz, jyy = info[_JXX], info[_JXY], info[_JXZ], info[_JYY]
    jyz, jzz, jx, jy, jz = info[_JYZ], info[_JZZ], info[_JX], info[_JY], info[_JZ]
    lmax = -np.inf
    for p in range(parts.shape[0]):
        a = parts[p]
        if half > 0.0:
            n1 = (2.0 * sph._nb_uniform(state) - 1.0) * half
            n2 = (2.0 * sph._nb_uniform(state) - 1.0) * half
            n3 = (2.0 * sph._nb_uniform(state) - 1.0) * half
            cm.rmul(a, 1.0, 0.5 * n1, 0.5 * n2, 0.5 * n3)
        sg = 2.0 if a[0] * m0 + a[1] * m1 + a[2] * m2 + a[3] * m3 >= 0.0 else -2.0
        dx = sg * (a[1] * m0 - a[0] * m1 - a[2] * m3 + a[3] * m2)
        dy = sg * (a[2] * m0 - a[0] * m2 + a[1] * m3 - a[3] * m1)
        dz = sg * (a[3] * m0 - a[0] * m3 - a[1] * m2 + a[2] * m1)
        quad = jxx * dx * dx + jyy * dy * dy + jzz * dz * dz
        quad += 2.0 * (jxy * dx * dy + jxz * dx * dz + jyz * dy * dz)
        lp = jx * dx + jy * dy + jz * dz - 0.5 * quad
        lik[p] = lp
        if lp > lmax:
            lmax = lp
    return lmax


@numba.njit(cache=True)
def _weigh(w, lik, lmax, inv_sum, parts, mean):
    """Bayesian weights ``wᵢ ← wᵢ·exp(likᵢ)`` (kept unnormalised between samples: the previous
    sum is divided out here), ESS ``(Σw)²/Σw²`` (To eq. 156) and the Markley mean warm-started
    from the previous one, written to ``mean``. Returns ``(1/Σw, ESS)``."""
    sw = 0.0
    s2 = 0.0
    for p in range(parts.shape[0]):
        wp = w[p] * inv_sum * np.exp(lik[p] - lmax)
        w[p] = wp
        sw += wp
        s2 += wp * wp
    sph._nb_mean(parts, w, mean, mean)
    return 1.0 / sw, sw * sw / s2


# ---------------------------------------------------------------- divergence monitor


@numba.njit(cache=True)
def _monitor_clear(mon: np.ndarray) -> None:
    """Forget the monitor's history: low-passed vectors on earth-up and north, no bad run."""
    mon[:] = 0.0
    mon[_LA + 2] = 1.0
    mon[_LM + 1] = 1.0


@numba.njit(cache=True)
def _monitor_follow(mon, mean, prev):
    """Turn the monitor's earth-frame vectors by the estimate's correction ``mean ⊗ prev*``
    (the horizontal field directions by its rotation about up), so that a run's sums stay the
    vectors seen under the current estimate."""
    c0 = mean[0] * prev[0] + mean[1] * prev[1] + mean[2] * prev[2] + mean[3] * prev[3]
    c1 = -mean[0] * prev[1] + mean[1] * prev[0] - mean[2] * prev[3] + mean[3] * prev[2]
    c2 = -mean[0] * prev[2] + mean[1] * prev[3] + mean[2] * prev[0] - mean[3] * prev[1]
    c3 = -mean[0] * prev[3] - mean[1] * prev[2] + mean[2] * prev[1] + mean[3] * prev[0]
    for i in (_LA, _SA, _SM):
        mon[i], mon[i + 1], mon[i + 2] = _rotate(c0, c1, c2, c3, mon[i], mon[i + 1], mon[i + 2])
    turn = 2.0 * np.arctan2(c3, c0)
    cs, sn = np.cos(turn), np.sin(turn)
    for i in (_LM, _SH):
        mon[i], mon[i + 1] = cs * mon[i] - sn * mon[i + 1], sn * mon[i] + cs * mon[i + 1]


@numba.njit(cache=True)
def _monitor(mon, ae, me, field_ok, heading_ok, prm, dt):
    """Feed one sample to the divergence monitor; return the reset it calls for.

    ``ae`` is acc/g and ``me`` the field, in the earth frame under the posterior mean. A
    consistent filter sees ``ae`` along earth-up on average (linear accelerations average out)
    and the undisturbed field's horizontal part (``heading_ok``) pointing north. Both are
    low-passed with ``RESET_TAU``; while one stays further than ``RESET_ANGLE`` from its
    reference, that run's vectors are summed (the field of the tilt run only where its norm is
    normal, ``field_ok``). A tilt run longer than ``RESET_TIME`` returns 1; a heading run longer
    than ``RESET_HEADING_TIME`` whose field directions agree (mean resultant length above
    ``RESET_AGREE``) returns 2; else 0 (To's "κ_post < κ_TH → reset").
    """
    alpha = min(1.0, dt / prm[RESET_TAU])
    cos_lim = np.cos(prm[RESET_ANGLE])
    for i in range(3):
        mon[_LA + i] += alpha * (ae[i] - mon[_LA + i])
    ln = np.sqrt(mon[_LA] ** 2 + mon[_LA + 1] ** 2 + mon[_LA + 2] ** 2)
    if mon[_LA + 2] < cos_lim * ln:
        for i in range(3):
            mon[_SA + i] += ae[i]
        if field_ok:
            for i in range(3):
                mon[_SM + i] += me[i]
            mon[_NM] += 1.0
        mon[_TA] += dt
        if mon[_TA] > prm[RESET_TIME]:
            return 1
    else:
        for i in range(_SA, _TA + 1):
            mon[i] = 0.0
    if heading_ok:
        hn = np.sqrt(me[0] ** 2 + me[1] ** 2)
        hx, hy = me[0] / hn, me[1] / hn
        mon[_LM] += alpha * (hx - mon[_LM])
        mon[_LM + 1] += alpha * (hy - mon[_LM + 1])
        if mon[_LM + 1] < cos_lim * np.sqrt(mon[_LM] ** 2 + mon[_LM + 1] ** 2):
            mon[_SH] += hx
            mon[_SH + 1] += hy
            mon[_NH] += 1.0
            mon[_TH] += dt
            agree = np.sqrt(mon[_SH] ** 2 + mon[_SH + 1] ** 2) > prm[RESET_AGREE] * mon[_NH]
            if mon[_TH] > prm[RESET_HEADING_TIME] and agree:
                return 2
        else:
            for i in range(_SH, _TH + 1):
                mon[i] = 0.0
    return 0


@numba.njit(cache=True)
def _reset_center(mon, mode, mean, prm, out):
    """The posterior mean re-aligned with the monitor's summed vectors, into ``out``.

    Tilt (``mode`` 1): the shortest rotation taking the summed acc to earth-up, then, when the
    summed field so tilted has the reference norm and dip, the rotation about up turning it north
    (TRIAD with gravity exact). Heading (``mode`` 2): the rotation about up only.
    """
    for i in range(4):
        out[i] = mean[i]
    if mode == 2:
        psi = np.arctan2(mon[_SH], mon[_SH + 1])
        cm.lmul(np.cos(0.5 * psi), 0.0, 0.0, np.sin(0.5 * psi), out)
        return
    an = np.sqrt(mon[_SA] ** 2 + mon[_SA + 1] ** 2 + mon[_SA + 2] ** 2)
    ux, uy, uz = mon[_SA] / an, mon[_SA + 1] / an, mon[_SA + 2] / an
    t0, t1, t2 = (1.0 + uz, uy, -ux) if 1.0 + uz > 1e-9 else (0.0, 1.0, 0.0)
    tn = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0, t1, t2 = t0 / tn, t1 / tn, t2 / tn
    cm.lmul(t0, t1, t2, 0.0, out)
    if mon[_NM] == 0.0:
        return
    c = 1.0 / mon[_NM]
    mx, my, mz = _rotate(t0, t1, t2, 0.0, c * mon[_SM], c * mon[_SM + 1], c * mon[_SM + 2])
    mn = np.sqrt(mx * mx + my * my + mz * mz)
    dip = np.arcsin(min(1.0, max(-1.0, -mz / mn))) if mn > 1e-9 else np.inf
    norm_ok = abs(mn - prm[REF_NORM]) < 2.0 * prm[MAG_NORM_TOLERANCE]
    if norm_ok and abs(dip - prm[REF_DIP]) < prm[MAG_GATE_DIP]:
        psi = np.arctan2(mx, my)
        cm.lmul(np.cos(0.5 * psi), 0.0, 0.0, np.sin(0.5 * psi), out)


# ---------------------------------------------------------------- the filter


@numba.njit(cache=True)
def nb_filter(
    gyr, acc, mag, use_mag, mag_flag, rest, dt, q0, prm, proposal, scheme, seed, n,
    ref_body, ref_earth, ref_var, bias0, quat, bias_out, ess_out, reset_out, gated_out, used,
):  # fmt: skip
    """The filter over all samples (see the module docstring for the order of the steps).

    ``ref_body`` (K, 3), ``ref_earth`` (N, K, 3, NaN = not seen) and ``ref_var`` (K,) are the
    marker reference vectors (K = 0: IMU only), ``bias0`` the initial gyroscope bias; ``used``
    receives the measurement bits of each sample.
    """
    state = np.empty(2, dtype=np.uint64)
    sph._nb_seed(state, seed)
    parts = np.empty((n, 4))
    tmp = np.empty((n, 4))
    w = np.full(n, 1.0 / n)
    lik = np.empty(n)
    work = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    cov = np.empty((3, 3))
    vecs = np.empty((3, 3))
    lam3 = np.empty(3)
    lam4 = np.empty(4)
    basis = np.empty((4, 4))
    jit = np.empty(4)
    info = np.empty(9)
    mon = np.empty(N_MONITOR)
    mean = q0.copy()
    prev = q0.copy()
    center = np.empty(4)
    ag = np.zeros(3)  # acc/g in the frame of G (the particles' offsets act on it)
    mg = np.zeros(3)  # field in the frame of G
    ae = np.empty(3)  # earth-frame vectors under the mean
    me = np.zeros(3)
    v3 = np.empty(3)
    g = np.array([1.0, 0.0, 0.0, 0.0])
    b = bias0.copy()
    prior = np.empty(4)
    rm = np.empty((3, 3))
    hidden_s = 0.0  # time since the marker vectors were last seen
    zmax = prm[BINGHAM_ZMAX]
    h = prm[KERNEL_H]
    rs.nb_spread(state, parts, q0, prm[INIT_SIGMA], proposal, zmax, lam4, basis, jit)
    _monitor_clear(mon)
    half = np.sqrt(3.0 * dt) * prm[PROCESS_NOISE]
    floor = prm[PROCESS_NOISE] ** 2 * dt
    g_ref = prm[GRAVITY]
    inv_sum = 1.0
    out_prev = q0.copy()
    for k in range(gyr.shape[0]):
        # 1. the shared strapdown integral G (To eq. 231), bias-compensated
        if k > 0:
            rx = (gyr[k, 0] - b[0]) * dt
            ry = (gyr[k, 1] - b[1]) * dt
            rz = (gyr[k, 2] - b[2]) * dt
            ang = np.sqrt(rx * rx + ry * ry + rz * rz)
            sk = np.sin(0.5 * ang) / ang if ang > 1e-12 else 0.5
            cm.rmul(g, np.cos(0.5 * ang), sk * rx, sk * ry, sk * rz)
        # 2. information about the correction of the prior mean (To's q_obs residuals, eqs.
        # 232-234): tilt from gravity, heading from the field angle
        for i in range(9):
            info[i] = 0.0
        _rot(g, acc[k, 0] / g_ref, acc[k, 1] / g_ref, acc[k, 2] / g_ref, ag)
        dev = abs(np.sqrt(ag[0] ** 2 + ag[1] ** 2 + ag[2] ** 2) - 1.0)
        used[k] = 0
        if dev < prm[ACC_GATE]:
            used[k] += USED_ACC
            sigma = prm[ACC_REST_SIGMA] if rest[k] else prm[ACC_SIGMA]
            sigma += prm[ACC_NORM_GAIN] * dev
            _rot(mean, ag[0], ag[1], ag[2], ae)
            _info_vector(info, ae[0], ae[1], ae[2], 0.0, 0.0, 1.0, 1.0 / (sigma * sigma))
        gated = True
        if use_mag:
            _rot(g, mag[k, 0], mag[k, 1], mag[k, 2], mg)
            _rot(mean, mg[0], mg[1], mg[2], me)
            psi, km, gated = _mag_heading(me[0], me[1], me[2], prm, rest[k], mag_flag[k])
            if km > 0.0:
                _info_heading(info, psi, km)
                used[k] += USED_MAG
        gated_out[k] = gated
        if ref_body.shape[0] > 0:
            # marker vectors: R(mean ⊗ G) a should turn into the measured direction
            prior[:] = mean
            cm.rmul(prior, g[0], g[1], g[2], g[3])
            cm.rot_matrix(prior, rm)
            seen = False
            for j in range(ref_body.shape[0]):
                seen = seen or np.isfinite(ref_earth[k, j, 0])
            widen = prm[MARKER_DRIFT] * hidden_s
            if seen and widen > 1e-4:
                for p in range(n):
                    sph._nb_vmf(state, 4.0 / (widen * widen), jit)
                    cm.rmul(parts[p], jit[0], jit[1], jit[2], jit[3])
            hidden_s = 0.0 if seen else hidden_s + dt
            jump = marker_jump(rm, ref_body, ref_earth, ref_var, k, 0.0)
            if jump > 0.0:
                rs.nb_spread(state, parts, mean, np.sqrt(jump), proposal, zmax, lam4, basis, jit)
                for p in range(n):
                    w[p] = 1.0 / n
                inv_sum = 1.0
            for j in range(ref_body.shape[0]):
                if np.isfinite(ref_earth[k, j, 0]):
                    ax, ay, az = ref_body[j, 0], ref_body[j, 1], ref_body[j, 2]
                    ux = rm[0, 0] * ax + rm[0, 1] * ay + rm[0, 2] * az
                    uy = rm[1, 0] * ax + rm[1, 1] * ay + rm[1, 2] * az
                    uz = rm[2, 0] * ax + rm[2, 1] * ay + rm[2, 2] * az
                    ox, oy, oz = ref_earth[k, j, 0], ref_earth[k, j, 1], ref_earth[k, j, 2]
                    _info_vector(info, ux, uy, uz, ox, oy, oz, 1.0 / ref_var[j])
                    used[k] |= USED_MARKERS
        # 3.-4. particles: noise, likelihood, weights, posterior mean
        lmax = _move_and_score(state, parts, mean, info, half if k > 0 else 0.0, lik)
        prev[:] = mean
        inv_sum, ess = _weigh(w, lik, lmax, inv_sum, parts, mean)
        # 5. bias (BC, To §6.5.7): at rest the rate itself; optionally the mean's correction
        # c = prev* ⊗ mean in the sensor frame (Mahony-type integral)
        d0 = prev[0] * mean[0] + prev[1] * mean[1] + prev[2] * mean[2] + prev[3] * mean[3]
        sd = 2.0 if d0 >= 0.0 else -2.0
        cx = sd * (prev[0] * mean[1] - prev[1] * mean[0] - prev[2] * mean[3] + prev[3] * mean[2])
        cy = sd * (prev[0] * mean[2] + prev[1] * mean[3] - prev[2] * mean[0] - prev[3] * mean[1])
        cz = sd * (prev[0] * mean[3] - prev[1] * mean[2] + prev[2] * mean[1] - prev[3] * mean[0])
        _rot_inv(g, cx, cy, cz, v3)
        for i in range(3):
            b[i] -= v3[i] / prm[BIAS_TAU]
            if rest[k]:
                b[i] += dt / prm[BIAS_REST_TAU] * (gyr[k, i] - b[i])
            b[i] = min(prm[BIAS_MAX], max(-prm[BIAS_MAX], b[i]))
        # divergence monitor on the posterior, then reset or resampling
        _monitor_follow(mon, mean, prev)
        _rot(mean, ag[0], ag[1], ag[2], ae)
        if use_mag:
            _rot(mean, mg[0], mg[1], mg[2], me)
        field_ok = use_mag and not mag_flag[k]
        mode = _monitor(mon, ae, me, field_ok, not gated, prm, dt)
        if mode != 0 or ess < prm[ESS_THRESHOLD] * n:
            for p in range(n):
                w[p] *= inv_sum
            inv_sum = 1.0
        if mode != 0:
            _reset_center(mon, mode, mean, prm, center)
            rs.nb_spread(state, parts, center, prm[INIT_SIGMA], proposal, zmax, lam4, basis, jit)
            for p in range(n):
                w[p] = 1.0 / n
            mean[:] = center
            _monitor_clear(mon)
            reset_out[k] = True
        elif ess < prm[ESS_THRESHOLD] * n:
            # resample, then regularise: Liu-West shrinkage plus a kernel draw (Musso et al.)
            kappa, bb = rs.nb_kernel_shape(
                parts, w, mean, h, floor, proposal, cov, vecs, lam3, lam4, basis
            )
            rs.nb_resample(state, scheme, prm[AUX_ALPHA], w, idx, work)
            rs.nb_regularise(
                state, parts, tmp, idx, mean, h, proposal, kappa, lam4, basis, bb, zmax, jit
            )
        # output q = mean ⊗ G, sign-continuous
        o0 = mean[0] * g[0] - mean[1] * g[1] - mean[2] * g[2] - mean[3] * g[3]
        o1 = mean[0] * g[1] + mean[1] * g[0] + mean[2] * g[3] - mean[3] * g[2]
        o2 = mean[0] * g[2] - mean[1] * g[3] + mean[2] * g[0] + mean[3] * g[1]
        o3 = mean[0] * g[3] + mean[1] * g[2] - mean[2] * g[1] + mean[3] * g[0]
        if o0 * out_prev[0] + o1 * out_prev[1] + o2 * out_prev[2] + o3 * out_prev[3] < 0.0:
            o0, o1, o2, o3 = -o0, -o1, -o2, -o3
        quat[k, 0] = o0
        quat[k, 1] = o1
        quat[k, 2] = o2
        quat[k, 3] = o3
        out_prev[0], out_prev[1], out_prev[2], out_prev[3] = o0, o1, o2, o3
        for i in range(3):
            bias_out[k, i] = b[i]
        ess_out[k] = ess / n
