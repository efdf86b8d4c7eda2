"""Calibration quality per segment, in numbers and in plain instructions for the operator.

Reliability ρ of each axis (Ricci 2015 eq. 6.2) is compared with the protocol's ``reference_rho``
(for the children's protocol: Tab. 6.1, 40 children) or with a default; the fitted frame's
residual angle per axis (eq. 6.18), the smallest angle between axes that should be orthogonal,
the agreement of the closed-form fit with Ricci's LM, and, for a knee or elbow flexion, the angle
between the SVD axis and Seel's hinge axis are checked.
"""

from __future__ import annotations

from motionlab.results import AxisMeasurement, SegmentQuality

STATIC_RHO_MIN = 0.95
FUNCTIONAL_RHO_MIN = 0.60
RHO_MARGIN = 0.10  # below the reference by more than this: flagged
RESIDUAL_MAX_DEG = 15.0
SEPARATION_MIN_DEG = 45.0
HINGE_CHECK_MAX_DEG = 10.0


def assess(
    segment: str,
    axes: list[AxisMeasurement],
    separation_deg: float | None,
    lm_difference_deg: float | None,
) -> SegmentQuality:
    """Quality record of one segment.

    ``axes`` are the segment's measured axes (:func:`motionlab.segments.mounting.measure`).
    Returns the :class:`~motionlab.results.SegmentQuality`.
    """
    messages = []
    for a in axes:
        floor = STATIC_RHO_MIN if a.kind == "static" else FUNCTIONAL_RHO_MIN
        ref = a.reference_rho
        if ref is not None:
            floor = ref - RHO_MARGIN
        if a.rho < floor:
            why = (
                "the segment was not still"
                if a.kind == "static"
                else ("the movement was not planar enough")
            )
            expect = f"expected about {ref:.2f}" if ref is not None else f"want ≥ {floor:.2f}"
            messages.append(
                f"{segment}: repeat the {a.step.replace('_', ' ')}: {why} "
                f"(ρ = {a.rho:.2f}, {expect})"
            )
        if a.hinge_check_deg is not None and a.hinge_check_deg > HINGE_CHECK_MAX_DEG:
            messages.append(
                f"{segment}: repeat the {a.step.replace('_', ' ')}: its axis differs from "
                f"the hinge-joint fit by {a.hinge_check_deg:.0f}° (the movement was not "
                "about one axis, or the upper segment moved)"
            )
        if a.residual_deg is not None and a.residual_deg > RESIDUAL_MAX_DEG:
            messages.append(
                f"{segment}: the axis from {a.step} is {a.residual_deg:.0f}° off the "
                "fitted frame: check the movement was about the instructed axis and the sensor "
                "did not slip"
            )
    if separation_deg is not None and separation_deg < SEPARATION_MIN_DEG:
        messages.append(
            f"{segment}: two calibration axes are only {separation_deg:.0f}° apart, so the "
            "frame is poorly fixed: check the sensor placement and repeat the movements as "
            "instructed"
        )
    if lm_difference_deg is not None and lm_difference_deg > 1.0:
        messages.append(
            f"{segment}: the LM check differs from the closed-form fit by "
            f"{lm_difference_deg:.1f}°: the axes are inconsistent"
        )
    return SegmentQuality(
        ok=not messages,
        messages=messages,
        min_rho=min((a.rho for a in axes), default=float("nan")),
        separation_deg=separation_deg,
        lm_difference_deg=lm_difference_deg,
        hinge_check_deg={a.step: a.hinge_check_deg for a in axes if a.hinge_check_deg is not None},
    )
