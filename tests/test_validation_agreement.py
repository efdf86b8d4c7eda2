"""Agreement statistics checked against numbers computed by hand."""

import numpy as np
import pytest

from motionlab.kinematics.cycles import Cycles
from motionlab.validation.agreement import agreement, cmc, per_repetition


def test_statistics_of_a_hand_made_error():
    ref = np.array([10.0, 20.0, 30.0, 40.0, np.nan])
    est = ref + np.array([1.0, -1.0, 2.0, 0.0, 5.0])  # d = 1, -1, 2, 0 (last sample skipped)
    a = agreement(est, ref)
    sd = np.sqrt(5.0 / 3.0)  # deviations from 0.5: .5, 1.5, 1.5, .5
    assert a["n_samples"] == 4
    assert a["bias_deg"] == pytest.approx(0.5)
    assert a["rmse_deg"] == pytest.approx(np.sqrt(6.0 / 4.0))
    assert a["sd_deg"] == pytest.approx(sd)
    assert a["rmse_centred_deg"] == pytest.approx(np.sqrt(5.0 / 4.0))
    assert a["max_abs_deg"] == 2.0
    assert a["loa_deg"] == pytest.approx([0.5 - 1.96 * sd, 0.5 + 1.96 * sd])
    assert a["r"] == pytest.approx(np.corrcoef(est[:4], ref[:4])[0, 1])
    masked = agreement(est, ref, mask=np.array([True, True, False, False, True]))
    assert masked["n_samples"] == 2 and masked["bias_deg"] == 0.0
    assert np.isnan(agreement(est[:1], ref[:1])["rmse_deg"])


def test_cmc_by_hand():
    # two systems, three frames: y1 = 0,1,2 and y2 = 1,2,3. Within-frame variance
    # Σ(y - ȳ_f)² / (F (G-1)) = 6·0.25 / 3 = 0.5; total Σ(y - ȳ)² / (GF - 1) = 5.5 / 5 = 1.1.
    assert cmc(np.array([[0.0, 1, 2], [1, 2, 3]])) == pytest.approx(np.sqrt(1 - 0.5 / 1.1))
    assert cmc(np.array([[0.0, 1, 2], [0, 1, 2]])) == pytest.approx(1.0)
    assert np.isnan(cmc(np.array([[0.0, 1], [1, 0]])))  # ratio 1.5 > 1: undefined
    two_cycles = np.stack([[[0.0, 1, 2], [1, 2, 3]], [[5.0, 6, 7], [6, 7, 8]]])
    assert cmc(two_cycles) == pytest.approx(np.sqrt(1 - 0.5 / 1.1))  # cycle means removed


def test_per_repetition():
    t = np.arange(40) / 10.0
    ref = 30.0 * np.abs(np.sin(np.pi * t / 2))  # repetitions of 2 s
    est = ref * 1.1 + 1.0
    reps = Cycles(np.array([0, 20]), np.array([10, 30]), np.array([19, 39]))
    out = per_repetition(est, ref, reps, t)
    assert out["n"] == 2
    np.testing.assert_allclose(out["start_s"], [0.0, 2.0])
    np.testing.assert_allclose(out["bias_deg"], 0.1 * ref[:20].mean() + 1.0)
    np.testing.assert_allclose(out["rom_error_deg"], 0.1 * np.ptp(ref[:20]))
    np.testing.assert_allclose(out["peak_error_deg"], 0.1 * 30.0 + 1.0)
    assert 0.9 < out["cmc"] < 1.0


def test_an_angle_wrapping_at_180_in_one_system_only_is_no_360_error():
    """A real rig's ball joint: the optical angle wrapped from +180° to -180° where the IMU's
    went on to 185°: two such samples read a largest error of 352° and doubled the RMSE. The
    curves are compared on one branch: the errors are the 1° they are."""
    from motionlab.validation import angle_agreement

    t = np.arange(0, 10, 0.01)
    true = 150 + 40 * np.sin(2 * np.pi * 0.5 * t)  # 110-190°: crosses 180° each cycle
    ref = (true + 180) % 360 - 180  # wraps to -180 ... -170
    imu = true + 1.0  # never wraps, 1° off
    imu[::97] = np.nan
    a = angle_agreement(imu, ref, None)
    assert a.max_abs_deg == pytest.approx(1.0, abs=1e-9)
    assert a.rmse_deg == pytest.approx(1.0, abs=1e-9) and a.bias_deg == pytest.approx(1.0)
    assert a.r == pytest.approx(1.0)
    assert np.nanmax(a.ref_deg) - np.nanmin(a.ref_deg) == pytest.approx(80.0, abs=0.01)
    assert np.isnan(a.imu_deg[::97]).all()
