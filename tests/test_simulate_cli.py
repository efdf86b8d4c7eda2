"""simulate command, byte-identical output per seed, truth file and CSV, C3D markers."""

import ezc3d
import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from motionlab import rotations as rot
from motionlab.cli import main
from motionlab.io import read_any
from motionlab.session import load_session, save_session, sha256_file
from motionlab.simulate import load_truth, save_truth, simulate, write_truth_csv
from motionlab.simulate.markers import OpticalSystem, c3d_labels, write_c3d

PROTOCOL = {
    "name": "knee_cli",
    "segments": {
        "thigh_r": {"side": "r", "landmarks": ["RGT", "RLE"]},
        "shank_r": {"side": "r", "sensor_axes": ["-z", "y", "x"], "landmarks": ["RLM"]},
    },
    "calibration": [
        {
            "name": "standing",
            "kind": "static",
            "pose": "standing",
            "duration_s": 3,
            "vertical_axis": {"thigh_r": "y"},
        },
    ],  # fmt: skip
    "joints": {"knee_r": {"type": "knee", "proximal": "thigh_r", "distal": "shank_r", "side": "r"}},
    "tasks": [{"name": "gait", "kind": "gait", "duration_s": 20}],
}


@pytest.fixture
def protocol(tmp_path):
    path = tmp_path / "knee_cli.yaml"
    path.write_text(yaml.safe_dump(PROTOCOL))
    return path


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_same_seed_same_bytes_different_seed_different(tmp_path, protocol):
    digests = []
    for i, seed in enumerate((3, 3, 4)):
        session, truth = simulate(protocol, 20.0, seed, "harsh", markers=True)
        save_session(session, tmp_path / f"s{i}.h5")
        save_truth(truth, tmp_path / f"t{i}.h5")
        digests.append((sha256_file(tmp_path / f"s{i}.h5"), sha256_file(tmp_path / f"t{i}.h5")))
    assert digests[0] == digests[1]
    assert digests[0][0] != digests[2][0] and digests[0][1] != digests[2][1]


def test_cli_writes_session_truth_csv_and_c3d(tmp_path, protocol):
    out = tmp_path / "sim.h5"
    res = run("simulate", "--protocol", protocol, "--duration", 30, "--seed", 1, "-o", out,
              "--truth", tmp_path / "truth.h5", "--truth-csv", tmp_path / "csv",
              "--markers", tmp_path / "m.c3d", "--height", 1.6)  # fmt: skip
    assert res.exit_code == 0, res.output
    session = load_session(out)
    assert set(session.sensors) == {"thigh_r", "shank_r"}
    s = session.sensors["shank_r"]
    assert (s.vendor, s.segment, s.side) == ("motionlab-sim", "shank_r", "r")
    assert session.metadata["subject"]["height_m"] == 1.6 and session.metadata["seed"] == 1
    assert session.metadata["preset"] == "typical" and not session.markers
    truth = load_truth(tmp_path / "truth.h5")
    assert [st["name"] for st in truth.steps] == ["standing", "gait"]
    assert truth.sensors["shank_r"]["mounting"].shape == (4,)
    table = pd.read_csv(tmp_path / "csv" / "joint_angles.csv")
    assert list(table.columns) == ["time_s", "knee_r_flexion_deg", "knee_r_adduction_deg",
                                   "knee_r_rotation_deg"]  # fmt: skip
    assert np.allclose(table["knee_r_flexion_deg"], truth.joint_angles["knee_r_flexion_deg"])
    for name in ("steps", "sensors", "markers", "lab_frame", "segment_orientations"):
        assert (tmp_path / "csv" / f"{name}.csv").is_file()
    c3d = ezc3d.c3d(str(tmp_path / "m.c3d"))
    assert c3d["parameters"]["POINT"]["UNITS"]["value"] == ["mm"]
    assert c3d["parameters"]["POINT"]["RATE"]["value"][0] == pytest.approx(120.0)
    assert c3d["parameters"]["POINT"]["LABELS"]["value"] == truth.markers["labels"]


def test_truth_round_trip(tmp_path, protocol):
    _, truth = simulate(protocol, 20.0, 2, "typical")
    save_truth(truth, tmp_path / "t.h5")
    back = load_truth(tmp_path / "t.h5")
    assert np.array_equal(back.time, truth.time)
    for label, s in truth.sensors.items():
        for key in ("orientation", "gyr_bias", "soft_iron", "sample_time"):
            assert np.array_equal(back.sensors[label][key], s[key])
        assert back.sensors[label]["clock_drift"] == s["clock_drift"]
    assert back.steps == truth.steps
    assert back.markers["labels"] == truth.markers["labels"]
    assert back.config["seed"] == 2
    written = write_truth_csv(truth, tmp_path / "csv")
    assert len(written) == 7


def test_markers_in_the_lab_frame_match_the_truth(tmp_path, protocol):
    system = OpticalSystem(rate_hz=100.0, offset_s=0.0, drift=0.0, noise_m=0.0,
                           occlusions_per_min=0.0)  # fmt: skip
    session, truth = simulate(protocol, 20.0, 5, "clean", markers=True, optical=system)
    write_c3d(session.markers["optical"], tmp_path / "m.c3d")
    pts = ezc3d.c3d(str(tmp_path / "m.c3d"))["data"]["points"][:3] / 1000.0  # (3, M, F) m
    m = truth.markers
    assert np.array_equal(m["frame_time"], truth.time)
    for j, (label, seg) in enumerate(zip(m["labels"], m["segments"], strict=True)):
        q, p = truth.segments[seg]["orientation"], truth.segments[seg]["position"]
        enu = p + rot.rotate(q, m["local"][j])
        lab = rot.rotate(rot.conj(m["lab_rotation"]), enu - m["lab_origin"])
        assert np.abs(pts[:, j].T - lab).max() < 1e-4, label


