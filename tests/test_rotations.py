"""Property tests of every helper in :mod:`motionlab.rotations` (hypothesis, derandomised)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from motionlab import rotations as R
from motionlab.fusion import _common as cm

PROPS = settings(max_examples=60, deadline=None, derandomize=True)
FLOATS = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


@st.composite
def quats(draw, n: int | None = None):
    """Unit quaternions, shape (4,) or (n, 4), with norms before normalising ≥ 0.1."""
    shape = (4,) if n is None else (n, 4)
    a = draw(arrays(float, shape, elements=FLOATS))
    assume(np.all(np.linalg.norm(a, axis=-1) > 0.1))
    return _unit(a)


vectors = arrays(float, (5, 3), elements=st.floats(-10, 10, allow_nan=False))


def same_rotation(p, q, atol=1e-9):
    """p and q equal up to the sign of the whole quaternion (double cover)."""
    d = np.abs(np.sum(np.asarray(p) * np.asarray(q), axis=-1))
    return np.allclose(d, 1.0, atol=atol)


# ----------------------------------------------------------------------------- algebra


@PROPS
@given(quats(5), quats(5), quats(5))
def test_mul_associative(p, q, r):
    np.testing.assert_allclose(R.mul(R.mul(p, q), r), R.mul(p, R.mul(q, r)), atol=1e-12)


@PROPS
@given(quats(5))
def test_mul_identity_and_inverse(q):
    np.testing.assert_allclose(R.mul(R.IDENTITY, q), q, atol=1e-15)
    np.testing.assert_allclose(R.mul(q, R.IDENTITY), q, atol=1e-15)
    np.testing.assert_allclose(R.mul(q, R.conj(q)), np.tile(R.IDENTITY, (5, 1)), atol=1e-12)


def test_mul_hamilton_units():
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_array_equal(R.mul(i, j), k)  # Hamilton: ij = k (JPL would give -k)
    np.testing.assert_array_equal(R.mul(j, k), i)
    np.testing.assert_array_equal(R.mul(i, i), -R.IDENTITY)


@PROPS
@given(quats(5), quats(5))
def test_conj_of_product(p, q):
    np.testing.assert_allclose(R.conj(R.mul(p, q)), R.mul(R.conj(q), R.conj(p)), atol=1e-12)
    np.testing.assert_array_equal(R.conj(R.conj(p)), p)


@PROPS
@given(arrays(float, (5, 4), elements=st.floats(-100, 100, allow_nan=False)))
def test_normalize(a):
    assume(np.all(np.linalg.norm(a, axis=-1) > 1e-3))
    u = R.normalize(a)
    np.testing.assert_allclose(np.linalg.norm(u, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(u * np.linalg.norm(a, axis=-1, keepdims=True), a, atol=1e-12)


# ----------------------------------------------------------------------------- rotating vectors


@PROPS
@given(quats(5), vectors)
def test_rotate_matches_sandwich_matrix_and_scipy(q, v):
    sandwich = R.mul(R.mul(q, np.concatenate([np.zeros((5, 1)), v], axis=1)), R.conj(q))
    np.testing.assert_allclose(sandwich[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(R.rotate(q, v), sandwich[:, 1:], atol=1e-12)
    np.testing.assert_allclose(
        R.rotate(q, v), np.einsum("nij,nj->ni", R.to_matrix(q), v), atol=1e-12
    )
    np.testing.assert_allclose(R.rotate(q, v), R.to_scipy(q).apply(v), atol=1e-12)


def test_rotate_loop_is_the_broadcast_formula_to_the_bit():
    """The one-loop path (:func:`motionlab.quat_kernels.rotate_rows`) against the formula it
    replaced, ``v + w t + u × t`` with ``t = 2 u × v`` broadcast by numpy, in every shape pair
    it takes; shapes it does not take broadcast as before."""
    rng = np.random.default_rng(3)
    q, v = R.normalize(rng.normal(size=(7, 4))), rng.normal(size=(7, 3))

    def formula(q, v):
        t = 2.0 * np.cross(q[..., 1:], v)
        return v + q[..., :1] * t + np.cross(q[..., 1:], t)

    for a, b in [(q, v), (q[0], v), (q, v[0]), (q[0], v[0]), (q[:1], v), (q, v[:1]),
                 (q[:1], v[0]), (q[::-2], v[::-2]), (q[:, None], v[None])]:  # fmt: skip
        got, want = R.rotate(a, b), formula(a, b)
        assert got.shape == want.shape
        np.testing.assert_array_equal(got, want)


def test_rotate_hand_computed():
    # 90° about earth z (ENU up): the sensor x axis points north (earth y)
    q = R.from_axis_angle([0, 0, 1], np.pi / 2)
    np.testing.assert_allclose(R.rotate(q, [1.0, 0, 0]), [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(R.to_matrix(q)[:, 0], [0, 1, 0], atol=1e-15)


@PROPS
@given(quats(5), vectors)
def test_numba_kernels_match_numpy(q, v):
    # the allocation-free helpers of the estimators' loops (motionlab.fusion._common)
    for k in range(5):
        p, rv = q[(k + 1) % 5], 0.5 * v[k]
        np.testing.assert_allclose(cm.qmul(*q[k], *p), R.mul(q[k], p), atol=1e-15)
        np.testing.assert_allclose(cm.normq(*(3.0 * q[k])), q[k], atol=1e-15)
        r = np.empty((3, 3))
        cm.rot_matrix(q[k], r)
        np.testing.assert_allclose(r @ v[k], R.rotate(q[k], v[k]), atol=1e-12)
        out = np.empty(4)
        cm.mul_exp_right(q[k], *rv, out)
        np.testing.assert_allclose(out, R.mul(q[k], R.from_rotvec(rv)), atol=1e-12)
        left = q[k].copy()
        cm.mul_exp_left(*rv, left)
        np.testing.assert_allclose(left, R.mul(R.from_rotvec(rv), q[k]), atol=1e-12)
        rel = np.array(cm.conj_mul_shortest(q[k], p))
        expect = R.mul(R.conj(q[k]), p)
        np.testing.assert_allclose(rel, expect if expect[0] >= 0 else -expect, atol=1e-15)
        row = 3.0 * q[k]
        cm.normalize(row)
        np.testing.assert_allclose(row, q[k], atol=1e-15)


# ----------------------------------------------------------------------------- conversions


@PROPS
@given(quats(5))
def test_matrix_round_trip(q):
    m = R.to_matrix(q)
    np.testing.assert_allclose(
        m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-12)
    back = R.from_matrix(m)
    assert np.all(back[:, 0] >= 0)
    assert same_rotation(back, q)
    np.testing.assert_allclose(m, R.to_scipy(q).as_matrix(), atol=1e-12)


@PROPS
@given(quats(5))
def test_scipy_round_trip(q):
    back = R.from_scipy(R.to_scipy(q))
    assert same_rotation(back, q)
    assert np.all(back[:, 0] >= 0)
    # scalar-last boundary: scipy sees [x, y, z, w]
    np.testing.assert_allclose(
        Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix(), R.to_matrix(q), atol=1e-12
    )


@PROPS
@given(arrays(float, (5, 3), elements=st.floats(-3.0, 3.0, allow_nan=False)))
def test_rotvec_round_trip(rv):
    assume(np.all(np.linalg.norm(rv, axis=-1) < np.pi - 1e-6))
    q = R.from_rotvec(rv)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(R.to_rotvec(q), rv, atol=1e-9)
    np.testing.assert_allclose(R.to_rotvec(-q), rv, atol=1e-9)  # sign does not matter
    np.testing.assert_allclose(rv, Rotation.from_rotvec(rv).as_rotvec(), atol=1e-9)
    np.testing.assert_allclose(R.angle(q), np.linalg.norm(rv, axis=-1), atol=1e-9)


def test_rotvec_small_angles():
    rv = np.array([[0.0, 0.0, 0.0], [1e-14, 0, 0], [0, 2e-9, 0]])
    q = R.from_rotvec(rv)
    np.testing.assert_allclose(q[:, 1:], rv / 2, rtol=1e-12, atol=0)
    np.testing.assert_allclose(R.to_rotvec(q), rv, rtol=1e-9, atol=1e-30)


@PROPS
@given(arrays(float, 3, elements=FLOATS), st.floats(-2 * np.pi, 2 * np.pi))
def test_axis_angle(axis, a):
    assume(np.linalg.norm(axis) > 0.1)
    q = R.from_axis_angle(axis, a)
    np.testing.assert_allclose(q, R.from_rotvec(_unit(axis) * a), atol=1e-12)
    np.testing.assert_allclose(R.angle(q), abs((a + np.pi) % (2 * np.pi) - np.pi), atol=1e-9)


@PROPS
@given(quats(5), quats(5))
def test_angle_between_is_a_metric(p, q):
    d = R.angle_between(p, q)
    np.testing.assert_allclose(d, R.angle_between(q, p), atol=1e-9)
    np.testing.assert_allclose(d, R.angle_between(p, -q), atol=1e-9)
    np.testing.assert_allclose(d, (R.to_scipy(p) * R.to_scipy(q).inv()).magnitude(), atol=1e-7)
    np.testing.assert_allclose(R.angle_between(p, p), 0.0, atol=1e-7)


# ----------------------------------------------------------------------------- sequences


@PROPS
@given(quats(20), st.lists(st.booleans(), min_size=20, max_size=20))
def test_make_continuous(q, flip):
    smooth = R.make_continuous(R.slerp(q[0], q[1], np.linspace(0, 1, 20)))
    noisy = smooth * np.where(flip, -1.0, 1.0)[:, None]
    fixed = R.make_continuous(noisy)
    assert np.all(np.sum(fixed[1:] * fixed[:-1], axis=1) >= 0)
    np.testing.assert_array_equal(fixed[0], noisy[0])  # the first sample keeps its sign
    assert same_rotation(fixed, noisy)


@PROPS
@given(quats(), quats())
def test_slerp_endpoints_and_constant_rate(q0, q1):
    t = np.linspace(0.0, 1.0, 11)
    path = R.slerp(q0, q1, t)
    assert same_rotation(path[0], q0)
    assert same_rotation(path[-1], q1)
    np.testing.assert_allclose(np.linalg.norm(path, axis=-1), 1.0, atol=1e-12)
    total = R.angle_between(q0, q1)
    steps = R.angle_between(path[1:], path[:-1])
    np.testing.assert_allclose(steps, total / 10, atol=1e-6)  # constant angular rate
    np.testing.assert_allclose(R.angle_between(path, q0), t * total, atol=1e-6)  # short arc


def test_slerp_takes_the_short_arc_through_minus_q1():
    q0 = R.IDENTITY
    q1 = -R.from_axis_angle([0, 0, 1], 0.2)  # same rotation, opposite hemisphere
    mid = R.slerp(q0, q1, 0.5)
    np.testing.assert_allclose(R.angle(mid), 0.1, atol=1e-12)


@PROPS
@given(quats(), arrays(float, 3, elements=FLOATS))
def test_resample_constant_rate(q0, w):
    # a constant body rate: q(t) = q0 ⊗ exp(w t); SLERP between samples is exact on it
    t = np.arange(6) * 0.1
    q = R.mul(q0, R.from_rotvec(t[:, None] * w))
    t_new = np.linspace(0.0, 0.5, 17)
    out = R.resample(t, q, t_new)
    truth = R.mul(q0, R.from_rotvec(t_new[:, None] * w))
    np.testing.assert_allclose(out, truth, atol=1e-9)  # same sign too: continuous from q[0]
    assert same_rotation(R.resample(t, q, t), q)
    # clamped outside the span
    assert same_rotation(R.resample(t, q, [-1.0, 9.0]), q[[0, -1]])


@PROPS
@given(quats(), arrays(float, (30, 3), elements=st.floats(-0.05, 0.05, allow_nan=False)))
def test_mean_of_a_cloud(q0, noise):
    cloud = R.mul(q0, R.from_rotvec(noise))
    cloud[::3] *= -1.0  # the mean must not care about sign
    m = R.mean(cloud)
    assert m[0] >= 0
    np.testing.assert_allclose(np.linalg.norm(m), 1.0, atol=1e-12)
    assert R.angle_between(m, q0) <= np.max(np.linalg.norm(noise, axis=1)) + 1e-9
    ref = R.from_scipy(R.to_scipy(cloud).mean())
    assert R.angle_between(m, ref) < 1e-9  # scipy's mean is the same Markley estimator


def test_mean_weights():
    a = R.from_axis_angle([1, 0, 0], 0.0)
    b = R.from_axis_angle([1, 0, 0], 0.4)
    m = R.mean(np.stack([a, b]), weights=np.array([0.0, 1.0]))
    assert same_rotation(m, b)


@PROPS
@given(quats(), arrays(float, 3, elements=st.floats(-5, 5, allow_nan=False)))
def test_integrate_gyro_constant_rate(q0, w):
    n, dt = 201, 0.01
    out = R.integrate_gyro(q0, np.tile(w, (n, 1)), dt)
    truth = R.mul(q0, R.from_rotvec(np.arange(n)[:, None] * dt * w))
    np.testing.assert_allclose(out, truth, atol=1e-9)
    # the same with per-interval steps
    out2 = R.integrate_gyro(q0, np.tile(w, (n, 1)), np.full(n - 1, dt))
    np.testing.assert_array_equal(out, out2)


def test_integrate_gyro_one_sample_and_empty():
    np.testing.assert_array_equal(
        R.integrate_gyro(R.IDENTITY, np.zeros((1, 3)), 0.01), [R.IDENTITY]
    )
    assert R.integrate_gyro(R.IDENTITY, np.zeros((0, 3)), 0.01).shape == (0, 4)


@pytest.mark.parametrize("w", [[0.0, 0.0, 1.0], [2.0, -1.0, 0.5]])
def test_integrate_gyro_body_frame(w):
    # body rates compose on the right: the rotation axis is fixed in the sensor frame
    q0 = R.from_axis_angle([1, 0, 0], 1.0)
    out = R.integrate_gyro(q0, np.tile(w, (101, 1)), 0.01)
    rel = R.mul(R.conj(q0), out[-1])
    np.testing.assert_allclose(R.to_rotvec(rel), np.asarray(w) * 1.0, atol=1e-9)


def test_resample_agrees_with_scipys_slerp():
    """:func:`R.resample` gives scipy's Slerp's quaternions (to 1e-12, before the sign
    conventions) over tiny and large steps, no motion at all, at the knots, between them and at
    the ends, inputs of any norm; and it refuses what Slerp refuses."""
    from scipy.spatial.transform import Slerp

    rng = np.random.default_rng(11)
    for step in (1e-5, 4e-4, 3e-3, 0.3):
        inc = R.from_rotvec(rng.normal(size=(600, 3)) * step)
        inc[::40] = R.IDENTITY  # no motion at all
        q = np.empty((600, 4))
        q[0] = R.normalize(rng.normal(size=4))
        for i in range(1, 600):
            q[i] = R.mul(q[i - 1], inc[i])
        q *= rng.uniform(0.5, 2.0, size=(600, 1))  # any norm: normalised as scipy does
        t = np.cumsum(rng.uniform(0.005, 0.02, 600))
        for t_new in (t, np.linspace(t[0], t[-1], 1001), t[::3] + 0.001, t[[0, -1]]):
            ref = R.from_scipy(Slerp(t, R.to_scipy(q))(np.clip(t_new, t[0], t[-1])))
            got = R.resample(t, q, t_new)
            got = got * np.where(got[:, :1] < 0, -1.0, 1.0)
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12, err_msg=str(step))
    for t, q in (
        ([0.0, 1.0], np.zeros((2, 4))),
        ([1.0, 1.0], np.ones((2, 4))),
        ([0.0], np.ones((1, 4))),
    ):
        with pytest.raises(ValueError):
            R.resample(np.array(t), q, np.array([0.0]))
    with pytest.raises(ValueError, match="range"):
        R.resample(np.array([0.0, 1.0]), np.ones((2, 4)), np.array([np.nan]))


def test_mul_loop_is_the_vectorised_product():
    """:func:`R.mul`'s compiled loop (rows, a row against many, single quaternions) gives the
    numbers of the vectorised product it replaced, to the bit (NaN, infinities and −0 too),
    and the same shapes; other shapes broadcast as before."""

    def vectorised(p, q):  # R.mul takes its broadcasting path above two dimensions
        return R.mul(np.asarray(p)[None, None], np.asarray(q)[None, None])[0, 0]

    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(50, 4)) * 1e3, rng.normal(size=(50, 4))
    a[3, 1], b[4, 2], a[5] = np.nan, np.inf, -0.0
    for p, q in (
        (a, b), (a[:1], b), (a, b[7]), (a[2], b[9]), (a[:0], b[1]), (a[1], b[:0]),
        (a[::2], b[1::2]), (a.T[:, :4].T, b[:4]), (a.reshape(5, 10, 4), b[:10]),
    ):  # fmt: skip
        got, ref = R.mul(p, q), vectorised(p, q)
        assert got.shape == ref.shape and np.array_equal(got, ref, equal_nan=True)
        assert np.array_equal(np.signbit(got), np.signbit(ref))
