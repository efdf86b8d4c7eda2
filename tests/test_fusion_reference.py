"""Every estimator pinned to its stored output on a fixed short signal (6-D and 9-D).

The references and the signal are in ``tests/data/fusion_reference.npz``; how they were made and
when regenerating them is legitimate: ``tests/regen_fusion_reference.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from regen_fusion_reference import PATH, key, pinned, run

TOL = 1e-10  # absolute, per quaternion component


@pytest.fixture(scope="module")
def stored() -> dict[str, np.ndarray]:
    with np.load(PATH) as data:
        return dict(data)


def test_reference_file_is_small():
    assert PATH.stat().st_size < 200_000


def test_every_estimator_is_pinned(stored):
    names = pinned()
    assert len(names) >= 10
    missing = [key(n, d) for n in names for d in (6, 9) if key(n, d) not in stored]
    assert not missing, f"no reference for {missing}: see tests/regen_fusion_reference.py"
    outputs = {k for k in stored if k not in ("gyr", "acc", "mag")}
    stale = outputs - {key(n, d) for n in names for d in (6, 9)}
    assert not stale, f"references of estimators no longer registered: {sorted(stale)}"


@pytest.mark.parametrize("dims", [6, 9])
@pytest.mark.parametrize("name", pinned())
def test_output_matches_reference(stored, name, dims):
    quat = run(name, stored, dims)
    ref = stored[key(name, dims)]
    assert quat.shape == ref.shape
    worst = np.abs(quat - ref).max()
    assert worst <= TOL, f"{name} {dims}-D differs from its reference by {worst:.3g}"
