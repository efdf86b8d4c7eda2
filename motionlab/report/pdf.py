"""A4 pages drawn with matplotlib, filled top to bottom and saved into one PDF with PdfPages.

Conventions: lengths in inches (A4 portrait is 8.27 × 11.69 in), font sizes in points, the page
cursor ``y`` in inches from the top of the page. Figures are plain :class:`matplotlib.figure.Figure`
objects (no pyplot state). The text is set in the PDF's standard Helvetica, in the characters it
has (:func:`pdf_text`: ``≥`` is written ``>=``); it is wrapped by measuring it with the Agg
renderer in DejaVu Sans, a wider font, so lines never run past the margin. :meth:`Document.save`
writes the PDF and keeps every page's text (titles, paragraphs, tables, axis labels and legends;
not tick numbers) for tests and for a plain-text copy.
:func:`layout_problems` lists text that leaves the page or overlaps other text.
"""

from __future__ import annotations

import logging
import unicodedata
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext, suppress
from functools import lru_cache
from itertools import combinations
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib import colors as mcolors
from matplotlib.artist import allow_rasterization
from matplotlib.axes import Axes
from matplotlib.axis import Axis, XAxis, YAxis
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.text import Text
from matplotlib.ticker import NullLocator

from motionlab.report.widths import text_width

PAGE_W, PAGE_H = 8.27, 11.69
MARGIN = 0.6
TOP = 0.75  # below the running header
BOTTOM = 0.7  # above the footer
WIDTH = PAGE_W - 2 * MARGIN
SIZE = {"title": 15.0, "heading": 11.5, "body": 9.5, "small": 8.0, "table": 8.5}
LINE = 1.35  # line height / font size
HEADING_H = 0.08 + (LINE + 0.45) * SIZE["heading"] / 72  # a sub-heading's height (in)
FLAG_COLOUR = "#b2182b"
SIDE_COLOUR = {"r": "#1a9850", "l": "#d73027", "": "#2166ac"}  # right green, left red
BAND_COLOUR = "#bdbdbd"
MUTED = "#555555"
MUTED_ROW = "#8c8c8c"  # a table row of an angle that is not determined
NOT_DETERMINED_COLOUR = "#a0a0a0"  # its curves
RC = {
    "font.size": SIZE["body"],
    "axes.titlesize": SIZE["body"],
    "axes.labelsize": SIZE["small"],
    "xtick.labelsize": SIZE["small"],
    "ytick.labelsize": SIZE["small"],
    "legend.fontsize": SIZE["small"],
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.titley": 1.0,  # titles at the axes' top: no measuring of the tick labels to place them
    # the PDF's standard Helvetica (not embedded): matplotlib writes each line as one string,
    # where an embedded TrueType font costs a glyph-by-glyph layout per text (docs/performance.md)
    "pdf.use14corefonts": True,
    "font.family": "sans-serif",
    "font.sans-serif": ["Helvetica", "DejaVu Sans"],  # DejaVu Sans: the (wider) measuring font
    "axes.unicode_minus": False,  # tick labels: '-' (U+2212 is not in the standard fonts)
    "figure.autolayout": False,  # no layout engine: pages are placed by hand (place_figure)
    "figure.constrained_layout.use": False,
    # zlib level of the PDF's streams: 3 compresses them in half the time of matplotlib's 6,
    # the file 5 % larger (docs/performance.md)
    "pdf.compression": 3,
}

#: a placed figure's room (in) left of its axes (tick and axis labels), right of them, above
#: the first (its title), under the last (tick labels and the x label), between two
FIGURE_PAD = (0.75, 0.1, 0.25, 0.5, 0.32)
#: a scatter with more points than this is drawn as an image in the PDF, at RASTER_DPI
DENSE_POINTS = 2000
RASTER_DPI = 200
#: a plain curve with more than 4 points per column, a column being 1/ENVELOPE_DPI in of its
#: axes' width, is drawn through its envelope per column (:func:`envelope`): the same shape
ENVELOPE_DPI = 144

#: characters the standard PDF fonts (Windows-1252 encoding) lack, spelled with ones they have
SPELLED = {
    "≥": ">=",
    "≤": "<=",
    "≠": "!=",
    "−": "-",
    "→": "->",
    "←": "<-",
    "≈": "~",
    "ρ": "rho",
    "σ": "sigma",
    "Σ": "sum ",
    "Δ": "delta ",
    "θ": "theta",
    "ω": "omega",
    "√": "sqrt ",
    "✓": "yes",
    "✗": "no",
}


def report_rc():
    """A context with the report's settings (:data:`RC`): none when they are set already, as
    :func:`motionlab.report.write_report` sets them for the whole report (``rc_context``
    copies all of matplotlib's settings, about 1 ms, for each page and axes)."""
    rc = matplotlib.rcParams
    if all(rc[k] == v for k, v in _rc_as_set().items()):
        return nullcontext()
    return matplotlib.rc_context(RC)


