"""BROAD error definitions on hand-made orientation pairs."""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.validation.orientation_error import error_angles, orientation_errors


def test_pure_heading_and_pure_inclination_errors():
    ref = rot.normalize(np.random.default_rng(1).normal(size=(10, 4)))
    yaw = rot.mul(rot.from_axis_angle([0, 0, 1.0], np.deg2rad(10.0)), ref)
    tilt = rot.mul(rot.from_axis_angle([1.0, 1.0, 0], np.deg2rad(4.0)), ref)
    a = error_angles(yaw, ref)
    np.testing.assert_allclose(a["total"], 10.0)
    np.testing.assert_allclose(a["heading"], 10.0)
    np.testing.assert_allclose(a["inclination"], 0.0, atol=1e-5)  # acos near 1
    b = error_angles(-tilt, ref)  # the sign of a quaternion does not matter
    np.testing.assert_allclose(b["inclination"], 4.0)
    np.testing.assert_allclose(b["heading"], 0.0, atol=1e-9)


def test_rmse_mask_and_nan_reference():
    ref = np.tile([1.0, 0, 0, 0], (4, 1))
    est = rot.from_axis_angle([0, 0, 1.0], np.deg2rad([3.0, 4.0, 50.0, 0.0]))
    ref[3] = np.nan
    out = orientation_errors(est, ref, mask=np.array([True, True, False, True]))
    assert out["n_samples"] == 2
    assert out["total_rmse_deg"] == pytest.approx(np.sqrt((9 + 16) / 2))
    assert out["heading_rmse_deg"] == pytest.approx(np.sqrt((9 + 16) / 2))
    assert out["median_deg"] == pytest.approx(3.5)
    with pytest.raises(InputError):
        orientation_errors(est, ref, mask=np.zeros(4, bool))
