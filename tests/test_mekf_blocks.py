"""The smoother's multi-rate MEKF (``motionlab.fusion._mekf_blocks``): its forward pass against the
per-sample kernel, its backward pass against a dense RTS step, and the multi-rate smoother against
the full-rate one."""

import numpy as np
import pytest
from test_fusion_mekf import _rest_then_motion

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.fusion import _mekf_blocks as blk
from motionlab.fusion import _mekf_kernels as kern
from motionlab.fusion import estimate
from motionlab.fusion.detect import rest_mask, steady_mask
from motionlab.fusion.mekf import SmootherParams, _p0, _pack, _unpacked, block_outputs
from motionlab.validation.orientation_error import error_angles


def _inputs(m: int, seconds_move: float = 8.0):
    sig = _rest_then_motion(seconds_rest=3.0, seconds_move=seconds_move, bias=(0.01, -0.01, 0.005))
    p = SmootherParams()
    rest = rest_mask(sig["gyr"], sig["acc"], sig["rate"], min_duration=p.rest_min_duration)
    steady = steady_mask(sig["gyr"], sig["rate"], rest, p.rest_sway)
    n = len(sig["gyr"])
    nb = len(blk.instants(n, m))
    out = block_outputs(n, nb)
    q0 = rot.from_axis_angle([0.3, -1.0, 0.2], 0.6)
    blk.forward(
        sig["gyr"], sig["acc"], np.zeros((1, 3)), False, np.ones(1), rest, steady, np.zeros(1),
        1.0 / sig["rate"], m, q0, _p0(p), _pack(p), out["quat"], out["qprior"], out["gsum"],
        out["bias_blk"], out["acc_bias_blk"], out["reset_blk"], out["p_post"], out["field"],
    )  # fmt: skip
    return sig, p, rest, steady, q0, out


def test_instants():
    assert blk.instants(11, 5).tolist() == [0, 5, 10]
    assert blk.instants(12, 5).tolist() == [0, 5, 10, 11]
    assert blk.instants(2, 4).tolist() == [0, 1]


@pytest.mark.parametrize("value", ["nan", "inf", "-0.01"])
def test_a_bad_update_interval_is_refused(value):
    sig = _rest_then_motion(seconds_rest=2.0, seconds_move=1.0)
    with pytest.raises(InputError, match="update_interval"):
        estimate("smoother", sig["gyr"], sig["acc"], None, sig["rate"], update_interval=value)
    # longer than the recording: one block after sample 0
    res = estimate("smoother", sig["gyr"], sig["acc"], None, sig["rate"], update_interval=1e9)
    assert np.isfinite(res.quat).all()


def test_one_sample_blocks_are_the_per_sample_filter():
    """With m = 1 the multi-rate forward pass is the online filter's kernel (6-D, no reset):
    the same orientations and biases at every sample to rounding. (The covariances enter every
    gain, at rest and in motion: a covariance apart would move the states; the stored ones are
    checked against the dense RTS step below.)"""
    sig, p, rest, steady, q0, out = _inputs(1)
    n = len(sig["gyr"])
    ref = {"quat": np.empty((n, 4)), "bias": np.empty((n, 3)), "acc_bias": np.empty((n, 3))}
    kern.forward(
        sig["gyr"], sig["acc"], np.zeros((1, 3)), False, rest, steady, 1.0 / sig["rate"], q0,
        _p0(p), _pack(p), ref["quat"], ref["bias"], ref["acc_bias"], np.empty(n, dtype=np.bool_),
        np.empty(n, dtype=np.int8),
    )  # fmt: skip
    assert not out["reset_blk"].any()
    assert rest.any() and steady.any() and not rest.all()
    for name in ("quat", "bias", "acc_bias"):
        got = out[name if name == "quat" else f"{name}_blk"]
        np.testing.assert_allclose(got, ref[name], rtol=0, atol=1e-12, err_msg=name)


def _rotvec(q: np.ndarray) -> np.ndarray:
    q = q if q[0] >= 0 else -q
    vn = np.linalg.norm(q[1:])
    return 2.0 * np.arctan2(vn, q[0]) * q[1:] / vn if vn > 1e-12 else 2.0 * q[1:]


