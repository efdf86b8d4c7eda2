"""Optical frames: rigid fit on hand-made poses, gaps, angular velocity, anatomical frames."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.validation.anatomy import RECIPES, anatomical_frame, resolve_name, two_axis_frame
from motionlab.validation.optical import (
    cluster_shape,
    fill_gaps,
    resample_quat,
    rigid_fit,
    smooth_pose,
    track_cluster,
)

SHAPE = np.array([[0.04, 0.03, 0.0], [-0.04, 0.03, 0.0], [-0.05, -0.03, 0.0], [0.04, -0.02, 0.0]])


def _pose(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rot.normalize(rng.normal(size=(n, 4))), rng.uniform(-1, 1, (n, 3))


def test_rigid_fit_recovers_a_hand_made_pose_with_three_or_more_markers():
    q, t = _pose(4)
    pts = rot.rotate(q[:, None], SHAPE) + t[:, None]
    pts[1, 0] = np.nan  # three markers left
    pts[2, :2] = np.nan  # two markers left: no fit
    pts[3, 3] = pts[3, 0] + 2 * (pts[3, 1] - pts[3, 0])  # marker 4 moved onto the line 1-2 …
    pts[3, 2] = np.nan  # … and 3 hidden: the three usable markers are collinear
    q_fit, t_fit, res = rigid_fit(SHAPE, pts)
    assert np.degrees(rot.angle_between(q_fit[:2], q[:2])).max() < 1e-9
    np.testing.assert_allclose(t_fit[:2], t[:2] - 0.0, atol=1e-12)  # SHAPE centroid at origin…
    assert np.isnan(q_fit[2]).all() and np.isnan(res[2])
    assert np.isnan(q_fit[3]).all()
    assert res[0] < 1e-12


def test_rigid_fit_cross_covariance_is_the_masked_einsum():
    """The compiled centroids and cross-covariance of the seen markers are numpy's masked
    formulation (centroids to the bit: the mask's weights are 0 and 1)."""
    from motionlab.validation._kernels import cross_covariance

    q, t = _pose(500, seed=3)
    pts = rot.rotate(q[:, None], SHAPE) + t[:, None]
    pts += np.random.default_rng(4).normal(0.0, 1e-3, pts.shape)
    pts[np.random.default_rng(5).random(pts.shape[:2]) < 0.2] = np.nan
    ok = np.isfinite(pts).all(axis=-1)
    w = ok.astype(float)
    denom = np.maximum(w.sum(axis=1), 1.0)[:, None]
    p = np.where(ok[..., None], pts, 0.0)
    cp = np.einsum("nk,nkj->nj", w, p) / denom
    cs = (w @ SHAPE) / denom
    h = np.einsum("nki,nkj->nij", SHAPE[None] - cs[:, None], (p - cp[:, None]) * w[..., None])
    out = np.empty((500, 3)), np.empty((500, 3)), np.empty((500, 3, 3))
    cross_covariance(SHAPE, pts, ok, *out)
    np.testing.assert_array_equal(out[0], cp)
    np.testing.assert_array_equal(out[1], cs)
    np.testing.assert_allclose(out[2], h, rtol=0, atol=1e-18)


def test_rigid_fit_residual_of_a_saddle_is_its_height():
    a, d = 0.05, 0.002
    shape = np.array([[a, a, 0], [-a, -a, 0], [a, -a, 0], [-a, a, 0]])
    pts = shape + np.array([[0, 0, d], [0, 0, d], [0, 0, -d], [0, 0, -d]])
    q, t, res = rigid_fit(shape, pts[None])
    assert res[0] == pytest.approx(d)  # no rotation can fit a saddle: the best is none
    assert np.degrees(rot.angle(q[0])) < 1e-9


def test_cluster_shape_is_rigid_centred_and_in_principal_axes():
    q, t = _pose(200, 1)
    pts = rot.rotate(q[:, None], SHAPE + 0.3) + t[:, None]
    pts[::3, 1] = np.nan
    shape = cluster_shape(pts)
    d_true = np.linalg.norm(SHAPE[:, None] - SHAPE[None], axis=-1)
    d_est = np.linalg.norm(shape[:, None] - shape[None], axis=-1)
    np.testing.assert_allclose(d_est, d_true, atol=1e-12)
    np.testing.assert_allclose(shape.mean(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(shape[:, 2], 0.0, atol=1e-12)  # planar: z is the normal
    assert np.ptp(shape[:, 0]) >= np.ptp(shape[:, 1])
    with pytest.raises(InputError):
        cluster_shape(np.full((5, 4, 3), np.nan))


def test_short_gaps_are_slerped_long_ones_flagged():
    t = np.arange(20) / 100.0
    q = rot.from_axis_angle([0, 0, 1.0], np.radians(2.0 * np.arange(20)))
    o = np.zeros((20, 3))
    q[[0, 5, 6]] = np.nan
    q[10:16] = np.nan
    filled, _, interp, flagged = fill_gaps(t, q, o, max_gap_s=0.05)
    np.testing.assert_allclose(np.degrees(rot.angle(filled[[5, 6]])), [10.0, 12.0], atol=1e-9)
    assert interp.tolist() == [i in (5, 6) for i in range(20)]
    assert flagged.tolist() == [i == 0 or 10 <= i < 16 for i in range(20)]
    assert np.isnan(filled[10:16]).all()


def test_track_cluster_follows_a_rotating_cluster_through_occlusions():
    t = np.arange(600) / 120.0
    q = rot.integrate_gyro(rot.IDENTITY, np.tile([1.0, 2.0, -0.5], (600, 1)), 1 / 120.0)
    pts = rot.rotate(q[:, None], SHAPE) + np.array([0.5, 0.2, 1.0])
    pts[100:130, 0] = np.nan  # one marker hidden: three remain
    pts[300:304, :2] = np.nan  # two hidden for 4 frames: a short gap
    pts[400:460, 1:3] = np.nan  # a long gap
    rng = np.random.default_rng(2)
    track = track_cluster(t, pts + rng.normal(0, 1e-4, pts.shape), lowpass_hz=0)
    ok = np.isfinite(track.quat).all(axis=1)
    rel = rot.mean(rot.mul(rot.conj(q[ok]), track.quat[ok]))  # shape frame in cluster frame
    err = np.degrees(rot.angle_between(rot.mul(q, rel), track.quat))
    assert np.sqrt(np.nanmean(err**2)) < 0.2 and np.nanmax(err) < 1.0  # 0.1 mm noise, 4-8 cm
    assert track.interpolated[300:304].all() and track.flagged[400:460].all()
    s = track.summary()
    assert s["n_long_gaps"] == 1 and s["residual_rms_mm"] == pytest.approx(0.15, abs=0.05)


def test_angular_velocity_of_a_constant_rotation():
    omega = np.array([0.3, -1.2, 2.0])
    t = np.cumsum(np.r_[0, np.full(49, 0.01), 0.02, np.full(49, 0.01)])  # uneven steps
    q = rot.mul(rot.from_axis_angle([1.0, 0, 0], 0.4), rot.from_rotvec(t[:, None] * omega))
    t_mid, w = rot.angular_velocity(t, q)
    np.testing.assert_allclose(w, np.tile(omega, (99, 1)), atol=1e-9)
    np.testing.assert_allclose(t_mid, 0.5 * (t[1:] + t[:-1]))


def test_resample_quat_keeps_samples_and_respects_gaps():
    t = np.arange(6.0)
    q = rot.from_axis_angle([0, 0, 1.0], np.radians(10.0 * t))
    q[3] = np.nan
    out = resample_quat(t, q, np.array([0.5, 2.0, 2.5, 4.0, 4.5, 5.0, 6.0]))
    np.testing.assert_allclose(np.degrees(rot.angle(out[[0, 1, 3, 4, 5]])), [5, 20, 40, 45, 50])
    assert np.isnan(out[[2, 6]]).all()


def test_smooth_pose_removes_noise_and_keeps_the_movement():
    t = np.arange(1200) / 120.0
    q = rot.from_axis_angle([0, 1.0, 0], np.radians(30.0) * np.sin(2 * np.pi * t))
    noisy = rot.mul(q, rot.from_rotvec(np.random.default_rng(3).normal(0, 0.01, (1200, 3))))
    o = np.zeros((1200, 3))
    smooth, _ = smooth_pose(t, noisy, o, 10.0)
    before = np.degrees(rot.angle_between(noisy, q))
    after = np.degrees(rot.angle_between(smooth, q))
    assert np.sqrt(np.mean(after**2)) < 0.5 * np.sqrt(np.mean(before**2))
    assert np.sqrt(np.mean(after[100:-100] ** 2)) < 0.5


@pytest.mark.parametrize(
    "name, expected",
    [("RLHE", ("LE", "r")), ("LASI", ("ASIS", "l")), ("LE", ("LE", "")), ("LLM", ("LM", "l")),
     ("R_ME", ("ME", "r")), ("US_l", ("US", "l")), ("T8", ("T8", "")), ("L1", ("L1", "")),
     ("RTT", ("TT", "r")), ("RTHI", ("RTHI", ""))],
)  # fmt: skip
def test_landmark_names(name, expected):
    assert resolve_name(name) == expected


def test_two_axis_frame_is_right_handed_for_every_axis_pair():
    rng = np.random.default_rng(4)
    for a1 in "xyz":
        for a2 in "xyz":
            if a1 == a2:
                continue
            m = two_axis_frame(a1, rng.normal(size=3), a2, rng.normal(size=3))
            np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-12)
            assert np.linalg.det(m) == pytest.approx(1.0)


def test_thigh_frames_on_both_sides_ignore_the_trochanter_offset():
    r = rot.to_matrix(rot.from_axis_angle([1.0, 2.0, 3.0], 0.7))
    right = {"RGT": [0.0, 0.42, 0.08], "RLE": [0, 0, 0.05], "RME": [0, 0, -0.05]}
    m, used = anatomical_frame(RECIPES["thigh"], {k: r @ v for k, v in right.items()}, "r")
    np.testing.assert_allclose(m, r, atol=1e-12)
    assert used == ["GT", "LE", "ME"]
    left = {"LGT": [0, 0.42, -0.08], "LLE": [0, 0, -0.05], "LME": [0, 0, 0.05]}
    m, _ = anatomical_frame(RECIPES["thigh"], left, "l")
    np.testing.assert_allclose(m, np.eye(3), atol=1e-12)
    assert anatomical_frame(RECIPES["thigh"], {"RLE": [0, 0, 0.05]}, "r") is None


def test_pelvis_frame_from_the_spines():
    pts = {"LASI": [0.03, 0, -0.12], "RASI": [0.03, 0, 0.12], "LPSI": [-0.1, 0, -0.04],
           "RPSI": [-0.1, 0, 0.04]}  # fmt: skip
    m, _ = anatomical_frame(RECIPES["pelvis"], pts)
    np.testing.assert_allclose(m, np.eye(3), atol=1e-12)
