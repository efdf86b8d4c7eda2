"""A walk-calibrated knee's ab/adduction and rotation are graded by the flexion its axis'
uncertainty can carry into them, ``excursion × sin(√(witness² + AXIS_FLOOR_DEG²))``
(:mod:`motionlab.segments.grades`), the two estimates' disagreement and their shared offset from
the knee's own axis being independent."""

import numpy as np
import pytest

from motionlab.results import HingeFit
from motionlab.segments.grades import AXIS_FLOOR_DEG, _crosstalk_grade


def _fit(witness_deg: float, excursion_deg: float) -> HingeFit:
    z = np.array([0.0, 0.0, 1.0])
    return HingeFit("knee_r", z, z, 0.0, 0.0, 0.0, "measured", "anatomy", (excursion_deg, 0.0),
                    method="principal", witness_deg=witness_deg)  # fmt: skip


@pytest.mark.parametrize(
    ("witness", "excursion", "grade", "known"),
    [
        # 30 sin(√(2² + 5²) = 5.39°) = 2.82°: determined
        (2.0, 30.0, "determined", None),
        # 60 sin(5°) = 5.23°: weak, the floor alone
        (0.0, 60.0, "weak", 5),
        # 60 sin(√(3² + 5²) = 5.83°) = 6.09°: not determined (the larger alone, 5°, said weak)
        (3.0, 60.0, "not determined", 6),
        # the real 16-IMU walk's right knee: 103 sin(√(4.7² + 5²) = 6.86°) = 12.3°
        (4.7, 103.0, "not determined", 7),
    ],
)
def test_the_axis_uncertainty_adds_the_witness_and_the_floor_in_quadrature(
    witness, excursion, grade, known
):
    assert AXIS_FLOOR_DEG == 5.0
    g, reason = _crosstalk_grade(_fit(witness, excursion))
    assert g == grade
    if known is not None:
        assert f"known to {known}°" in reason
        carried = excursion * np.sin(np.radians(np.hypot(witness, 5.0)))
        assert f"can carry {carried:.0f}°" in reason


def test_an_unknown_witness_leaves_the_angles_not_determined():
    g, reason = _crosstalk_grade(_fit(float("nan"), 60.0))
    assert g == "not determined" and "unknown" in reason