def test_default_optical_clock_and_occlusions(protocol):
    session, truth = simulate(protocol, 20.0, 6, "harsh", markers=True)
    ms = session.markers["optical"]
    assert ms.rate_hz == pytest.approx(120.0)
    t_true = (ms.time - 0.137) / (1 + 100e-6)
    assert np.allclose(truth.markers["frame_time"], t_true)
    assert 0 < np.isnan(ms.positions[..., 0]).mean() < 0.2


def test_help_has_an_example():
    res = run("simulate", "--help")
    assert res.exit_code == 0 and "Example" in res.output and "motionlab simulate" in res.output


@pytest.mark.parametrize(
    "args",
    [
        ["--preset", "bogus"],
        ["--protocol-missing"],
        ["--exists"],
        ["--duration", "5"],
        ["--height", "7"],
        ["--stride-cv", "-0.01"],
        ["--stride-cv", "0.5"],
        ["--gait", "fast"],
    ],
)
def test_bad_arguments_exit_2_with_one_line(tmp_path, protocol, args):
    out = tmp_path / "sim.h5"
    base = ["simulate", "--protocol", protocol, "-o", out]
    if args == ["--protocol-missing"]:
        base[2], args = tmp_path / "missing.yaml", []
    if args == ["--exists"]:
        out.write_bytes(b"keep me")
        args = []
    res = run(*base, *args)
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    if out.exists():
        assert out.read_bytes() == b"keep me"


def test_stride_cv_sets_how_much_the_strides_vary(tmp_path, protocol):
    """--stride-cv: the walking task's stride times vary by that fraction (the feet's true
    initial contacts in the truth), 0 gives the metronome; with --gait it keeps the variant's
    timing (the asymmetric walk's right step, 47 % of the stride)."""

    def stride_cv(*args):
        out, truth = tmp_path / "s.h5", tmp_path / "t.h5"
        res = run("simulate", "--protocol", protocol, "--duration", 60, "-o", out, "--truth",
                  truth, "--force", *args)  # fmt: skip
        assert res.exit_code == 0, res.output
        gait = load_truth(truth).gait
        ic = np.asarray(gait["ic_r"], float)[np.asarray(gait["ic_r_steady"], bool)]
        t = np.diff(ic)
        return float(np.std(t) / np.mean(t)), ic, gait

    metronome, _, _ = stride_cv("--stride-cv", 0)
    varied, _, _ = stride_cv("--stride-cv", 0.06)
    assert metronome < 0.002 and 0.035 < varied < 0.09
    _, ic_r, gait = stride_cv("--stride-cv", 0.03, "--gait", "asymmetric")
    ic_l = np.asarray(gait["ic_l"], float)
    step = [(ic_l[ic_l > a][0] - a) / (b - a) for a, b in zip(ic_r[:-1], ic_r[1:], strict=True)
            if (ic_l > a).any() and ic_l[ic_l > a][0] < b]  # fmt: skip
    assert abs(np.median(step) - 0.47) < 0.01


def test_a_landmark_two_segments_name_gets_unique_c3d_labels(tmp_path):
    """The femoral epicondyle that the thigh and the shank both list is simulated once on each,
    and both copies were written to the C3D file as ``RLE``: two points with one label, which
    the ingest renamed with a warning per label and other tools would confuse. The shank's copy
    is now ``RLE_shank_r``; the file reads back without a warning, the thigh's ``RLE`` still
    where the protocol's landmark lists find it."""
    knee = {**PROTOCOL, "name": "knee_shared_landmark"}
    knee["segments"] = {**PROTOCOL["segments"],
                        "shank_r": {**PROTOCOL["segments"]["shank_r"],
                                    "landmarks": ["RLE", "RLM"]}}  # fmt: skip
    path = tmp_path / "knee.yaml"
    path.write_text(yaml.safe_dump(knee, sort_keys=False))  # the thigh first, as in knee.yaml
    res = run("simulate", "--protocol", path, "--duration", 30, "--seed", 1, "-o",
              tmp_path / "s.h5", "--truth", tmp_path / "t.h5", "--markers",
              tmp_path / "m.c3d")  # fmt: skip
    assert res.exit_code == 0, res.output
    truth = load_truth(tmp_path / "t.h5")
    assert truth.markers["labels"].count("RLE") == 2  # a copy on each segment
    labels = ezc3d.c3d(str(tmp_path / "m.c3d"))["parameters"]["POINT"]["LABELS"]["value"]
    assert len(set(labels)) == len(labels) == len(truth.markers["labels"])
    assert labels == c3d_labels(truth.markers["labels"], truth.markers["segments"])
    rle = [j for j, lab in enumerate(truth.markers["labels"]) if lab == "RLE"]
    assert [labels[j] for j in rle] == ["RLE", "RLE_shank_r"]
    assert [truth.markers["segments"][j] for j in rle] == ["thigh_r", "shank_r"]
    back = read_any(tmp_path / "m.c3d").markers[0]
    assert back.labels == labels and "warnings" not in back.attrs
    assert back.attrs["flags"]["duplicate_labels"] is False
    res = run("ingest", tmp_path / "m.c3d", "-o", tmp_path / "m.h5")
    assert res.exit_code == 0 and res.stderr == "", res.output