@lru_cache(maxsize=1)
def _rc_as_set() -> dict:
    """:data:`RC` as matplotlib holds it once set (``"sans-serif"`` is ``["sans-serif"]``)."""
    with matplotlib.rc_context(RC):
        return {k: matplotlib.rcParams[k] for k in RC}


def pdf_text(text: str) -> str:
    """``text`` in the characters the PDF's standard fonts have (Windows-1252): the ones
    they lack spelled as :data:`SPELLED` says, else by their compatibility decomposition, else
    ``?``."""
    try:
        text.encode("cp1252")
        return text
    except UnicodeEncodeError:
        return "".join(_spell(c) for c in text)


def _spell(c: str) -> str:
    try:
        c.encode("cp1252")
        return c
    except UnicodeEncodeError:
        pass
    if c in SPELLED:
        return SPELLED[c]
    plain = unicodedata.normalize("NFKD", c).encode("cp1252", "ignore").decode("cp1252")
    return plain or "?"


class PlainText(Text):
    """A text drawn without matplotlib's layout pass when it is one unrotated line on its baseline.

    :meth:`matplotlib.text.Text.draw` measures every text (its width, height and descent, one
    FreeType layout of the string) to find where its lines go, before the PDF backend lays the
    string out again to write its glyphs. A line on its baseline, left-aligned, needs no
    measure: it starts at its position; right-aligned or centred, only its width (the renderer's
    own measure, as matplotlib takes it). Anything else (several lines, rotation, a box, math
    text, path effects) is drawn by :class:`Text`. The glyphs written are the same.
    """

    @allow_rasterization
    def draw(self, renderer) -> None:
        text = self.get_text()
        simple = (
            self._verticalalignment == "baseline"
            and not self.get_rotation()
            and "\n" not in text
            and not self._bbox_patch
            and not self.get_path_effects()
            and not self.get_usetex()
            and not self.get_wrap()
        )
        if not simple:
            return super().draw(renderer)
        if renderer is not None:
            self._renderer = renderer
        if not self.get_visible() or text == "":
            return
        line, ismath = self._preprocess_math(text)
        if ismath:
            return super().draw(renderer)
        x, y = self.get_transform().transform((float(self._x), float(self._y)))
        if not (np.isfinite(x) and np.isfinite(y)):
            return
        ha = self._horizontalalignment
        if ha != "left":
            w = renderer.get_text_width_height_descent(line, self._fontproperties, False)[0]
            x = -(w if ha == "right" else w / 2) + x
        if renderer.flipy():
            y = renderer.get_canvas_width_height()[1] - y
        renderer.open_group("text", self.get_gid())
        gc = renderer.new_gc()
        gc.set_foreground(mcolors.to_rgba(self.get_color()), isRGBA=True)
        gc.set_alpha(self.get_alpha())
        gc.set_url(self._url)
        gc.set_antialiased(self._antialiased)
        gc.set_snap(self.get_snap())
        self._set_gc_clip(gc)
        renderer.draw_text(gc, x, y, line, self._fontproperties, 0.0, ismath=False, mtext=self)
        gc.restore()
        renderer.close_group("text")
        self.stale = False


def _contains_close(interval: np.ndarray, value: float, rtol: float = 1e-10) -> bool:
    """Whether ``value`` is in ``interval`` widened by ``rtol`` of its length (matplotlib's test
    of which ticks an axis draws)."""
    a, b = sorted(interval)
    pad = (b - a) * rtol
    return a - pad <= value <= b + pad


#: whether a group of ticks (major or minor) has anything to draw (matplotlib ≥ 3.10 skips
#: groups with none; earlier versions drew them anyway, which draws nothing)
_group_visible = getattr(Axis, "_tick_group_visible", lambda kw: True)


