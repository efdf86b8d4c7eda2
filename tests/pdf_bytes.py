"""A figure's page as PDF bytes that two ways of drawing it can be compared by: the report's
settings, uncompressed, without a creation date."""

import io
from collections.abc import Callable

import matplotlib
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from motionlab.report.pdf import RC


def pdf_bytes(draw: Callable[[], Figure]) -> bytes:
    """The one-page PDF of the figure ``draw()`` makes under the report's settings."""
    with matplotlib.rc_context({**RC, "pdf.compression": 0}):
        fig = draw()
        buf = io.BytesIO()
        with PdfPages(buf, metadata={"CreationDate": None}) as pdf:
            pdf.savefig(fig)
    return buf.getvalue()
