"""The relative sign of a knee's two axes: where the rates give it wrong, anatomy (the knee flexes
one way from its straight stand) overrules them (:func:`motionlab.segments.movement.signed_axes`).
"""

import numpy as np
import pytest

from motionlab import rotations as rot
from motionlab.segments import movement

J = np.array([0.0, 1.0, 0.0])


def _knee() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A stand (0-3 s), then a thigh swinging ±20° and a knee flexing 0-60° about ``J``."""
    t = np.arange(0.0, 20.0, 0.01)
    walking = t >= 3.0
    phase = 2.0 * np.pi * (t - 3.0) / 1.1
    flexion = np.where(walking, np.radians(30.0) * (1.0 - np.cos(phase)), 0.0)
    swing = np.where(walking, np.radians(20.0) * np.sin(phase), 0.0)
    q_p = rot.from_rotvec(swing[:, None] * J)
    return t, q_p, rot.mul(q_p, rot.from_rotvec(flexion[:, None] * J))


@pytest.mark.parametrize("rates_say", [1.0, -1.0])
def test_anatomy_overrules_a_wrong_relative_sign_from_the_rates(monkeypatch, rates_say):
    t, q_p, q_d = _knee()
    monkeypatch.setattr(movement, "relative_sign", lambda *a: (rates_say, 0.9))
    monkeypatch.setattr(movement, "swing_sign", lambda *a: (rates_say, 0.0))
    reasons: list[str] = []
    j_p, j_d, rel, sign, excursion = movement.signed_axes(
        t, q_p, q_d, J, J, J, J, np.ones(len(t), bool), (0.5, 2.5), True, reasons
    )
    assert j_p @ j_d == pytest.approx(1.0)  # the same axis, the same way round
    assert rel == ("measured" if rates_say > 0 else "anatomy")
    assert sign == "anatomy" and j_p @ J == pytest.approx(1.0)  # flexion positive
    assert excursion[0] == pytest.approx(60.0, abs=0.5) and excursion[1] < 0.5
    assert reasons == []


@pytest.mark.parametrize("placement_says", [1.0, -1.0])
def test_anatomy_signs_the_axes_when_the_rates_cannot(monkeypatch, placement_says):
    """Rates that do not tell (margin 0): the nominal placement's guess is confirmed or
    overruled by the anatomy, and either way the relative sign counts as measured, not
    hinted (a real 14-s walk was graded weak for a guess the anatomy had confirmed)."""
    t, q_p, q_d = _knee()
    monkeypatch.setattr(movement, "relative_sign", lambda *a: (1.0, 0.0))
    monkeypatch.setattr(movement, "swing_sign", lambda *a: (1.0, 0.0))
    reasons: list[str] = []
    j_p, j_d, rel, sign, excursion = movement.signed_axes(
        t, q_p, q_d, J, J, J, placement_says * J, np.ones(len(t), bool), (0.5, 2.5), True,
        reasons,
    )  # fmt: skip
    assert j_p @ j_d == pytest.approx(1.0) and j_p @ J == pytest.approx(1.0)
    assert (rel, sign) == ("anatomy", "anatomy")
    assert excursion[0] == pytest.approx(60.0, abs=0.5) and excursion[1] < 0.5
    assert reasons == []


def test_without_a_stand_the_placement_guess_stays_a_hint(monkeypatch):
    t, q_p, q_d = _knee()
    monkeypatch.setattr(movement, "relative_sign", lambda *a: (1.0, 0.0))
    monkeypatch.setattr(movement, "swing_sign", lambda *a: (1.0, 0.0))
    reasons: list[str] = []
    *_, rel, sign, _ = movement.signed_axes(
        t, q_p, q_d, J, J, J, J, np.ones(len(t), bool), None, True, reasons
    )
    assert (rel, sign) == ("nominal", "nominal")
    assert reasons[0].startswith(movement.NOMINAL_DISTAL)
