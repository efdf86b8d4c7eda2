"""The report's plain lines (PlainText, pdftext.draw_line) write the PDF bytes matplotlib writes;
ticks_in_view draws the ticks and labels matplotlib draws."""

import io

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure
from matplotlib.text import Text

from motionlab.report import pdftext
from motionlab.report.pdf import RC, PlainText, layout_problems, page_text, put_text, ticks_in_view

# kerning pairs (AV, Ty, To), a ligature (fi), characters past U+00FF (–, →, ≤, Σ, −) and
# PDF string escapes ((, ), \)
LINES = [
    ("AVATAR Tyre: To 4–62° (fi) ≤ ±1.5 → Σ \\ x", {}),
    ("Right knee flexion range", {"ha": "right", "weight": "bold", "color": "#b2182b"}),
    ("centred −3.2°", {"ha": "center", "size": 8.0}),
    ("", {}),
    ("two\nlines", {}),
    ("rotated", {"rotation": 90}),
    ("on top", {"va": "top"}),
    ("$x^2$ math", {}),
]


def _pdf(cls: type[Text]) -> bytes:
    """A page of LINES drawn as ``cls``, uncompressed, without a creation date."""
    with matplotlib.rc_context({**RC, "pdf.compression": 0}):
        fig = Figure(figsize=(8.27, 11.69))
        FigureCanvasAgg(fig)
        for i, (s, kw) in enumerate(LINES):
            t = cls(0.5, 0.9 - 0.05 * i, s, transform=fig.transSubfigure, va="baseline")
            t.update(kw)
            t.set_figure(fig)
            fig.texts.append(t)
        buf = io.BytesIO()
        with PdfPages(buf, metadata={"CreationDate": None}) as pdf:
            pdf.savefig(fig)
    return buf.getvalue()


def test_plain_text_writes_the_bytes_matplotlib_writes(monkeypatch):
    calls = []
    real = pdftext.draw_line
    monkeypatch.setattr(pdftext, "draw_line", lambda *a: calls.append(a[4]) or real(*a))
    assert _pdf(PlainText) == _pdf(Text)
    assert calls == [s for s, _ in LINES[:3]]  # the fast path was taken for the plain lines


def test_plain_text_is_an_ordinary_text_to_the_page_checks():
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(8.27, 11.69))
        FigureCanvasAgg(fig)
        put_text(fig, 0.5, 0.5, "overlapping words")
        put_text(fig, 0.5, 0.5, "more words")
        put_text(fig, 0.98, 0.2, "runs off the right edge of the page")
        problems = layout_problems(fig)
    assert len(fig.texts) == 3
    assert "overlapping words" in page_text(fig)
    assert any(p.startswith("overlap") for p in problems)
    assert any(p.startswith("off the page") for p in problems)


def _labels(lo: float, hi: float, in_view: bool) -> tuple[list[tuple[float, str]], int]:
    """The drawn y ticks (position, label) of an axes spanning ``lo``-``hi``, and how many tick
    objects its axis made."""
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(3, 2))
        FigureCanvasAgg(fig)
        ax = fig.add_axes((0.2, 0.2, 0.7, 0.7))
        ax.plot([0, 1], [lo, hi])
        if in_view:
            ticks_in_view(fig)
        fig.draw_without_rendering()
        vlo, vhi = sorted(ax.get_ylim())
        ticks = ax.yaxis.get_major_ticks()
        drawn = [(t.get_loc(), t.label1.get_text()) for t in ticks if vlo <= t.get_loc() <= vhi]
        return drawn, len(ticks)


def test_ticks_in_view_draws_the_same_ticks_and_labels():
    spans = [(0, 65), (-2.7, 7.4), (0.001, 0.0042), (-1e-5, 3e-5), (1000, 1000.8), (-180, 180)]
    spans += [(95, 1005), (-0.31, -0.02), (1.0e6, 1.2e6), (12.3, 12.3)]
    fewer = 0
    for lo, hi in spans:
        (same, n_all), (fast, n_view) = _labels(lo, hi, False), _labels(lo, hi, True)
        assert fast == same, (lo, hi)
        assert n_view == len(fast)
        fewer += n_all - n_view
    assert fewer > 0
