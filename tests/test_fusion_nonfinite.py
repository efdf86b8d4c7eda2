"""Non-finite samples never spread silently through fusion (issue 16): a short run of NaN is
bridged and listed; a long run that reaches the fusion (ingest makes one of the accelerometer or
gyroscope a packet-loss gap), or an estimate that turns NaN, is refused with the sensor and the
time span (exit 2, one line) instead of written with exit 0."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fusion_signals import constant_rotation  # noqa: E402
from test_input_boundaries import cli, refused  # noqa: E402

from motionlab import rotations as rot  # noqa: E402
from motionlab import stages  # noqa: E402
from motionlab.errors import InputError  # noqa: E402
from motionlab.fusion.stage import NAN_BRIDGE_MAX_S, fuse_session  # noqa: E402
from motionlab.session import SensorStream, Session, load_session, save_session  # noqa: E402

RATE = 100.0


def session_with(edit=None, seconds: float = 10.0) -> Session:
    sig = constant_rotation(seconds=seconds, rate=RATE, seed=3)
    n = len(sig["gyr"])
    s = SensorStream(
        "shank_r", np.arange(n) / RATE, acc=sig["acc"].copy(), gyr=sig["gyr"].copy(),
        segment="shank", side="r",
    )  # fmt: skip
    if edit:
        edit(s)
    ses = Session(metadata={})
    ses.sensors[s.label] = s
    ses.truth = sig["quat"]  # type: ignore[attr-defined]
    return ses


def nan_rows(channel: str, start: int, stop: int):
    def edit(s: SensorStream) -> None:
        getattr(s, channel)[start:stop] = np.nan

    return edit


def test_a_short_nan_run_is_bridged_listed_and_the_orientation_stays_right():
    ses = session_with(nan_rows("gyr", 400, 405))  # 5 samples: 0.06 s from finite to finite
    entries = fuse_session(ses, "madgwick", magnetometer=False)
    assert list(entries) == ["shank_r"] and not ses.results.fusion  # stages.fuse stores them
    entry = entries["shank_r"]
    assert entry.nan_bridged_s == [[4.0, 4.04]]
    q = entry.quat
    assert np.isfinite(q).all()
    # held gyro over 0.05 s at ≤ 0.6 rad/s: the tilt stays within a few degrees of the truth
    truth = ses.truth  # type: ignore[attr-defined]
    up_est = rot.rotate(rot.conj(q), np.array([0.0, 0.0, 1.0]))
    up_true = rot.rotate(rot.conj(truth), np.array([0.0, 0.0, 1.0]))
    tilt = np.degrees(np.arccos(np.clip((up_est * up_true).sum(axis=1), -1, 1)))
    assert tilt[300:].max() < 5.0


def test_the_fuse_stage_stores_what_it_returns_and_notes_the_bridge():
    ses = session_with(nan_rows("gyr", 400, 405))
    out = stages.fuse(ses, "madgwick", magnetometer=False)
    assert list(out) == ["shank_r"] and out["shank_r"] is ses.results.fusion["shank_r"]
    notes = stages.fusion_notes(ses, list(out))
    assert notes == {"shank_r": "1 run(s) of non-finite samples bridged"}


def test_a_long_nan_run_is_refused_with_sensor_channel_and_span():
    ses = session_with(nan_rows("acc", 250, 400))  # 1.5 s
    with pytest.raises(InputError) as exc:
        fuse_session(ses, "madgwick", magnetometer=False, path="s.h5")
    line = exc.value.line()
    assert "sensor shank_r" in line and "acc not a number from 2.50 s to 3.99 s" in line, line
    assert "150 samples" in line and f"{NAN_BRIDGE_MAX_S:g} s" in line
    assert "shank_r" not in ses.results.fusion


def test_infinite_values_count_as_not_a_number():
    ses = session_with(nan_rows("gyr", 100, 101))
    ses.sensors["shank_r"].gyr[100] = np.inf
    entry = fuse_session(ses, "madgwick", magnetometer=False)["shank_r"]
    assert entry.nan_bridged_s == [[1.0, 1.0]]


def test_an_estimate_that_turns_nan_midway_is_refused_with_where_it_starts(monkeypatch):
    from motionlab.fusion import registry

    real = registry.estimate

    def diverging(*args, **kwargs):
        res = real(*args, **kwargs)
        res.quat[600:] = np.nan  # as a filter driven to NaN by an implausible spike
        return res

    monkeypatch.setattr(registry, "estimate", diverging)
    ses = session_with()
    with pytest.raises(InputError) as exc:
        fuse_session(ses, "madgwick", magnetometer=False, path="s.h5")
    assert "no finite orientation for 40.0 % of the samples, from 6.00 s on" in exc.value.line()


def test_cli_fuse_and_run_never_write_nan_orientations(tmp_path):
    """A session file's long NaN run in the gyroscope is the gap of the packets lost there
    (prepared as ingest does, tests/test_nan_span_gap.py): fused across, not refused, and no
    NaN orientation written; the 9-D fusion's magnetometer run is refused."""
    save_session(session_with(nan_rows("gyr", 200, 320)), tmp_path / "s.h5")
    before = (tmp_path / "s.h5").read_bytes()
    r = cli(tmp_path, "fuse", "s.h5", "-o", "gap.h5")
    assert r.exit_code == 0, r.output
    out = load_session(tmp_path / "gap.h5")
    assert out.sensors["shank_r"].qc["gaps"] == [[1.99, 3.2]]
    assert np.isfinite(out.results.fusion["shank_r"].quat).all()
    assert (tmp_path / "s.h5").read_bytes() == before

    def mag_nan(s: SensorStream) -> None:
        s.mag = np.tile([0.0, 20.0, -40.0], (len(s.time), 1))
        s.mag[200:320] = np.nan

    save_session(session_with(mag_nan), tmp_path / "m.h5")
    r = cli(tmp_path, "fuse", "m.h5", "--magnetometer", "-o", "o9.h5")
    refused(r, "m.h5 sensor shank_r: mag not a number", "fuse without the magnetometer")
    assert r.stdout == ""  # nothing ("fusing (…)") before the error
    assert not (tmp_path / "o9.h5").exists()
    save_session(session_with(nan_rows("gyr", 200, 203)), tmp_path / "b.h5")
    r = cli(tmp_path, "fuse", "b.h5", "-o", "o.h5")
    assert r.exit_code == 0, r.output
    assert "1 run(s) of non-finite samples bridged" in r.output
    q = load_session(tmp_path / "o.h5").results.fusion["shank_r"].quat
    assert np.isfinite(q).all()


