"""One line of text written straight into matplotlib's PDF: the same bytes, in a third of the time.

:meth:`matplotlib.backends.backend_pdf.RendererPdf.draw_text` lays the string out with libraqm,
then loads every glyph's outline (which the PDF never uses: it only needs the glyph indices and
positions), records each glyph in the font's subset and formats each glyph run and kern through
the generic ``pdfRepr``. :func:`draw_line` does the same steps for the report's plain lines
(type-42 fonts, no rotation, no font features) without the glyph loads, with each glyph's
subset entry looked up once per file and the ``TJ`` array formatted directly. The bytes are
those of matplotlib (``tests/test_report.py`` compares them), so the pages look the same; a
renderer or a matplotlib that does not look as expected gets ``draw_text`` itself.

This reaches into matplotlib's PDF backend (its ``PdfFile`` and character tracker, matplotlib
3.11); :func:`supported` checks what it uses before every page.
"""

from __future__ import annotations

import weakref

import matplotlib as mpl
from matplotlib import font_manager
from matplotlib.backends import backend_pdf
from matplotlib.ft2font import LoadFlags

_ESCAPES = str.maketrans({"\\": "\\\\", "(": "\\(", ")": "\\)", "\n": "\\n", "\r": "\\r"})
#: per PDF file: (font file, face, characters, glyph index) → (subset, character code)
_TRACKED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class _Raw:
    """Bytes already in PDF syntax (``pdfRepr`` returns them as they are)."""

    __slots__ = ("data",)

    def __init__(self, data: bytes) -> None:
        self.data = data

    def pdfRepr(self) -> bytes:  # noqa: N802 (matplotlib's name)
        return self.data


def _fill(items: list[bytes], linelen: int = 75) -> bytes:
    """matplotlib's ``backend_pdf._fill``: items joined by spaces in lines of ≤ ``linelen``."""
    pos, last, out = 0, 0, []
    for i, s in enumerate(items):
        if pos + len(s) < linelen:
            pos += len(s) + 1
        else:
            out.append(b" ".join(items[last:i]))
            last, pos = i, len(s)
    out.append(b" ".join(items[last:]))
    return b"\n".join(out)


def _number(x: float) -> bytes:
    """A float as ``pdfRepr`` writes it (10 decimals, trailing zeros dropped)."""
    return (b"%.10f" % x).rstrip(b"0").rstrip(b".")


def _glyphs(codes: list[int]) -> bytes:
    """A run of 2-byte glyph codes as a PDF string (type-42 fonts)."""
    raw = b"".join(c.to_bytes(2, "big") for c in codes)
    return b"(" + raw.decode("latin-1").translate(_ESCAPES).encode("latin-1") + b")"


def vector_renderer(renderer):
    """The :class:`RendererPdf` behind ``renderer`` (savefig's mixed-mode renderer in its vector
    phase), or None."""
    inner = getattr(renderer, "_renderer", renderer)
    return inner if isinstance(inner, backend_pdf.RendererPdf) else None


def supported(pdf) -> bool:
    """Whether :func:`draw_line` can write into this renderer's file as matplotlib would."""
    return (
        mpl.rcParams["pdf.fonttype"] == 42
        and not mpl.rcParams["pdf.use14corefonts"]
        and hasattr(pdf, "check_gc")
        and hasattr(pdf, "_get_font_ttf")
        and hasattr(pdf, "_setup_textpos")
        and hasattr(pdf.file, "_character_tracker")
        and hasattr(pdf.file._character_tracker, "track_glyph")
        and hasattr(pdf.file, "fontName")
        and hasattr(font_manager, "FontPath")
    )


def draw_line(pdf, gc, x: float, y: float, text: str, prop) -> bool:
    """Write ``text`` at ``(x, y)`` (points, the baseline's left end) into the PDF renderer
    ``pdf`` as ``pdf.draw_text(gc, x, y, text, prop, 0)`` would. Returns False, having written
    nothing, when the layout has a raised glyph (then call ``draw_text``)."""
    font = pdf._get_font_ttf(prop)
    items = list(font._layout(text, LoadFlags.NO_HINTING, features=None, language=None))
    if any(item.y for item in items):
        return False
    fontsize = prop.get_size_in_points()
    file = pdf.file
    tracked = _TRACKED.setdefault(file, {})
    tracker = file._character_tracker
    out = file.output
    pdf.check_gc(gc, gc._rgb)
    out(backend_pdf.Op.gsave)
    out(1.0, 0.0, -0.0, 1.0, x, y, backend_pdf.Op.concat_matrix)
    out(backend_pdf.Op.begin_text)
    parts: list[bytes] = []  # the current TJ array: glyph runs and kerns
    run: list[int] = []

    def flush() -> None:
        if run:
            parts.append(_glyphs(run))
            run.clear()
        if parts:
            out(_Raw(_fill([b"[", *parts, b"]"])), backend_pdf.Op.showkern)
            parts.clear()

    prev_font = None
    prev_x = 0
    for item in items:
        ft = item.ft_object
        key = (ft.fname, ft.face_index, item.char, item.glyph_index)
        code = tracked.get(key)
        if code is None:
            code = tracked[key] = tracker.track_glyph(ft, item.char, item.glyph_index)
        subset, charcode = code
        if (ft, subset) != prev_font:
            flush()
            name = file.fontName(font_manager.FontPath(ft.fname, ft.face_index), subset)
            out(name, fontsize, backend_pdf.Op.selectfont)
            pdf._setup_textpos(item.x, 0, 0, prev_x, 0, 0)
            prev_font, prev_x = (ft, subset), item.x
        if item.prev_kern:
            if run:
                parts.append(_glyphs(run))
                run.clear()
            parts.append(_number(-1000 * item.prev_kern / fontsize))
        run.append(charcode)
    flush()
    out(backend_pdf.Op.end_text)
    out(backend_pdf.Op.grestore)
    return True
