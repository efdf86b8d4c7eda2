"""The report's plain lines (PlainText, drawn without matplotlib's layout pass) write the PDF
bytes matplotlib's Text writes, and the page checks read them as ordinary texts."""

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text
from pdf_bytes import pdf_bytes

from motionlab.report.pdf import (
    RC,
    SPELLED,
    Document,
    PlainText,
    layout_problems,
    page_text,
    pdf_text,
    put_text,
)

# kerning pairs (AV, Ty, To), a ligature (fi), characters past U+00FF (–, →, ≤, Σ, −), PDF
# string escapes ((, ), \), and texts PlainText hands to Text (several lines, rotated, top,
# math)
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

    def draw() -> Figure:
        fig = Figure(figsize=(8.27, 11.69))
        FigureCanvasAgg(fig)
        for i, (s, kw) in enumerate(LINES):
            t = cls(0.5, 0.9 - 0.05 * i, s, transform=fig.transSubfigure, va="baseline")
            t.update(kw)
            t.set_figure(fig)
            fig.texts.append(t)
        return fig

    return pdf_bytes(draw)


def test_plain_text_writes_the_bytes_matplotlib_writes():
    assert _pdf(PlainText) == _pdf(Text)


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


def test_pdf_text_spells_what_the_standard_fonts_lack():
    assert pdf_text("ρ ≥ 0.95 → −3.2° ± 1 (σ, Σ)") == "rho >= 0.95 -> -3.2° ± 1 (sigma, sum )"
    assert pdf_text("4–62° · µs × 2 — ½") == "4–62° · µs × 2 — ½"  # all in Windows-1252
    assert pdf_text("ﬁt ℵ") == "fit ?"  # a compatibility ligature decomposes; the rest is '?'
    for spelled in SPELLED.values():
        spelled.encode("cp1252")


def test_a_report_page_writes_only_what_the_standard_fonts_have(tmp_path, monkeypatch):
    """Every string the PDF gets encodes in Windows-1252 without a replacement character:
    texts, titles, legends and tick labels (negative ticks included)."""
    from matplotlib.backends.backend_pdf import RendererPdf

    monkeypatch.setattr(RendererPdf, "encode_string", lambda self, s, fonttype: s.encode("cp1252"))
    with matplotlib.rc_context(RC):
        doc = Document("report · ρ ≥ 0.9", "subject → σ")
        doc.section("Calibration − quality", "ρ ≥ 0.95 for static poses, Σσ = 1")
        doc.table(["Segment", "ρ"], [["pelvis", "≥ 0.95"]], [0.5, 0.5])
        ax = doc.axes_grid(1, 1, 2.0)[0][0]
        ax.plot([0, 1], [-5, 5], label="IMU − optical")
        ax.set_title("angle → time")
        ax.legend()
        pages = doc.save(tmp_path / "r.pdf", tmp_path / "r.txt")
    pdf = (tmp_path / "r.pdf").read_bytes()
    assert b"/BaseFont /Helvetica" in pdf and b"/FontFile" not in pdf
    assert "rho >= 0.95 for static poses, sum sigma = 1" in pages[0]
    assert "IMU - optical" in (tmp_path / "r.txt").read_text()