def test_vendor_orientations_follow_the_same_rule(tmp_path):
    def with_quat(start: int, stop: int):
        def edit(s: SensorStream) -> None:
            s.quat = constant_rotation(seconds=10.0, rate=RATE, seed=3)["quat"].copy()
            s.quat[start:stop] = np.nan

        return edit

    ses = session_with(with_quat(500, 502))
    assert list(stages.fuse(ses, orientation="vendor")) == ["shank_r"]
    entry = ses.results.fusion["shank_r"]
    assert entry.name == "vendor" and entry.nan_bridged_s == [[5.0, 5.01]]
    assert np.isfinite(entry.quat).all()
    assert np.array_equal(entry.quat[500], entry.quat[499])  # the last one held
    save_session(session_with(with_quat(500, 700)), tmp_path / "v.h5")
    refused(cli(tmp_path, "fuse", "v.h5", "--orientation", "vendor", "-o", "o.h5"),
            "sensor shank_r: quat not a number from 5.00 s to 6.99 s")  # fmt: skip


@pytest.mark.parametrize("compiled, note", [(False, True), (True, False), (None, False)])
def test_the_first_fusion_after_installing_says_it_compiles(monkeypatch, compiled, note):
    """The default smoother's kernels take numba about half a minute to compile on the first
    run after installing: the progress line says so then, and only then (not when numba's cache
    has them, nor when it cannot be asked)."""
    from motionlab.fusion import _mekf_blocks

    monkeypatch.setattr(_mekf_blocks, "compiled", lambda: compiled)
    lines: list[str] = []

    def progress(labels, text):
        lines.append(text)
        return labels

    fuse_session(session_with(seconds=3.0), "smoother", magnetometer=False, progress=progress)
    assert lines[0].startswith("fusing (smoother, 6-D)")
    assert ("compiling it for this machine first" in lines[0]) is note
    fuse_session(session_with(seconds=3.0), "madgwick", magnetometer=False, progress=progress)
    assert "compiling" not in lines[1]  # other estimators compile in a second or two


def test_numba_is_asked_whether_the_smoother_is_compiled():
    """After a fusion with the smoother in this process its kernels are in numba's cache."""
    from motionlab.fusion import _mekf_blocks

    fuse_session(session_with(seconds=3.0), "smoother", magnetometer=False)
    assert _mekf_blocks.compiled() in (True, None)  # None: a numba whose cache is not readable
