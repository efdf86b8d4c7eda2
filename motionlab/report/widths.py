"""Widths of the report's words for wrapping, measured once per machine and kept on disk.

The report wraps its text by measuring each distinct word with FreeType through matplotlib's
Agg renderer (:func:`text_width`): about 0.4 ms a word, 1 700 words on the demo's knee report,
most of what a process's first report costs more than the next (docs/performance.md). The
widths are kept in one JSON file in matplotlib's cache folder (``matplotlib.get_cachedir()``),
so a new process measures only words it has never seen.

A stored width is used only when everything it depends on is the same: this module's
:data:`FORMAT`, the matplotlib, FreeType and libraqm versions, the ``text.*`` settings that
change glyph advances (hinting, kerning), and, per font size and weight, the font files
matplotlib picks for them (path, size in bytes and modification time). Anything else found in
the file (another version, a changed font, a file that does not parse, entries of the wrong
type) is ignored and measured again; a cache that cannot be read or written is skipped
silently. The file is replaced atomically (a temporary file renamed over it) and holds at most
:data:`MAX_ENTRIES` widths: past that, only the widths the process used are kept.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from functools import lru_cache
from itertools import islice
from pathlib import Path

import matplotlib
from matplotlib import font_manager, ft2font
from matplotlib.backends.backend_agg import RendererAgg
from matplotlib.font_manager import FontProperties

from motionlab.atomic import output_mode

#: the layout of the file and the way widths are measured; change it when either changes
FORMAT = 1
CACHE_NAME = "motionlab-text-widths.json"
MAX_ENTRIES = 20000
#: matplotlib settings that change how wide a text is measured (glyph advances, kerning)
TEXT_RC = ("text.hinting", "text.hinting_factor", "text.kerning_factor")
#: matplotlib settings that choose the font (``findfont`` reads them)
FONT_RC = tuple(
    f"font.{k}"
    for k in ("family", "style", "variant", "weight", "stretch", "size", "serif", "sans-serif",
              "cursive", "fantasy", "monospace")
)  # fmt: skip

_MEASURE = RendererAgg(600, 850, 72)  # 72 dpi: widths in points


def cache_file() -> Path:
    """Where the widths are kept: in matplotlib's cache folder."""
    return Path(matplotlib.get_cachedir()) / CACHE_NAME


def _versions() -> dict:
    """The software every stored width depends on (the whole file is ignored if it differs)."""
    return {
        "format": FORMAT,
        "matplotlib": matplotlib.__version__,
        "freetype": getattr(ft2font, "__freetype_version__", None),
        "libraqm": getattr(ft2font, "__libraqm_version__", None),
    }


def _settings() -> tuple:
    """The current values of :data:`FONT_RC` and :data:`TEXT_RC` (hashable)."""
    rc = matplotlib.rcParams
    return tuple(tuple(v) if isinstance(v, list) else v for v in (rc[k] for k in FONT_RC + TEXT_RC))


@lru_cache(maxsize=64)
def _group(size: float, weight: str, settings: tuple) -> str:
    """The key of the widths of ``size`` and ``weight`` under ``settings``: those, the
    :data:`TEXT_RC` values and the font files matplotlib measures with (per family it tries,
    as ``findfont`` finds it; each with its size in bytes and modification time, so that a
    changed or replaced file gives another key)."""
    prop = FontProperties(size=size, weight=weight)
    fonts = []
    for family in prop.get_family():
        one = prop.copy()
        one.set_family(family)
        try:
            path = font_manager.findfont(one, fallback_to_default=False)
            st = os.stat(path)
            fonts.append([str(path), st.st_size, st.st_mtime_ns])
        except (ValueError, OSError):
            fonts.append([family, None, None])
    text_rc = list(settings[len(FONT_RC) :])
    return json.dumps([float(size), weight, text_rc, fonts], ensure_ascii=False)


def _measure(text: str, size: float, weight: str) -> float:
    """Width (in) of one line of ``text`` measured by FreeType (matplotlib's Agg renderer); a
    character no font can hold (an undecodable byte of a file name, kept as a lone surrogate)
    measured as the ``?`` the PDF writes for it."""
    text = text.encode("utf-8", "replace").decode("utf-8")
    prop = FontProperties(size=size, weight=weight)
    w, _, _ = _MEASURE.get_text_width_height_descent(text, prop, ismath=False)
    return w / 72.0


def _valid(w: object) -> bool:
    return type(w) is float and 0.0 <= w < float("inf")


class _Store:
    """The widths of this process, per group (:func:`_group`): those read from the cache file
    (a group's only when first used) and those measured since."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.widths: dict[str, dict[str, float]] = {}
        self.used: dict[str, set[str]] = {}
        self.stored: dict = {}
        self.changed = False
        with contextlib.suppress(OSError, ValueError, TypeError, AttributeError):
            data = json.loads(path.read_text(encoding="utf-8"))
            if data.get("versions") == _versions() and isinstance(data.get("groups"), dict):
                self.stored = data["groups"]

    def width(self, text: str, size: float, weight: str) -> float:
        group = _group(float(size), weight, _settings())
        table = self.widths.get(group)
        if table is None:
            stored = self.stored.pop(group, None)
            table = self.widths[group] = (
                {t: w for t, w in stored.items() if _valid(w)} if isinstance(stored, dict) else {}
            )
            self.used[group] = set()
        self.used[group].add(text)
        w = table.get(text)
        if w is None:
            w = table[text] = _measure(text, size, weight)
            self.changed = True
        return w

    def save(self) -> None:
        """Write the widths (when any was measured) atomically; failures are ignored."""
        if not self.changed:
            return
        groups = {**self.stored, **self.widths}
        if sum(len(t) for t in groups.values() if isinstance(t, dict)) > MAX_ENTRIES:
            # the widths this process used, at most MAX_ENTRIES of them
            groups, room = {}, MAX_ENTRIES
            for g, t in self.widths.items():
                groups[g] = dict(islice(((s, t[s]) for s in self.used[g]), room))
                room -= len(groups[g])
        tmp = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{CACHE_NAME}.", dir=self.path.parent)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump({"versions": _versions(), "groups": groups}, f, ensure_ascii=False)
            os.chmod(tmp, output_mode(self.path))  # as a plain open() would make it
            os.replace(tmp, self.path)
            tmp = None
            self.changed = False
        except (OSError, ValueError, TypeError):
            pass
        finally:
            if tmp is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)


_store: _Store | None = None


def _the_store() -> _Store:
    global _store
    if _store is None:
        _store = _Store(cache_file())
    return _store


@lru_cache(maxsize=20000)
def text_width(text: str, size: float, weight: str = "normal") -> float:
    """Width (in) of one line of ``text`` at ``size`` pt in the measuring font (DejaVu Sans
    under the report's settings), from the cache file when measured before on this machine.

    Kept in memory too, as the first width found for these arguments in the process (the
    report measures under its own settings, :data:`motionlab.report.pdf.RC`)."""
    return _the_store().width(text, size, weight)


def save() -> None:
    """Keep this process's new widths in the cache file (nothing when none was measured)."""
    if _store is not None:
        _store.save()


def forget() -> None:
    """Drop this process's widths (tests: the next width reads the cache file again)."""
    global _store
    _store = None
    text_width.cache_clear()
    _group.cache_clear()