class _StampedTicks:
    """An axis that draws its ticks by moving one tick object from position to position.

    matplotlib's :meth:`Axis.draw <matplotlib.axis.Axis.draw>` makes a :class:`Tick` (tick
    marks, grid line, two labels: five artists, copied from the first tick) for every tick
    position the first time it draws, about 1 ms each: a report page of six axes makes ~100.
    Every tick of an axis has its first tick's properties (``tick_params`` and
    ``set_ticklabels`` set all of them, new ones copy the first), so drawing the first one at
    each position and with each label draws the same page: its grid line and tick marks at
    all positions as one line each (:func:`_draw_lines_at`), then its labels one by one, in
    matplotlib's order (the same text in the PDF, the same pixels:
    ``tests/test_report_ticks.py``). The positions, labels and the filter to the view are
    matplotlib's (``Axis._update_ticks``); tick labels are spelled as the PDF spells text
    (:func:`pdf_text`). :meth:`get_children` leaves the ticks out, so finding a page's texts
    makes none. Only :meth:`draw` stamps: anything else that asks for the ticks (a tight
    bounding box, a layout engine) gets matplotlib's tick objects.
    """

    def get_children(self) -> list:
        return [self.label, self.offsetText]

    def _stamps(self) -> list[tuple]:
        """``(tick, position, label)`` of each tick drawn, major ones first."""
        low, high = sorted(self.get_view_interval())
        scale = self.get_transform()
        interval = scale.transform([low, high])
        out = []
        groups = (
            (self._major_tick_kw, self.major, self.get_majorticklocs, self.get_major_ticks),
            (self._minor_tick_kw, self.minor, self.get_minorticklocs, self.get_minor_ticks),
        )
        for kw, ticker, positions, ticks in groups:
            if not _group_visible(kw) or isinstance(ticker.locator, NullLocator):
                continue
            locs = positions()  # the minor ones without those of major ticks
            labels = ticker.formatter.format_ticks(locs)
            if len(locs) == 0:
                continue
            tick = ticks(1)[0]
            for loc, label in zip(locs, labels, strict=True):
                try:
                    loc_t = scale.transform(loc)
                except AssertionError:  # masked values of some scales, as matplotlib skips them
                    continue
                if _contains_close(interval, loc_t):
                    out.append((tick, loc, pdf_text(label)))
        return out

    @allow_rasterization
    def draw(self, renderer) -> None:
        if not self.get_visible():
            return
        renderer.open_group(Axis.__module__, gid=self.get_gid())
        boxes1, boxes2 = [], []
        stamps = [s for s in self._stamps() if s[0].get_visible()]
        self._drawn = list(dict.fromkeys(tick for tick, _, _ in stamps))
        for tick in self._drawn:
            _draw_lines_at(tick, [loc for t, loc, _ in stamps if t is tick], renderer)
        for tick, loc, label in stamps:
            tick.update_position(loc)
            for text, boxes in ((tick.label1, boxes1), (tick.label2, boxes2)):
                text.set_text(label)
                if text.get_visible() and text.get_in_layout():
                    boxes.append(text.get_window_extent(renderer))
                text.draw(renderer)
        self._boxes = (boxes1, boxes2)
        self._update_label_position(renderer)
        self.label.draw(renderer)
        self._update_offset_text_position(boxes1, boxes2)
        self.offsetText.set_text(self.major.formatter.get_offset())
        self.offsetText.draw(renderer)
        renderer.close_group(Axis.__module__)
        self._drawn = self._boxes = None
        self.stale = False

    def _update_ticks(self) -> list:
        # during draw, the spine asks which ticks are drawn (for their length): the template
        # ticks; anyone else gets matplotlib's answer, one tick object per position
        drawn = getattr(self, "_drawn", None)
        return drawn if drawn is not None else super()._update_ticks()

    def _get_tick_boxes_siblings(self, renderer) -> tuple[list, list]:
        # the axis label's place: below (beside) this draw's tick labels
        boxes = getattr(self, "_boxes", None)
        return boxes if boxes is not None else super()._get_tick_boxes_siblings(renderer)


def _draw_lines_at(tick, locs: list[float], renderer) -> None:
    """Draw ``tick``'s grid line and tick marks at every position of ``locs``, each as one
    line: the marks as one line of markers, the grid lines as one line broken by gaps (NaN).

    The same marks and grid lines as a tick drawn at each position (the tick's own lines,
    moved with :meth:`Tick.update_position <matplotlib.axis.Tick.update_position>`), in one
    draw each instead of one per position and line."""
    lines = [ln for ln in (tick.gridline, tick.tick1line, tick.tick2line) if ln.get_visible()]
    if not locs or not lines:
        return
    data = [([], []) for _ in lines]
    for loc in locs:
        tick.update_position(loc)
        for line, (xs, ys) in zip(lines, data, strict=True):
            x, y = np.broadcast_arrays(line.get_xdata(), line.get_ydata())  # as Line2D takes them
            xs.extend(x)
            ys.extend(y)
            if line.get_linestyle() not in ("None", " ", ""):  # a gap to the next position
                xs.append(np.nan)
                ys.append(np.nan)
    for line, (xs, ys) in zip(lines, data, strict=True):
        line.set_data(xs, ys)
        line.draw(renderer)


class _StampedXAxis(_StampedTicks, XAxis):
    pass


class _StampedYAxis(_StampedTicks, YAxis):
    pass


_STAMPED = {XAxis: _StampedXAxis, YAxis: _StampedYAxis}
_PLAIN = {v: k for k, v in _STAMPED.items()}


#: the parts of matplotlib's axes :class:`_StampedTicks` relies on (private ones: a matplotlib
#: without them keeps its own ticks, and the pages are drawn as before, only slower)
_AXIS_PARTS = ("_major_tick_kw", "_minor_tick_kw", "_update_ticks", "_update_label_position",
               "_update_offset_text_position", "_get_tick_boxes_siblings")  # fmt: skip


