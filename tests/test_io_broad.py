"""BROAD benchmark reader: IMU stream + optical reference on one timebase."""

import h5py
import numpy as np
import pytest
from conftest import DATA, SHARED, assert_other_hdf5_refused, needs_shared

from motionlab.errors import InputError
from motionlab.io import broad, detect_format, read_any

EXCERPT = DATA / "broad" / "broad_10_excerpt.hdf5"
RATE = 285.7142857142857


def test_excerpt():
    assert detect_format(EXCERPT) == "broad"
    rec = read_any(EXCERPT)
    (imu,) = rec.sensors
    (opt,) = rec.markers
    with h5py.File(EXCERPT) as f:
        raw = {k: f[k][()] for k in f}
    assert imu.label == "imu" and imu.n_samples == 285
    assert imu.rate_hz == pytest.approx(RATE, rel=1e-9)
    np.testing.assert_array_equal(imu.time, np.arange(285) / RATE)
    np.testing.assert_array_equal(opt.time, imu.time)
    np.testing.assert_array_equal(imu.acc, raw["imu_acc"])
    np.testing.assert_array_equal(imu.gyr, raw["imu_gyr"])
    np.testing.assert_array_equal(imu.mag, raw["imu_mag"])
    assert imu.extra["movement"].dtype == bool and imu.extra["movement"].all()
    assert imu.source_units["gyr"] == "rad/s" and imu.quat is None
    assert opt.labels == ["imu_origin"] and opt.positions.shape == (285, 1, 3)
    np.testing.assert_array_equal(opt.positions[:, 0], raw["opt_pos"])
    q = opt.rigid_bodies["imu"]
    occluded = np.isnan(q).any(axis=1)
    assert occluded.sum() == 26 and np.isnan(q[occluded]).all()
    np.testing.assert_allclose(np.linalg.norm(q[~occluded], axis=1), 1.0, atol=1e-9)
    assert opt.attrs["earth_frame"] == "ENU"
    assert rec.metadata["licence"] == "CC BY 4.0"


def _copy_without(tmp_path, drop=None, drop_attr=None):
    path = tmp_path / "trial.hdf5"
    with h5py.File(EXCERPT) as src, h5py.File(path, "w") as dst:
        for k in src:
            if k != drop:
                dst[k] = src[k][()]
        for k, v in src.attrs.items():
            if k != drop_attr:
                dst.attrs[k] = v
    return path


def test_errors(tmp_path):
    with pytest.raises(InputError, match="key /imu_acc"):
        broad.read(_copy_without(tmp_path, drop="imu_acc"))
    with pytest.raises(InputError, match="key /sampling_rate"):
        broad.read(_copy_without(tmp_path, drop_attr="sampling_rate"))
    path = _copy_without(tmp_path, drop="opt_pos")
    with h5py.File(path, "a") as f:
        f["opt_pos"] = np.zeros((100, 3))
    with pytest.raises(InputError, match="100 samples but imu_gyr has 285"):
        broad.read(path)
    assert_other_hdf5_refused(tmp_path / "other.hdf5", broad, "key /sampling_rate")


@needs_shared
@pytest.mark.skipif(not (SHARED / "datasets" / "broad").is_dir(), reason="no BROAD trials")
def test_shared_trials():
    files = sorted((SHARED / "datasets" / "broad").glob("*.hdf5"))
    assert files
    for path in files:
        rec = broad.read(path)
        imu, opt = rec.sensors[0], rec.markers[0]
        assert imu.rate_hz == pytest.approx(RATE, rel=1e-9)
        assert imu.n_samples > 40000 and len(opt.time) == imu.n_samples
        q = opt.rigid_bodies["imu"]
        seen = ~np.isnan(q).any(axis=1)
        assert 0.9 < seen.mean() < 1.0
        np.testing.assert_allclose(np.linalg.norm(q[seen], axis=1), 1.0, atol=1e-6)
        # at rest before the movement starts the IMU feels gravity: |acc| ≈ 9.81 m/s²
        still = ~imu.extra["movement"]
        assert np.median(np.linalg.norm(imu.acc[still], axis=1)) == pytest.approx(9.81, abs=0.3)
