"""Levenberg-Marquardt with an analytic Jacobian: MINPACK's ``lmder`` through scipy's ``leastsq``.

``scipy.optimize.least_squares(fun, x0, jac=jac, method="lm")`` hands the problem to the same
MINPACK routine (``lmder``, Moré 1978), but wraps every evaluation in its ``VectorFunction``
(copies, array comparisons, a cache): on the small fits of the run (4-14 parameters, 2 000-20 000
residuals, tens of evaluations each) that wrapper took as long as the residuals themselves.
:func:`lm` calls ``scipy.optimize.leastsq`` with the arguments ``least_squares`` gives ``lmder``
(its tolerances 1e-8, ``factor`` 100, ``diag`` = 1 / ``x_scale``, none for scipy's default
``x_scale="jac"``, at most ``max_nfev`` evaluations, 100 × the parameters by default), so the
iterates are the same numbers (``tests/test_minpack.py``); the residuals and the Jacobian
at ``x0``, which ``leastsq`` asks for twice, are computed once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import leastsq

TOLERANCE = 1e-8  # least_squares' ftol, xtol and gtol


@dataclass
class LMResult:
    """``x`` the solution, ``fun`` the residuals there, ``cost`` half their sum of squares (as
    ``least_squares`` reports it), ``nfev`` the evaluations, ``status`` MINPACK's ``info``."""

    x: np.ndarray
    fun: np.ndarray
    cost: float
    nfev: int
    status: int


def lm(
    fun: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    jac: Callable[[np.ndarray], np.ndarray],
    x_scale: float | np.ndarray | None = None,
    max_nfev: int | None = None,
) -> LMResult:
    """Minimise ``Σ fun(x)²`` from ``x0`` (n,), ``jac(x)`` the (m, n) Jacobian of ``fun(x)``
    (m,); ``x_scale`` each parameter's characteristic size (``None``: MINPACK scales by the
    Jacobian's columns); the same iterates as ``least_squares(..., method="lm")``."""
    x0 = np.atleast_1d(np.asarray(x0, dtype=float))
    diag = None
    if x_scale is not None:
        diag = 1 / np.resize(np.asarray(x_scale, dtype=float), x0.shape)
    x, _, info, _, status = leastsq(
        _once_at(fun, x0), x0, Dfun=_once_at(jac, x0), full_output=True, ftol=TOLERANCE,
        xtol=TOLERANCE, gtol=TOLERANCE, maxfev=max_nfev or 100 * x0.size, diag=diag,
    )  # fmt: skip
    f = info["fvec"]
    return LMResult(x, f, 0.5 * float(np.dot(f, f)), int(info["nfev"]), int(status))


def _once_at(f: Callable[[np.ndarray], np.ndarray], x0: np.ndarray):
    """``f`` with its value at ``x0`` computed once: ``leastsq`` calls ``f`` and the Jacobian
    there to check their shapes, and MINPACK then starts from the same point."""
    start: list[np.ndarray] = []

    def at(x: np.ndarray) -> np.ndarray:
        if not np.array_equal(x, x0):
            return f(x)
        if not start:
            start.append(f(x))
        return start[0]

    return at