@pytest.mark.parametrize("m", [1, 5])
def test_backward_pass_is_the_dense_rts_step(m):
    """The backward pass at the instants against the RTS step written out with dense 9 × 9
    matrices: ``Φ = [[I, −dt Σ R, 0], [0, I, 0], [0, 0, I]]``, ``P⁻ = Φ P Φᵀ + c Q``,
    ``e_j = P Φᵀ (P⁻)⁻¹ e⁻_{j+1}`` (to 1e-10)."""
    sig, p, _, _, _, out = _inputs(m, seconds_move=3.0)
    n, dt = len(sig["gyr"]), 1.0 / sig["rate"]
    at = blk.instants(n, m)
    fwd = {k: v.copy() for k, v in out.items()}
    prm = _pack(p)
    bias_out, acc_out = np.empty((n, 3)), np.empty((n, 3))
    blk.backward(
        dt, m, out["quat"], out["qprior"], out["gsum"], out["bias_blk"], out["acc_bias_blk"],
        out["p_post"], out["reset_blk"], np.zeros(1), prm, True, bias_out, acc_out, out["field"],
    )  # fmt: skip
    q_noise = np.array([prm[kern.GYR_NOISE] ** 2] * 3 + [prm[kern.BIAS_RW] ** 2] * 3
                       + [prm[kern.ACC_BIAS_RW] ** 2] * 3) * dt  # fmt: skip
    qs = fwd["quat"][at[-1]].copy()
    bs, as_ = fwd["bias_blk"][-1].copy(), fwd["acc_bias_blk"][-1].copy()
    for j in range(len(at) - 2, -1, -1):
        phi = np.eye(9)
        phi[:3, 3:6] = -dt * fwd["gsum"][j + 1]
        pj = _unpacked(fwd["p_post"][j])
        prior = phi @ pj @ phi.T + np.diag((at[j + 1] - at[j]) * q_noise)
        err = np.concatenate(
            [_rotvec(rot.mul(qs, rot.conj(fwd["qprior"][j + 1]))), bs - fwd["bias_blk"][j],
             as_ - fwd["acc_bias_blk"][j]]
        )  # fmt: skip
        e = pj @ phi.T @ np.linalg.solve(prior, err)
        angle = np.linalg.norm(e[:3])
        dq = rot.from_axis_angle(e[:3] / angle, angle) if angle > 0 else np.array([1.0, 0, 0, 0])
        qs = rot.mul(dq, fwd["quat"][at[j]])
        bs, as_ = fwd["bias_blk"][j] + e[3:6], fwd["acc_bias_blk"][j] + e[6:]
        same = qs if np.dot(qs, out["quat"][at[j]]) >= 0 else -qs
        np.testing.assert_allclose(out["quat"][at[j]], same, atol=1e-10)
        np.testing.assert_allclose(bias_out[at[j]], bs, atol=1e-12)
        np.testing.assert_allclose(acc_out[at[j]], as_, atol=1e-12)
    # between the instants: signs continuous, biases linear
    assert (np.einsum("ij,ij->i", out["quat"][1:], out["quat"][:-1]) > 0).all()
    if m > 1:
        np.testing.assert_allclose(bias_out[1], bias_out[0] + (bias_out[m] - bias_out[0]) / m)


@pytest.mark.parametrize("mag", [False, True])
def test_multi_rate_smoother_equals_the_full_rate_one(mag):
    """Every 40 ms (4 samples at 100 Hz) against every sample, on a simulated rest, tumbling
    and rest with gyroscope bias: within 0.01° of each other at every sample (measured 0.0025°
    6-D, 0.002° 9-D), as close to the truth (RMS within 0.005°) and the same gyroscope bias
    (within 1e-5 rad/s; measured 8e-7)."""
    sig = _rest_then_motion(bias=(0.01, -0.01, 0.005), seed=3)
    m = sig["mag"] if mag else None
    full = estimate("smoother", sig["gyr"], sig["acc"], m, sig["rate"], update_interval=0.0)
    multi = estimate("smoother", sig["gyr"], sig["acc"], m, sig["rate"])
    assert SmootherParams().update_interval == 0.04
    between = error_angles(multi.quat, full.quat)["total"]
    assert between.max() < 0.01
    e_full = error_angles(full.quat, sig["quat"])["total"]
    e_multi = error_angles(multi.quat, sig["quat"])["total"]
    if not mag:  # 6-D: the heading is free; compare the inclination
        e_full = error_angles(full.quat, sig["quat"])["inclination"]
        e_multi = error_angles(multi.quat, sig["quat"])["inclination"]
    rms = [float(np.sqrt(np.mean(e**2))) for e in (e_full, e_multi)]
    assert rms[1] < rms[0] + 0.005
    np.testing.assert_allclose(multi.gyro_bias, full.gyro_bias, atol=1e-5)


def test_field_gate_reads_an_earth_frame_field():
    """The gate on block means (25 Hz): a 2-s disturbance (norm +20 %) is gated with its hold
    (0.5 s, 12 blocks) and smoothing (0.2 s) on either side, the reference is the undisturbed
    field's, a zero field is gated (with its hold)."""
    from motionlab.fusion.detect import field_gate

    rate, n = 25.0, 500
    dip = np.deg2rad(-60.0)
    field = np.tile([0.0, 48.0 * np.cos(dip), 48.0 * np.sin(dip)], (n, 1))
    field += 0.3 * np.random.default_rng(2).standard_normal((n, 3))
    field[200:250] *= 1.2
    field[400] = 0.0
    gated, dev, ref_n, ref_d = field_gate(field, rate)
    assert abs(ref_n - 48.0) < 0.1 and abs(ref_d - dip) < np.deg2rad(0.5)
    assert gated[188:262].all() and gated[388:413].all()
    assert not gated[:185].any() and not gated[265:385].any() and not gated[417:].any()
    assert np.all(dev[:150] < 0.5)
