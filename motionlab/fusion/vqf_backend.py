"""VQF (Laidig & Seel 2023) as a registered estimator, through the optional ``vqf`` package.

Install with ``pip install motionlab[vqf]``. Without the package this module fails to import with
``ModuleNotFoundError`` for ``vqf``, which the registry skips. Both VQF and motionlab use
sensor → ENU quaternions, scalar first, so outputs need no conversion.

Reference: D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation estimation with bias
estimation and magnetic disturbance rejection", Information Fusion 91 (2023) 187–204,
doi:10.1016/j.inffus.2022.10.014.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from vqf import VQF, offlineVQF

from motionlab import rotations as rot
from motionlab.fusion.registry import FusionResult, param, register


@dataclass
class VQFParams:
    tau_acc: float = param(3.0, "s", "time constant of the inclination correction")
    tau_mag: float = param(9.0, "s", "time constant of the heading correction")
    motion_bias_est: bool = param(True, "", "estimate the gyro bias during motion")
    rest_bias_est: bool = param(True, "", "estimate the gyro bias at rest")
    mag_dist_rejection: bool = param(True, "", "detect and reject magnetic disturbances")


def _vqf_params(p: VQFParams) -> dict:
    return {
        "tauAcc": p.tau_acc,
        "tauMag": p.tau_mag,
        "motionBiasEstEnabled": p.motion_bias_est,
        "restBiasEstEnabled": p.rest_bias_est,
        "magDistRejectionEnabled": p.mag_dist_rejection,
    }


def _result(out: dict, has_mag: bool) -> FusionResult:
    quat = out["quat9D"] if has_mag else out["quat6D"]
    return FusionResult(
        quat=rot.make_continuous(rot.normalize(quat)),
        name="",
        params={},
        gyro_bias=np.asarray(out["bias"]),
        rest=np.asarray(out["restDetected"], dtype=bool),
        mag_disturbed=np.asarray(out["magDistDetected"], dtype=bool) if has_mag else None,
    )


@register("vqf", VQFParams, "VQF online filter (optional 'vqf' package; reference)")
def run_online(gyr, acc, mag, rate, params: VQFParams) -> FusionResult:
    """VQF's online (causal) filter over the whole recording."""
    f = VQF(1.0 / rate, **_vqf_params(params))
    out = f.updateBatch(gyr, acc, mag) if mag is not None else f.updateBatch(gyr, acc)
    return _result(out, mag is not None)


@register("vqf_offline", VQFParams, "VQF offline (forward-backward) filter (optional 'vqf')")
def run_offline(gyr, acc, mag, rate, params: VQFParams) -> FusionResult:
    """VQF's offline variant (acausal, uses future samples)."""
    out = offlineVQF(gyr, acc, mag, 1.0 / rate, _vqf_params(params))
    return _result(out, mag is not None)
