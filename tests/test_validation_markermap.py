"""Marker maps: loading, errors with key and line, checks against a marker set, defaults."""

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.protocol import Protocol, Segment
from motionlab.session import MarkerSet
from motionlab.validation.markermap import check_marker_map, default_marker_map, load_marker_map

GOOD = """\
marker_set: optical
max_gap_s: 0.2
static_time_s: [1.0, 4.0]
segments:
  thigh_r:
    cluster: [T1, T2, T3, T4]
    landmarks: [RGT, RLE, RME]
    sensor: imu_3
    frame:
      primary: {axis: z, from: [RME], to: [RLE]}
      secondary: {axis: y, from: [RLE, RME], to: [RGT]}
  pelvis:
    rigid_body: pelvis_rb
"""


def _write(tmp_path, text):
    path = tmp_path / "map.yaml"
    path.write_text(text)
    return path


def test_a_complete_map(tmp_path):
    m = load_marker_map(_write(tmp_path, GOOD))
    assert m.marker_set == "optical" and m.max_gap_s == 0.2 and m.static_time_s == (1.0, 4.0)
    thigh = m.segments["thigh_r"]
    assert thigh.cluster == ["T1", "T2", "T3", "T4"] and thigh.sensor == "imu_3"
    assert thigh.frame.primary.axis == "z" and thigh.frame.secondary.end == [["RGT"]]
    assert thigh.line == 5
    assert m.segments["pelvis"].rigid_body == "pelvis_rb" and m.segments["pelvis"].landmarks is None


@pytest.mark.parametrize(
    "old, new, where",
    [
        ("cluster: [T1, T2, T3, T4]", "cluster: [T1, T2]", "line 6, key segments.thigh_r.cluster"),
        ("    rigid_body: pelvis_rb\n", "    side: l\n", "line 13, key segments.pelvis.side"),
        ("    rigid_body: pelvis_rb\n", "    landmarks: [A]\n", "line 12, key segments.pelvis"),
        ("{axis: z,", "{axis: w,", "line 10, key segments.thigh_r.frame.primary.axis"),
        ("max_gap_s: 0.2", "max_gap_s: -1", "line 2, key max_gap_s"),
        ("static_time_s: [1.0, 4.0]", "static_time_s: [4.0, 1.0]", "line 3, key static_time_s"),
        ("marker_set: optical\n", "markers: optical\n", "line 1, key markers"),
        ("  pelvis:\n", "  pelvis\n", "line 13"),
    ],
)  # fmt: skip
def test_errors_name_the_key_and_line(tmp_path, old, new, where):
    with pytest.raises(InputError) as err:
        load_marker_map(_write(tmp_path, GOOD.replace(old, new)))
    assert err.value.where.startswith(where), err.value.line()
    assert err.value.path.name == "map.yaml"


def _markers(labels, bodies=()):
    n = 5
    return MarkerSet(
        "optical", np.arange(n) / 100.0, list(labels), np.zeros((n, len(labels), 3)),
        rigid_bodies={b: np.tile([1.0, 0, 0, 0], (n, 1)) for b in bodies},
    )  # fmt: skip


def test_check_against_the_recording(tmp_path):
    m = load_marker_map(_write(tmp_path, GOOD))
    with pytest.raises(InputError, match="marker T4 is not in") as err:
        check_marker_map(m, _markers(["T1", "T2", "T3", "RGT"], ["pelvis_rb"]))
    assert err.value.where == "line 5, key segments.thigh_r"
    with pytest.raises(InputError, match="rigid body 'pelvis_rb'"):
        check_marker_map(m, _markers(["T1", "T2", "T3", "T4"]))
    check_marker_map(m, _markers(["T1", "T2", "T3", "T4"], ["pelvis_rb"]))


def test_default_map_by_names():
    proto = Protocol(
        "p",
        {
            "thigh_r": Segment("thigh_r", "r", landmarks=["thigh_r_GT"]),
            "shank_r": Segment("shank_r"),
        },
        {},
    )
    labels = ["thigh_r_C1", "thigh_r_C2", "thigh_r_GT", "thigh_r_C3", "shank_r_C1", "RLE"]
    m = default_marker_map(_markers(labels, ["shank_r"]), proto)
    assert m.segments["thigh_r"].cluster == ["thigh_r_C1", "thigh_r_C2", "thigh_r_C3"]
    assert m.segments["shank_r"].rigid_body == "shank_r"
    broad = default_marker_map(_markers(["imu_origin"], ["imu"]), None, ["imu"])
    assert broad.segments["imu"].rigid_body == "imu"
    with pytest.raises(InputError, match="no segment"):
        default_marker_map(_markers(["A", "B", "C"]), proto)


def test_reference_files_session_and_trc(tmp_path, data_dir):
    from motionlab.session import Session, save_session
    from motionlab.validation.reference import choose_marker_set, read_reference

    path = tmp_path / "ref.h5"
    save_session(Session(markers={"optical": _markers(["A", "B", "C"])}), path)
    sets = read_reference(path)
    assert [m.name for m in sets] == ["optical"]
    assert choose_marker_set(sets, None).labels == ["A", "B", "C"]
    trc = read_reference(data_dir / "c3d" / "markers_20frames.trc")
    assert len(trc) == 1 and trc[0].positions.shape[0] == 20
    with pytest.raises(InputError, match="no marker set 'lab'"):
        choose_marker_set(sets, "lab", path)
    with pytest.raises(InputError, match="no such reference"):
        read_reference(tmp_path / "missing.c3d")


def test_run_takes_the_marker_set_its_marker_map_names(tmp_path):
    """``motionlab run --reference S --markers MAP`` refused a reference of two marker sets
    ("name one with marker_set: in the map") although the map named one: run read the
    reference without it (``validate`` passed it)."""
    from motionlab.pipeline import PipelineOptions, _read_reference
    from motionlab.protocol import load_protocol
    from motionlab.session import Session, save_session

    t = np.arange(50) / 100.0
    ref = Session()
    for name in ("lab", "optical"):
        ref.markers[name] = MarkerSet(
            name, t, ["M1"], np.zeros((50, 1, 3)) + (name == "optical")
        )  # fmt: skip
    path = tmp_path / "ref.h5"
    save_session(ref, path)
    options = PipelineOptions(load_protocol("knee"), reference=str(path), progress=False)
    with pytest.raises(InputError, match="holds 2 marker sets"):
        _read_reference(options, None)
    marker_set, kind = _read_reference(options, load_marker_map(_write(tmp_path, GOOD)))
    assert (marker_set.name, kind) == ("optical", "markers")
    assert marker_set.positions[0, 0, 0] == 1.0


def test_a_reference_without_the_protocols_segments_is_named_not_the_session():
    """An elbow's C3D given to a knee session read "k.h5 marker map: no segment found in marker
    set 'e' by name": the session was blamed for what the reference lacks."""
    t = np.arange(10) / 100.0
    elbow = MarkerSet("e", t, ["forearm_r_1", "forearm_r_2", "forearm_r_3"],
                      np.zeros((10, 3, 3)), attrs={"source_file": "e.c3d"})  # fmt: skip
    proto = Protocol("k", {s: Segment(s) for s in ("thigh_r", "shank_r")}, joints={})
    with pytest.raises(InputError) as err:
        default_marker_map(elbow, proto)
    assert err.value.line().startswith("e.c3d: no segment found in marker set 'e' by name")
    assert "for thigh_r, shank_r" in err.value.line()
