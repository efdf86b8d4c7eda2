"""plain(): numpy values as plain Python ones for JSON and YAML (NaN and ±inf as None)."""

from pathlib import Path

import numpy as np

from motionlab.plain import plain


def test_arrays_become_lists_of_python_numbers_with_nan_and_inf_as_none():
    out = plain(
        {
            "finite": np.array([1.5, -0.0]),
            "gaps": np.array([1.0, np.nan, np.inf]),
            "grid": np.array([[np.nan, 2.0], [3.0, -np.inf]]),
            "f32": np.float32([0.5]),
            "ints": np.arange(3, dtype=np.uint8),
            "flags": np.array([True, False]),
            "empty": np.zeros((2, 0)),
            "names": np.array(["a"]),
            3: Path("x"),
            "scalar": np.float64(np.nan),
        }
    )
    assert out == {
        "finite": [1.5, -0.0],
        "gaps": [1.0, None, None],
        "grid": [[None, 2.0], [3.0, None]],
        "f32": [0.5],
        "ints": [0, 1, 2],
        "flags": [True, False],
        "empty": [[], []],
        "names": ["a"],
        "3": "x",
        "scalar": None,
    }
    assert type(out["ints"][0]) is int and type(out["flags"][0]) is bool
    assert type(out["f32"][0]) is float
    assert type(out["gaps"][0]) is float and type(out["grid"][0][1]) is float
    assert plain(np.float32([0.1, np.nan])) == [0.10000000149011612, None]  # as tolist() gives
