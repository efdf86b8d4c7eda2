"""A sensor map's ``{segment: shank, side: right}`` reaches the protocol segment ``shank_r``."""

import numpy as np

from motionlab.segments import sensor_for_segment
from motionlab.session import SensorStream, Session


def _session(**placements):
    s = Session()
    for label, (segment, side) in placements.items():
        s.sensors[label] = SensorStream(label, np.arange(3.0), segment=segment, side=side)
    return s


def test_bare_segment_name_with_side_matches_the_protocol_segment():
    s = _session(A1=("shank", "r"), A2=("shank", "l"), A3=("pelvis", ""))
    assert sensor_for_segment(s, "shank_r") == "A1"
    assert sensor_for_segment(s, "shank_l") == "A2"
    assert sensor_for_segment(s, "pelvis") == "A3"
    assert sensor_for_segment(s, "thigh_r") is None


def test_full_segment_name_and_label_match():
    s = _session(B1=("thigh_r", "r"), shank_l=("", ""))
    assert sensor_for_segment(s, "thigh_r") == "B1"
    assert sensor_for_segment(s, "shank_l") == "shank_l"