def stamp_ticks(fig: Figure) -> None:
    """Let every plain x and y axis of ``fig`` draw its ticks as :class:`_StampedTicks` (the
    same pages, a fraction of matplotlib's tick objects); axes whose labels are aligned with
    other axes' (``Figure.align_labels``) keep matplotlib's ticks, and so does every axis with a
    matplotlib that lacks a part the stamping uses (:data:`_AXIS_PARTS`)."""
    groups = getattr(fig, "_align_label_groups", None)
    if not fig.axes or groups is None:
        return
    if not all(hasattr(fig.axes[0].xaxis, part) for part in _AXIS_PARTS):
        return
    for ax in fig.axes:
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            aligned = name in groups and len(groups[name].get_siblings(ax)) > 1
            if type(axis) in _STAMPED and not aligned:  # aligned labels: matplotlib's ticks
                axis.__class__ = _STAMPED[type(axis)]


def unstamp_ticks(fig: Figure) -> None:
    """Undo :func:`stamp_ticks`: matplotlib's own tick objects again."""
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if type(axis) in _PLAIN:
                axis.__class__ = _PLAIN[type(axis)]


def envelope(x: np.ndarray, y: np.ndarray, x0: float, x1: float, columns: int) -> np.ndarray:
    """Indices of the samples of a curve that draw it as all its samples do at ``columns``
    columns over ``x0`` to ``x1`` (M4: per column and per run of finite samples, its first,
    lowest, highest and last sample, in their order; Jugel et al. 2014, PVLDB 7(10)).

    ``x`` is nondecreasing (samples beyond ``x0``/``x1`` fall in columns of the same width
    outside); non-finite samples (the curve's gaps) are all kept. Within a column the line
    then spans the samples' lowest to highest value, and it enters and leaves the column where
    all the samples' line does, so a page drawn at up to ``columns`` dots over the span shows
    the same curve; a spike of one sample stays a spike.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    finite = np.isfinite(x) & np.isfinite(y)
    idx = np.flatnonzero(finite)
    if len(idx) == 0:
        return np.arange(len(y))
    col = np.floor((x[idx] - x0) * (columns / (x1 - x0)))
    # a group: consecutive finite samples in one column
    starts = np.r_[0, np.flatnonzero((np.diff(idx) != 1) | (np.diff(col) != 0)) + 1]
    ends = np.r_[starts[1:], len(idx)] - 1
    group = np.repeat(np.arange(len(starts)), ends - starts + 1)
    yv = y[idx]
    keep = ~finite
    keep[idx[starts]] = keep[idx[ends]] = True
    for extreme in (np.minimum, np.maximum):
        at = np.flatnonzero(yv == extreme.reduceat(yv, starts)[group])
        first = np.r_[True, np.diff(group[at]) != 0]  # the first such sample of each group
        keep[idx[at[first]]] = True
    return np.flatnonzero(keep)


#: a recording longer than this (s) is drawn as an overview of windows and an excerpt
#: (``pages_joint``, ``pages_oop``): on the page's 6.5 in, 5 minutes of walking are some 270
#: strides of 0.6 mm each, one band of ink
LONG_RECORDING_S = 300.0
#: the overview's window (s): the shortest of these that gives at most OVERVIEW_WINDOWS
WINDOWS_S = (1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1800.0)
OVERVIEW_WINDOWS = 150


def overview_window(duration_s: float) -> float:
    """The overview's window (s) for a recording of ``duration_s``: the shortest of
    :data:`WINDOWS_S` that cuts it into at most :data:`OVERVIEW_WINDOWS` windows."""
    return next((w for w in WINDOWS_S if duration_s / w <= OVERVIEW_WINDOWS), WINDOWS_S[-1])


def window_range(
    t: np.ndarray, y: np.ndarray, window_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each window's centre (s), lowest and highest finite value of ``y`` over consecutive
    windows of ``window_s`` from ``t[0]`` (``t`` nondecreasing, s); NaN where a window has no
    finite sample (a gap stays a gap)."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    k = np.floor((t - t[0]) / window_s).astype(np.int64)
    n = int(k[-1]) + 1
    lo, hi = np.full(n, np.nan), np.full(n, np.nan)
    ok = np.isfinite(y)
    if ok.any():
        kk, yy = k[ok], y[ok]
        starts = np.r_[0, np.flatnonzero(np.diff(kk)) + 1]
        lo[kk[starts]] = np.minimum.reduceat(yy, starts)
        hi[kk[starts]] = np.maximum.reduceat(yy, starts)
    return t[0] + (np.arange(n) + 0.5) * window_s, lo, hi


def thin_curves(fig: Figure, dpi: float = ENVELOPE_DPI) -> None:
    """Replace the data of each plain curve of ``fig`` (solid, no markers, default draw style,
    in its axes' data coordinates on linear axes, ``x`` nondecreasing) that has more than 4
    points per column (``dpi`` columns per inch of its axes' width) by its :func:`envelope`
    at the axes' final limits. Call when the page is complete: the limits are read (autoscaled
    on the full data, which the envelope's extremes keep)."""
    for ax in fig.axes:
        if ax.get_xscale() != "linear" or ax.get_yscale() != "linear":
            continue
        columns = int(np.ceil(ax.get_position().width * fig.get_figwidth() * dpi))
        x0, x1 = ax.get_xlim()
        for line in ax.lines:
            if (
                len(line.get_xdata(orig=False)) <= 4 * columns
                or line.get_marker() not in ("None", "", " ", None)
                or line.get_linestyle() != "-"
                or line.get_drawstyle() != "default"
                or line.get_transform() is not ax.transData
                or x1 == x0
            ):
                continue
            x = np.asarray(line.get_xdata(orig=False), dtype=float)
            y = np.asarray(line.get_ydata(orig=False), dtype=float)
            dx = np.diff(x[np.isfinite(x)])
            if len(x) != len(y) or np.any(dx < 0):
                continue
            keep = envelope(x, y, x0, x1, columns)
            if len(keep) < len(x):
                line.set_data(x[keep], y[keep])


def put_text(fig: Figure, x: float, y: float, text: str, **kw) -> PlainText:
    """:meth:`Figure.text <matplotlib.figure.Figure.text>` (figure-fraction position, kept in
    ``fig.texts``) as a :class:`PlainText`."""
    t = PlainText(x, y, text, transform=fig.transSubfigure, **kw)
    t.set_figure(fig)
    fig.texts.append(t)
    return t


def wrap(text: str, width: float, size: float, weight: str = "normal") -> list[str]:
    """Greedy word wrap of ``text`` into lines at most ``width`` in wide (explicit newlines kept).

    A line's width is the sum of its words' widths and the spaces between them.
    """
    space = text_width("a a", size, weight) - 2 * text_width("a", size, weight)
    lines: list[str] = []
    for para in str(text).split("\n"):
        line, used = "", 0.0
        for word in _split_long(para.split(), width, size, weight):
            w = text_width(word, size, weight)
            if line and used + space + w > width:
                lines.append(line)
                line, used = word, w
            else:
                line, used = (f"{line} {word}", used + space + w) if line else (word, w)
        lines.append(line)
    return lines


def label_spans(ax: Axes, spans: dict[str, tuple[float, float]], size: float) -> None:
    """Name each span ``(start, end)`` of the x axis just inside the axes' top edge, centred on
    it; a label that would run into the one before it goes one line lower. Call after the
    x limits are set."""
    x0, x1 = ax.get_xlim()
    per_in = (x1 - x0) / (ax.get_position().width * PAGE_W)
    ends = [-np.inf, -np.inf]
    for name, (a, b) in spans.items():
        centre = 0.5 * (a + b)
        half = (0.5 * text_width(name, size) + 0.05) * per_in
        row = 0 if centre - half > ends[0] else 1
        ends[row] = centre + half
        ax.annotate(
            name,
            (centre, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(0, -2 - row * (size + 2)),
            textcoords="offset points",
            ha="center",
            va="top",
            size=size,
            color=MUTED,
        )


def _split_long(words: list[str], width: float, size: float, weight: str) -> list[str]:
    """Words, with any word wider than ``width`` cut into pieces that fit (paths, hashes)."""
    out = []
    for word in words:
        while text_width(word, size, weight) > width and len(word) > 1:
            n = max(1, int(len(word) * width / text_width(word, size, weight)))
            while n > 1 and text_width(word[:n], size, weight) > width:
                n -= 1
            out.append(word[:n])
            word = word[n:]
        out.append(word)
    return out


class Document:
    """A report under construction: pages filled top to bottom.

    ``title`` and ``subtitle`` run along the top of every page; :meth:`section` starts a page,
    and every drawing method starts a continuation page when the current one is full.
    """

    def __init__(self, title: str, subtitle: str = "") -> None:
        self.title = title
        self.subtitle = subtitle
        self.pages: list[Figure] = []
        self.sections: list[str] = []
        self.y = PAGE_H
        self._section = ""

    # ------------------------------------------------------------------------------ pages

    @property
    def fig(self) -> Figure:
        return self.pages[-1]

    def section(self, name: str, intro: str = "", figure: Figure | None = None) -> None:
        """Start a new page headed ``name`` (and an optional introductory paragraph).

        With ``figure`` (a figure drawn elsewhere, e.g. by :mod:`motionlab.validation.figures`)
        the page is that figure, resized to A4; place its content with :meth:`place_figure`.
        """
        self._section = name
        self._new_page(figure)
        self._heading(name, SIZE["title"])
        if intro:
            self.paragraph(intro, colour=MUTED)
        self.space(0.05)

    def _new_page(self, fig: Figure | None = None) -> None:
        if fig is None:
            with report_rc():
                fig = Figure(figsize=(PAGE_W, PAGE_H))
        else:
            fig.set_size_inches(PAGE_W, PAGE_H)
        FigureCanvasAgg(fig)
        put_text(
            fig,
            MARGIN / PAGE_W,
            1 - 0.38 / PAGE_H,
            self.title,
            size=SIZE["small"],
            color=MUTED,
            va="baseline",
        )
        if self.subtitle:
            put_text(
                fig,
                1 - MARGIN / PAGE_W,
                1 - 0.38 / PAGE_H,
                self.subtitle,
                size=SIZE["small"],
                color=MUTED,
                ha="right",
                va="baseline",
            )
        fig.add_artist(
            Line2D(
                [MARGIN / PAGE_W, 1 - MARGIN / PAGE_W],
                [1 - 0.46 / PAGE_H] * 2,
                color="#999999",
                lw=0.5,
            )
        )
        self.pages.append(fig)
        self.sections.append(self._section)
        self.y = TOP

    def ensure(self, height: float) -> None:
        """Start a continuation page unless ``height`` in still fit on this one."""
        if not self.pages or self.y + height > PAGE_H - BOTTOM:
            self._new_page()
            if self._section:
                self._heading(f"{self._section} (continued)", SIZE["heading"])

    def space(self, height: float) -> None:
        self.y += height

    # ------------------------------------------------------------------------------ text

    def _put(self, x: float, text: str, size: float, **kw) -> Text:
        """One line of text with its baseline at the cursor + one line height."""
        return put_text(
            self.fig, x / PAGE_W, 1 - self.y / PAGE_H, text, size=size, va="baseline", **kw
        )

    def _heading(self, text: str, size: float) -> None:
        self.y += size * LINE / 72
        self._put(MARGIN, text, size, weight="bold")
        self.y += 0.45 * size / 72

    def room(self) -> float:
        """The height (in) left on the current page."""
        return PAGE_H - BOTTOM - self.y if self.pages else 0.0

    def heading(self, text: str, follows: float | None = None) -> None:
        """A sub-heading; kept on the page with what follows: 1.2 in with the heading, or all
        of it when ``follows`` (its height, in: :meth:`bullets_height`) is less (a short list
        left under the last one then stays on the page, not alone on the next)."""
        self.ensure(1.2 if follows is None else min(1.2, HEADING_H + follows))
        self.space(0.08)
        self._heading(text, SIZE["heading"])

    @staticmethod
    def paragraph_height(
        text: str, size: float = SIZE["body"], indent: float = 0.0, weight: str = "normal"
    ) -> float:
        """The height (in) :meth:`paragraph` takes for ``text``."""
        step = size * LINE / 72
        return len(wrap(text, WIDTH - indent, size, weight)) * step + 0.35 * step

    @staticmethod
    def bullets_height(items: Sequence[str], size: float = SIZE["body"]) -> float:
        """The height (in) :meth:`bullets` takes for ``items``."""
        step = size * LINE / 72
        lines = sum(len(wrap(item, WIDTH - 0.22, size)) for item in items)
        return lines * step + len(items) * 0.25 * step + 0.2 * step

    @staticmethod
    def table_height(
        header: Sequence[str],
        rows: Sequence[Sequence[str]],
        widths: Sequence[float],
        size: float = SIZE["table"],
    ) -> float:
        """The height (in) :meth:`table` takes on one page."""
        cols = [w * WIDTH for w in widths]
        step = size * LINE / 72

        def height(row: Sequence[str], weight: str) -> float:
            cells = zip(row, cols, strict=True)
            return max(len(wrap(str(c), w - 0.06, size, weight)) for c, w in cells) * step + (
                0.25 * step
            )

        head = height(header, "bold") + 0.06 if any(str(h).strip() for h in header) else 0.0
        return head + sum(height(r, "normal") for r in rows) + 0.12

    def paragraph(
        self,
        text: str,
        size: float = SIZE["body"],
        indent: float = 0.0,
        colour: str = "black",
        weight: str = "normal",
    ) -> None:
        """Wrapped text across the page width (starts a new page when full)."""
        step = size * LINE / 72
        for line in wrap(text, WIDTH - indent, size, weight):
            self.ensure(step)
            self.y += step
            self._put(MARGIN + indent, line, size, color=colour, weight=weight)
        self.y += 0.35 * step

    def bullets(self, items: Sequence[str], size: float = SIZE["body"], colour: str = "black"):
        """A bulleted list; each item wrapped under its own first line."""
        step = size * LINE / 72
        for item in items:
            for k, line in enumerate(wrap(item, WIDTH - 0.22, size)):
                self.ensure(step)
                self.y += step
                if k == 0:
                    self._put(MARGIN + 0.05, "•", size, color=colour)
                self._put(MARGIN + 0.22, line, size, color=colour)
            self.y += 0.25 * step
        self.y += 0.2 * step

    def table(
        self,
        header: Sequence[str],
        rows: Sequence[Sequence[str]],
        widths: Sequence[float],
        flagged: Sequence[Sequence[bool]] | None = None,
        align: Sequence[str] | None = None,
        size: float = SIZE["table"],
        muted: Sequence[bool] | None = None,
    ) -> None:
        """A table across the page; ``widths`` are fractions of the page width (sum ≤ 1).

        Cells wrap inside their column; ``flagged[i][j]`` draws cell ``(i, j)`` bold in red;
        ``muted[i]`` draws row ``i`` grey (a number shown but not stated as a finding);
        ``align`` is ``"l"`` or ``"r"`` per column. The header repeats on continuation pages.
        """
        cols = [w * WIDTH for w in widths]
        xs = [MARGIN + sum(cols[:k]) for k in range(len(cols))]
        align = align or ["l"] + ["r"] * (len(cols) - 1)
        step = size * LINE / 72
        pad = 0.06

        def cell_lines(row: Sequence[str], weight: str) -> list[list[str]]:
            return [wrap(str(c), w - pad, size, weight) for c, w in zip(row, cols, strict=True)]

        def draw(
            row_lines: list[list[str]], weight: str, flags: Sequence[bool], grey: bool = False
        ) -> None:
            for j, lines in enumerate(row_lines):
                for k, line in enumerate(lines):
                    x = xs[j] + (cols[j] - pad if align[j] == "r" else 0.0)
                    put_text(
                        self.fig,
                        x / PAGE_W,
                        1 - (self.y + (k + 1) * step) / PAGE_H,
                        line,
                        size=size,
                        va="baseline",
                        weight="bold" if flags[j] else weight,
                        ha="right" if align[j] == "r" else "left",
                        color=FLAG_COLOUR if flags[j] else (MUTED_ROW if grey else "black"),
                    )
            self.y += max(len(c) for c in row_lines) * step + 0.25 * step

        def rule() -> None:
            y = 1 - (self.y + 0.02) / PAGE_H
            self.fig.add_artist(
                Line2D(
                    [MARGIN / PAGE_W, (MARGIN + sum(cols)) / PAGE_W],
                    [y, y],
                    color="#777777",
                    lw=0.6,
                )
            )
            self.y += 0.06

        head = cell_lines(header, "bold") if any(str(h).strip() for h in header) else []
        head_h = max(len(c) for c in head) * step + 0.3 if head else 0.0
        page = None
        for i, row in enumerate(rows):
            lines = cell_lines(row, "normal")
            self.ensure(max(len(c) for c in lines) * step + 0.1 + (head_h if page is None else 0))
            if page is not self.fig:
                page = self.fig
                if head:
                    draw(head, "bold", [False] * len(cols))
                    rule()
            grey = bool(muted[i]) if muted else False
            draw(lines, "normal", flagged[i] if flagged else [False] * len(cols), grey)
        self.y += 0.12

    # ------------------------------------------------------------------------------ plots

    def axes_grid(
        self,
        nrows: int,
        ncols: int,
        height: float,
        left: float = 0.75,
        bottom: float = 0.5,
        hspace: float = 0.55,
        wspace: float = 0.75,
        top: float = 0.3,
        widths: Sequence[float] | None = None,
    ) -> list[list[Axes]]:
        """An ``nrows × ncols`` grid of axes filling the page width and ``height`` in.

        ``left``/``bottom`` leave room for the tick and axis labels of each cell, ``top`` for
        its title; ``hspace``/``wspace`` are gaps (in) between cells; ``widths``: the columns'
        relative widths (default: equal).
        """
        self.ensure(height)
        room = WIDTH - left - (ncols - 1) * wspace
        if widths is None:
            cell_ws = [room / ncols] * ncols
            xs = [MARGIN + left + j * (cell_ws[0] + wspace) for j in range(ncols)]
        else:
            cell_ws = [room * w / sum(widths) for w in widths]
            xs = list(MARGIN + left + np.r_[0.0, np.cumsum(np.add(cell_ws, wspace))[:-1]])
        cell_h = (height - top - bottom - (nrows - 1) * hspace) / nrows
        grid = []
        for i in range(nrows):
            row = []
            for x, cell_w in zip(xs, cell_ws, strict=True):
                y_top = self.y + top + i * (cell_h + hspace)
                rect = [x / PAGE_W, 1 - (y_top + cell_h) / PAGE_H, cell_w / PAGE_W, cell_h / PAGE_H]
                with report_rc():
                    row.append(self.fig.add_axes(rect))
            grid.append(row)
        self.y += height
        return grid

    def place_figure(self, height: float) -> None:
        """Place the page's own figure (one column of axes, as :mod:`motionlab.validation.figures`
        draws them) in the next ``height`` in: each axes the page's width less
        :data:`FIGURE_PAD`'s room for its tick and axis labels, its title above it, the shared
        x axis's labels under the last one.

        Fixed positions replace the figure's constrained layout, which measured every tick label
        of the page before drawing it (about a tenth of the report's time). A scatter of more
        than :data:`DENSE_POINTS` points is drawn as an image (at :data:`RASTER_DPI`) in the
        PDF: written point by point it was another tenth, and it looks the same.
        """
        fig = self.fig
        # None, not "none": a figure that had an engine keeps a placeholder under "none", and
        # savefig then draws the page twice (once to lay it out)
        fig.set_layout_engine(None)
        left, right, top, bottom, gap = FIGURE_PAD
        axes = fig.axes
        cell = (height - top - bottom - (len(axes) - 1) * gap) / len(axes)
        for i, ax in enumerate(axes):
            y_top = self.y + top + i * (cell + gap)
            w = WIDTH - left - right
            ax.set_position(
                [(MARGIN + left) / PAGE_W, 1 - (y_top + cell) / PAGE_H, w / PAGE_W, cell / PAGE_H]
            )
            for c in ax.collections:
                if len(c.get_offsets()) > DENSE_POINTS:
                    c.set_rasterized(True)
        self.y += height

    # ------------------------------------------------------------------------------ output

    def save(self, pdf_path: str | Path, text_path: str | Path | None = None) -> list[str]:
        """Number the pages, write the PDF (and the pages' text, spelled as the PDF spells it:
        :func:`pdf_text`); return the text per page. Ticks are stamped (:func:`stamp_ticks`) and
        long curves drawn through their envelope (:func:`thin_curves`) as each page is written."""
        n = len(self.pages)
        texts = []
        with (
            _font_weight_names_quiet(),
            _closed_pdf(pdf_path, {"Title": self.title, "Creator": "motionlab"}) as pdf,
        ):
            for i, fig in enumerate(self.pages, start=1):
                stamp_ticks(fig)
                thin_curves(fig)
                for t in fig.findobj(Text):  # tick labels are spelled as they are drawn
                    spelled = pdf_text(t.get_text())
                    if spelled != t.get_text():
                        t.set_text(spelled)
                put_text(
                    fig,
                    0.5,
                    0.35 / PAGE_H,
                    f"page {i} of {n}",
                    size=SIZE["small"],
                    color=MUTED,
                    ha="center",
                )
                texts.append(page_text(fig))
                pdf.savefig(fig, dpi=RASTER_DPI)  # the dpi of rasterised artists only
        if text_path is not None:
            Path(text_path).write_text("\f".join(texts), encoding="utf-8")
        return texts


@contextmanager
def _closed_pdf(path: str | Path, metadata: dict[str, str]) -> Iterator[PdfPages]:
    """``PdfPages`` closed at the end; when the writing fails or is interrupted (Ctrl-C) the
    half-written file is closed quietly and the first error stands: closing a page cut short
    raised "AssertionError: No offset for object 74", which replaced the interruption."""
    pdf = PdfPages(path, metadata=metadata)
    try:
        yield pdf
    except BaseException:
        with suppress(Exception):
            pdf.close()
        raise
    pdf.close()


@contextmanager
def _font_weight_names_quiet():
    """matplotlib's font finder warns that the standard Helvetica's regular weight is named
    ``medium`` where a text asks for ``normal`` (the same weight to a reader); keep it quiet."""
    log = logging.getLogger("matplotlib.font_manager")
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(level)


def _words(fig: Figure) -> list[tuple[float, float, str]]:
    """``(y, x, text)`` of the page's text, axes texts placed at their axes' top left (figure
    fraction); tick labels left out."""
    out = [(*t.get_position()[::-1], t.get_text()) for t in fig.texts]
    for ax in fig.axes:
        box = ax.get_position()
        texts = [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label]
        texts += ax.texts
        if ax.get_legend() is not None:
            texts += ax.get_legend().get_texts()
        out += [(box.y1, box.x0, t.get_text()) for t in texts]
    for legend in fig.legends:
        anchor = legend.get_bbox_to_anchor()
        y, x = anchor.y0 / fig.bbox.height, anchor.x0 / fig.bbox.width
        out += [(y, x, t.get_text()) for t in legend.get_texts()]
    return [(y, x, s) for y, x, s in out if s.strip()]


def page_text(fig: Figure) -> str:
    """The words on a page, top to bottom (tick numbers left out)."""
    return "\n".join(s for _, _, s in sorted(_words(fig), key=lambda w: (-round(w[0], 3), w[1])))


def layout_problems(fig: Figure) -> list[str]:
    """Text that leaves the page or overlaps other text (bounding boxes, 0.5 pt tolerance)."""
    unstamp_ticks(fig)  # every tick label its own text, placed by matplotlib
    fig.draw_without_rendering()  # places axis labels and legends
    renderer = fig.canvas.get_renderer()
    w, h = fig.bbox.width, fig.bbox.height
    boxes = []
    problems = []
    hidden = set()  # tick labels outside the axis range are not drawn
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            tol = 1e-9 * max(1.0, abs(hi - lo))
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not lo - tol <= tick.get_loc() <= hi + tol:
                    hidden.update({id(tick.label1), id(tick.label2)})
    found = fig.findobj(lambda a: isinstance(a, Text) and a.get_visible() and a.get_text())
    for t in [t for t in found if id(t) not in hidden]:
        bb = t.get_window_extent(renderer)
        if bb.x0 < -0.5 or bb.y0 < -0.5 or bb.x1 > w + 0.5 or bb.y1 > h + 0.5:
            problems.append(f"off the page: {t.get_text()!r}")
        boxes.append((t.get_text(), bb.shrunk(1.0, 0.9)))
    for (a, ba), (b, bb) in combinations(boxes, 2):
        if ba.overlaps(bb) and a.strip() and b.strip():
            problems.append(f"overlap: {a!r} / {b!r}")
    return problems
