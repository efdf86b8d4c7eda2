"""json_text writes what json.dumps(indent=1, allow_nan=False) writes, faster."""

import json

import pytest

from motionlab.export import json_text


class Name(str):
    pass


class Count(int):
    pass


TREE = {
    "empty list": [],
    "empty dict": {},
    "curve": [1.0, -0.0, 1e-300, 1e16, 2.5, 0.1, 1 / 3, 1e308, 1e308],  # sum overflows: checked
    "mixed": [1, True, False, None, 'x\u00e9\u2264"\n\\', 0.1, [], {}, [0.5]],
    "gr\u00fcn \u2265": {"k": [[1.0, 2.0], [3, None]], "t": (1.5,)},
    "big": 12345678901234567890,
    "subclasses": [Name("a"), Count(3)],
    "": "",
}


def test_json_text_is_json_dumps_indented():
    assert json_text(TREE) == json.dumps(TREE, indent=1, allow_nan=False)
    assert json_text([]) == "[]" and json_text(2.5) == "2.5" and json_text("é") == '"\\u00e9"'


@pytest.mark.parametrize(
    "bad", [[float("nan")], {"x": [1.0, float("inf")]}, [1, float("-inf")], float("nan")]
)
def test_json_text_refuses_nan_and_infinity_as_json_does(bad):
    with pytest.raises(ValueError):
        json.dumps(bad, allow_nan=False)
    with pytest.raises(ValueError):
        json_text(bad)


def test_json_text_refuses_what_json_cannot_write():
    with pytest.raises(TypeError):
        json_text({"x": object()})
