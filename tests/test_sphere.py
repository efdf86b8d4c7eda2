"""Samplers and the weighted mean on S³ (motionlab.fusion.sphere) and the resampling schemes."""

import numpy as np
import pytest
from scipy.special import ive

from motionlab import rotations as rot
from motionlab.fusion import sphere
from motionlab.fusion.resampling import SCHEMES, resample


@pytest.mark.parametrize("kappa", [0.5, 2.0, 10.0, 100.0, 1e4])
def test_vmf_mean_resultant_length(kappa):
    # E[μᵀx] = A₄(κ) = I₂(κ)/I₁(κ) for the vMF on S³
    mu = rot.normalize(np.array([0.3, -0.5, 0.2, 0.8]))
    x = sphere.sample_vmf(mu, kappa, 40000, seed=7)
    t = x @ mu
    expected = ive(2, kappa) / ive(1, kappa)
    assert abs(t.mean() - expected) < 5 * t.std() / np.sqrt(len(t)) + 1e-12
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 1.0, atol=1e-12)


def test_vmf_seeded_and_uniform_limit():
    a = sphere.sample_vmf([1, 0, 0, 0], 5.0, 100, seed=3)
    np.testing.assert_array_equal(a, sphere.sample_vmf([1, 0, 0, 0], 5.0, 100, seed=3))
    assert not np.array_equal(a, sphere.sample_vmf([1, 0, 0, 0], 5.0, 100, seed=4))
    u = sphere.sample_vmf([1, 0, 0, 0], 0.0, 40000, seed=1)
    np.testing.assert_allclose(u.T @ u / len(u), np.eye(4) / 4, atol=0.01)


def _bingham_moments_quadrature(lam):
    # E[x_i²] for f ∝ exp(−Σ λᵢxᵢ²) on S³ by Gauss–Legendre on hyperspherical coordinates
    n = 64
    g, wg = np.polynomial.legendre.leggauss(n)
    psi = (g + 1) * np.pi / 2
    th = (g + 1) * np.pi / 2
    ph = (g + 1) * np.pi
    P, T, F = np.meshgrid(psi, th, ph, indexing="ij")
    W = np.einsum("i,j,k->ijk", wg, wg, wg) * np.sin(P) ** 2 * np.sin(T)
    x = np.stack(
        [np.cos(P), np.sin(P) * np.cos(T), np.sin(P) * np.sin(T) * np.cos(F),
         np.sin(P) * np.sin(T) * np.sin(F)]
    )  # fmt: skip
    dens = W * np.exp(-np.einsum("i,i...->...", lam, x**2))
    return np.array([(dens * xi**2).sum() for xi in x]) / dens.sum()


@pytest.mark.parametrize("lam", [[0.0, 1.0, 4.0, 9.0], [0.0, 20.0, 20.0, 60.0]])
def test_bingham_second_moments(lam):
    lam = np.array(lam)
    basis = rot.to_matrix(rot.from_axis_angle([1, 2, 3], 0.7))  # any orthogonal 4×4 below
    u = np.eye(4)
    u[1:, 1:] = basis
    a = u @ np.diag(lam) @ u.T
    x = sphere.sample_bingham(a, 60000, seed=11)
    m = u.T @ (x.T @ x / len(x)) @ u
    np.testing.assert_allclose(np.diag(m), _bingham_moments_quadrature(lam), atol=0.01)
    assert np.abs(m - np.diag(np.diag(m))).max() < 0.01


def test_bingham_band_and_covariance_shape():
    cov = np.diag([1e-4, 4e-4, 9e-4])
    mu = rot.from_axis_angle([0, 0, 1], 0.4)
    a = sphere.bingham_from_covariance(mu, cov)
    x = sphere.sample_bingham(a, 40000, seed=2)
    x = x * np.sign(x @ mu)[:, None]
    r = rot.to_rotvec(rot.mul(x, rot.conj(mu)))
    np.testing.assert_allclose(np.cov(r.T), cov, atol=3e-5)
    band = sphere.sample_bingham(a, 20000, seed=2, zmax=0.5 * 2.0**2)
    xb = band * np.sign(band @ mu)[:, None]
    rb = rot.to_rotvec(rot.mul(xb, rot.conj(mu)))
    assert (np.einsum("ij,jk,ik->i", rb, np.linalg.inv(cov), rb) < 4.0 * 1.01).all()


def test_weighted_mean_of_symmetric_set():
    center = rot.from_axis_angle([1, -1, 2], 1.1)
    offsets = rot.from_rotvec(0.3 * np.vstack([np.eye(3), -np.eye(3)]))
    q = rot.mul(center, offsets)
    q[::2] *= -1  # the sign of each quaternion must not matter
    w = np.array([1.0, 2.0, 3.0, 1.0, 2.0, 3.0])
    for m in (sphere.weighted_mean(q, w), sphere.weighted_mean(q)):
        assert rot.angle_between(m, center) < 1e-9
    rng = np.random.default_rng(0)
    cloud = rot.mul(center, rot.from_rotvec(rng.normal(0, 0.2, (200, 3))))
    wc = rng.random(200)
    assert rot.angle_between(sphere.weighted_mean(cloud, wc), rot.mean(cloud, wc)) < 1e-9


@pytest.mark.parametrize("scheme", SCHEMES)
def test_resampling_expected_counts(scheme):
    rng = np.random.default_rng(5)
    n = 64
    w = rng.random(n) ** 3
    w /= w.sum()
    runs = 3000 if scheme != "deterministic" else 3
    counts = np.empty((runs, n))
    mass = np.empty((runs, n))
    for s in range(runs):
        idx, nw = resample(w, scheme, seed=s, alpha=2.0)
        counts[s] = np.bincount(idx, minlength=n)
        mass[s] = np.bincount(idx, weights=nw, minlength=n)
    assert (counts.sum(axis=1) == n).all()
    if scheme in ("systematic", "deterministic"):
        assert (np.abs(counts - n * w) < 1.0).all()  # ⌊Nw⌋ or ⌈Nw⌉ copies
    if scheme == "deterministic":
        assert (counts == counts[0]).all()
    if scheme == "residual":
        assert (counts >= np.floor(n * w)).all()
        frac = n * w - np.floor(n * w)
        r = frac.sum()
        sd = np.sqrt(r * (frac / r) * (1 - frac / r) / runs)
        assert (np.abs(counts.mean(0) - n * w) < 5 * sd + 1e-9).all()
    if scheme == "auxiliary":
        a = (w + 1.0 / n) / 2.0  # ((α−1)w + 1/N)/α with α = 2
        sd = np.sqrt(n * a * (1 - a) / runs)
        assert (np.abs(counts.mean(0) - n * a) < 5 * sd).all()
    # the weighted particle measure is preserved in expectation: E[Σ new weight of i] = wᵢ
    if scheme != "deterministic":
        np.testing.assert_allclose(mass.mean(0), w, atol=0.02 if scheme == "auxiliary" else 0.01)
