"""Axes drawn with one tick object per axis (``stamp_ticks``) draw the page matplotlib's own
tick objects draw (the same text operators in the PDF, the same pixels), and the page checks
still see every tick label."""

import re
import shutil
import subprocess

import matplotlib
import numpy as np
import pytest
from matplotlib.axis import XAxis
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from pdf_bytes import pdf_bytes

from motionlab.report.pdf import RC, layout_problems, stamp_ticks, unstamp_ticks


def _page(names: tuple[str, str] = ("thigh r", "some")) -> Figure:
    """Axes as the report draws them, and some it does not: default ticks with negative
    numbers and an offset, named and rotated ticks, hidden tick labels under shared x axes,
    a grid, minor ticks, a log scale, ticks on the right, an inverted axis, labels aligned."""
    fig = Figure(figsize=(8.27, 11.69))
    FigureCanvasAgg(fig)
    t = np.linspace(0.0, 12.3, 200)
    ax = fig.add_axes([0.1, 0.85, 0.8, 0.1])
    ax.plot(t, 40 * np.sin(t) - 5)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("angle (°)")
    ax.set_title("default ticks")
    ax = fig.add_axes([0.1, 0.7, 0.35, 0.08])
    ax.plot(t, 1e5 + t)  # an offset text
    ax.grid(True)
    ax.minorticks_on()
    ax = fig.add_axes([0.6, 0.7, 0.3, 0.08])
    ax.bar(range(3), [3, 1, 2])
    ax.set_xticks(range(3), ["pelvis", names[0], "shank_l"], rotation=30, ha="right")
    ax.set_yticks([0, 1.5, 3], ["none", names[1], "all"])
    axes = fig.subplots(3, 1, sharex=True, gridspec_kw={"top": 0.6, "bottom": 0.35})
    for k, a in enumerate(axes):
        a.plot(t, k * t)
        a.set_ylabel(f"panel {k}")
    axes[-1].set_xlabel("time (s)")
    ax = fig.add_axes([0.1, 0.1, 0.35, 0.15])
    ax.semilogy(t + 1, np.exp(t))
    ax.yaxis.tick_right()
    ax.invert_xaxis()
    ax = fig.add_axes([0.6, 0.1, 0.3, 0.07])
    ax.plot(t, 1000 * t)
    fig.align_ylabels(axes)
    return fig


def _pdf(stamped: bool, names: tuple[str, str] = ("thigh r", "some")) -> bytes:
    def draw() -> Figure:
        fig = _page(names)
        if stamped:
            stamp_ticks(fig)
        return fig

    return pdf_bytes(draw)


def _texts(pdf: bytes) -> list[bytes]:
    """The PDF's text objects (font, place and string of each), in order."""
    return re.findall(rb"\bBT\b.*?\bET\b", pdf, re.S)


def test_stamped_ticks_write_the_texts_matplotlib_writes():
    # the tick marks and grid lines of an axis are drawn as one line each (other bytes)
    texts = _texts(_pdf(True))
    assert len(texts) > 60 and texts == _texts(_pdf(False))


def _pixels(stamped: bool) -> np.ndarray:
    with matplotlib.rc_context(RC):
        fig = _page()
        if stamped:
            stamp_ticks(fig)
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba()).copy()


def test_stamped_ticks_draw_the_pixels_matplotlib_draws():
    assert np.array_equal(_pixels(True), _pixels(False))


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="poppler's pdftoppm is not installed")
def test_stamped_ticks_render_as_matplotlib_s_in_a_pdf_reader(tmp_path):
    pages = []
    for stamped in (True, False):
        pdf = tmp_path / f"{stamped}.pdf"
        pdf.write_bytes(_pdf(stamped))
        subprocess.run(["pdftoppm", "-r", "150", "-gray", str(pdf), str(pdf)], check=True)
        pages.append(next(tmp_path.glob(f"{stamped}.pdf*.pgm")).read_bytes())
    assert pages[0] == pages[1]


def test_stamped_tick_labels_are_spelled_as_the_pdf_spells_text():
    pdf = _pdf(True, ("thigh −r", "some ≥ 1"))
    assert b"(thigh -r)" in pdf and b"(some >= 1)" in pdf


def test_stamped_axes_make_one_tick_each_and_the_checks_see_every_label():
    with matplotlib.rc_context(RC):
        fig = _page()
        stamp_ticks(fig)
        fig.draw_without_rendering()
        # one tick object per axis, but where set_xticks made them (the named ticks) or the
        # labels are aligned with another axes' (matplotlib's own ticks)
        assert [len(a.xaxis.majorTicks) for a in fig.axes] == [1, 1, 3, 1, 1, 1, 1, 1]
        assert [len(a.yaxis.majorTicks) > 1 for a in fig.axes][2:6] == [True] * 4
        assert layout_problems(fig) == []
        assert len(fig.axes[0].xaxis.majorTicks) > 3  # matplotlib's own ticks, one per position
        unstamp_ticks(fig)


def test_a_matplotlib_without_the_parts_stamping_uses_keeps_its_own_ticks(monkeypatch):
    from motionlab.report import pdf

    fig = Figure()
    ax = fig.add_subplot()
    monkeypatch.setattr(pdf, "_AXIS_PARTS", (*pdf._AXIS_PARTS, "_a_part_matplotlib_dropped"))
    pdf.stamp_ticks(fig)
    assert type(ax.xaxis) is XAxis
    monkeypatch.undo()
    pdf.stamp_ticks(fig)
    assert type(ax.xaxis) is not XAxis
