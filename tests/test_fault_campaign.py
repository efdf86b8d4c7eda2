"""Our own fault campaign (issue 16), a representative subset: every reader's fixture broken
(truncated, bytes flipped, NaN/inf/1e308 values, columns deleted or added, delimiters and
encodings swapped), HDF5 attributes and datasets of the wrong type or damaged, BROAD, APDM .h5
and session files truncated or byte-flipped, every protocol and sensor-map key given a wrong
type. Each run keeps the promise: exit 0, or exit 2 with one
line on stderr; no traceback; inputs byte-identical; no output or temporary file left.

The cases are drawn with a fixed seed (reproducible in CI); ``bench/faults.py`` runs hundreds.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
import faults  # noqa: E402

CLEAN = ("ok", "refused")


def test_campaign_subset_keeps_the_promise(tmp_path, monkeypatch):
    from motionlab import isolated

    if hasattr(os, "fork"):  # guards on, even with a thread left running by an earlier test
        monkeypatch.setattr(isolated, "can_isolate", lambda: True)
    cases = faults.campaign(tmp_path / "make", seed=16, n_text=12, n_h5=6, n_session=12)
    assert len(cases) >= 100
    verdicts = [faults.run_case(c, tmp_path / f"c{i}") for i, c in enumerate(cases)]
    broken = [v for v in verdicts if v.verdict not in CLEAN]
    assert not broken, "\n" + faults.table(verdicts) + "\n".join(map(str, broken[:10]))
    assert sum(v.verdict == "refused" for v in verdicts) > 50  # the damage is seen


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(
    reader=st.sampled_from(faults.TEXT_READERS),
    offset=st.integers(0, 1 << 20),
    mask=st.integers(1, 255),
    cut=st.floats(0.0, 1.0),
)
def test_any_flip_and_cut_of_a_text_fixture(tmp_path, reader, offset, mask, cut):
    data = faults.FIXTURES[reader].read_bytes()
    mutated = faults.truncate(faults.flip(data, offset, mask), cut)
    folder = tmp_path / f"{reader}-{offset}-{mask}-{cut:.6f}"
    v = faults.run_case(faults.ingest_case("hyp", reader, mutated), folder)
    assert v.verdict in CLEAN, v


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(
    reader=st.sampled_from(faults.TEXT_READERS),
    k=st.integers(0, 10_000),
    value=st.sampled_from([b"nan", b"inf", b"-inf", b"1e308", b"-1e308", b"1e-320", b""]),
)
def test_any_cell_replaced_by_an_odd_number(tmp_path, reader, k, value):
    data = faults.replace_number(faults.FIXTURES[reader].read_bytes(), k, value)
    v = faults.run_case(
        faults.ingest_case("hyp", reader, data), tmp_path / f"{reader}-{k}-{value!r}"
    )
    assert v.verdict in CLEAN, v


@pytest.mark.parametrize("how", faults.H5_MUTATIONS)
def test_broad_type_swaps_and_damage(tmp_path, how):
    data = faults.h5_mutate(faults.FIXTURES["broad"].read_bytes(), how, tmp_path)
    v = faults.run_case(faults.ingest_case(how, "broad", data), tmp_path / "run")
    assert v.verdict in CLEAN, v
    if how.startswith(("rate_", "strings:", "shape:", "drop:")) or how == "compressed_then_damaged":
        assert v.verdict == "refused", v


@pytest.mark.parametrize("case", faults.yaml_cases(), ids=lambda c: c.name)
def test_every_yaml_key_with_a_wrong_type_is_refused_with_its_place(tmp_path, case):
    v = faults.run_case(case, tmp_path / "run")
    assert v.verdict == "refused", v
    assert ".yaml" in v.stderr or "in.txt" in v.stderr, v


def test_the_value_of_a_replaced_cell_is_the_one_asked_for():
    data = b"a,b\n1.5,2.5\n"
    assert faults.replace_number(data, 1, b"nan") == b"a,b\n1.5,nan\n"
    assert np.isclose(len(faults.truncate(data, 0.5)), len(data) // 2)


def test_broken_ximu3_exports_keep_the_promise(tmp_path):
    cases = faults.ximu3_cases(np.random.default_rng(28), 34)
    verdicts = [faults.run_case(c, tmp_path / f"c{i}") for i, c in enumerate(cases)]
    broken = [v for v in verdicts if v.verdict not in CLEAN]
    assert not broken, "\n" + faults.table(verdicts) + "\n".join(map(str, broken[:10]))
    assert sum(v.verdict == "refused" for v in verdicts) > 10
