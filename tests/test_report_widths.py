"""The words' widths kept on disk (report/widths.py): the widths FreeType measures, read back by
a new process, and never a stored width that could be wrong (other versions, other font files,
entries of the wrong type); a broken, unreadable or unwritable cache is skipped silently."""

import json

import pytest

from motionlab.report import widths


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """The cache file in a temporary folder, this process's widths forgotten before and after."""
    path = tmp_path / "mpl" / widths.CACHE_NAME
    monkeypatch.setattr(widths, "cache_file", lambda: path)
    widths.forget()
    yield path
    widths.forget()


def _no_measuring(monkeypatch):
    def fail(*args):
        raise AssertionError("measured again")

    monkeypatch.setattr(widths, "_measure", fail)


def _stored(path) -> dict:
    """text → width of every group of the cache file."""
    groups = json.loads(path.read_text(encoding="utf-8"))["groups"]
    return {t: w for g in groups.values() for t, w in g.items()}


def test_widths_are_measured_once_per_machine(cache, monkeypatch):
    knee = widths.text_width("knee", 9.5)
    flexion = widths.text_width("flexion", 8.0, "bold")
    assert knee == widths._measure("knee", 9.5, "normal") and 0.1 < knee < 0.5
    assert flexion == widths._measure("flexion", 8.0, "bold")
    assert not cache.exists()  # written when the report asks for it
    widths.save()
    assert _stored(cache) == {"knee": knee, "flexion": flexion}
    assert [p.name for p in cache.parent.iterdir()] == [cache.name]  # no temporary file left
    widths.forget()  # a new process
    _no_measuring(monkeypatch)
    assert widths.text_width("knee", 9.5) == knee
    assert widths.text_width("flexion", 8.0, "bold") == flexion


def _rewrite(path, change) -> None:
    data = json.loads(path.read_text(encoding="utf-8"))
    change(data)
    path.write_text(json.dumps(data), encoding="utf-8")


def _stored_as(path, text: str, width: object) -> None:
    """Every group of the file says ``text`` is ``width`` wide."""

    def change(data):
        for group in data["groups"].values():
            group[text] = width

    _rewrite(path, change)


@pytest.mark.parametrize(
    "change",
    [
        lambda d: d["versions"].update(matplotlib="0.0.1"),
        lambda d: d["versions"].update(freetype="1.0"),
        lambda d: d["versions"].update(format=widths.FORMAT + 1),
        # the same words measured with another font file, or the same file changed
        lambda d: d.update(
            groups={k.replace("DejaVuSans", "Other"): v for k, v in d["groups"].items()}
        ),
        lambda d: d.update(groups={k.replace(", ", ",", 1): v for k, v in d["groups"].items()}),
    ],
    ids=["matplotlib", "freetype", "format", "font file", "group key"],
)
def test_a_width_stored_under_other_conditions_is_not_used(cache, change):
    true = widths.text_width("gait", 9.5)
    widths.save()
    _stored_as(cache, "gait", 5.0)
    _rewrite(cache, change)
    widths.forget()
    assert widths.text_width("gait", 9.5) == true


def test_the_key_holds_the_font_files_identity(cache):
    key = json.loads(widths._group(9.5, "normal", widths._settings()))
    size, weight, text_rc, fonts = key
    assert (size, weight) == (9.5, "normal") and len(text_rc) == len(widths.TEXT_RC)
    path, nbytes, mtime = fonts[0]
    assert path.endswith(".ttf") and nbytes > 0 and mtime > 0
    bold = json.loads(widths._group(9.5, "bold", widths._settings()))[3]
    assert bold != fonts  # another file


@pytest.mark.parametrize("bad", ["not a number", -1.0, float("nan"), float("inf"), None, 3])
def test_entries_of_the_wrong_type_are_measured_again(cache, bad):
    true = widths.text_width("hip", 9.5)
    widths.save()
    _stored_as(cache, "hip", bad)
    widths.forget()
    assert widths.text_width("hip", 9.5) == true


@pytest.mark.parametrize(
    "content", [b"", b"{", b"\xff\xfe garbage", b"[1, 2]", b'{"versions": 1}', b"null"]
)
def test_a_broken_cache_is_ignored_and_replaced(cache, content):
    cache.parent.mkdir()
    cache.write_bytes(content)
    true = widths._measure("ankle", 9.5, "normal")
    assert widths.text_width("ankle", 9.5) == true
    widths.save()
    assert _stored(cache) == {"ankle": true}


def test_an_unreadable_cache_is_skipped(cache):
    cache.mkdir(parents=True)  # a folder where the file should be: neither read nor replaced
    assert widths.text_width("elbow", 9.5) == widths._measure("elbow", 9.5, "normal")
    widths.save()
    assert cache.is_dir() and list(cache.parent.iterdir()) == [cache]


def test_an_unwritable_cache_folder_is_skipped(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setattr(widths, "cache_file", lambda: blocker / "mpl" / widths.CACHE_NAME)
    widths.forget()
    try:
        assert widths.text_width("wrist", 9.5) == widths._measure("wrist", 9.5, "normal")
        widths.save()  # cannot make the folder: nothing written, nothing raised
    finally:
        widths.forget()
    assert blocker.read_text() == "x"


def test_the_cache_is_bounded(cache, monkeypatch):
    for word in ("one", "two", "three"):
        widths.text_width(word, 9.5)
    widths.save()
    monkeypatch.setattr(widths, "MAX_ENTRIES", 3)
    widths.forget()
    widths.text_width("three", 9.5)
    widths.text_width("four", 9.5)  # a fourth width: only this process's two are kept
    widths.save()
    assert sorted(_stored(cache)) == ["four", "three"]


def test_a_process_that_used_more_than_the_bound_keeps_the_bound(cache, monkeypatch):
    monkeypatch.setattr(widths, "MAX_ENTRIES", 2)
    for word in ("one", "two", "three"):
        widths.text_width(word, 9.5)
    widths.text_width("four", 8.0)
    widths.save()
    assert len(_stored(cache)) == 2
