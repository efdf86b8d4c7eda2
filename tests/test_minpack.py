"""motionlab.minpack.lm: the iterates of ``least_squares(method="lm")``, to the bit."""

import numpy as np
from scipy.optimize import least_squares

from motionlab.minpack import lm


def _problem():
    """A damped oscillation fitted to noisy samples: 4 parameters, 400 residuals."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 4.0, 400)
    truth = np.array([1.5, 0.7, 6.0, 0.3])

    def model(p):
        return p[0] * np.exp(-p[1] * t) * np.sin(p[2] * t + p[3])

    y = model(truth) + 0.05 * rng.normal(size=t.size)

    def fun(p):
        return model(p) - y

    def jac(p):
        e, s, c = np.exp(-p[1] * t), np.sin(p[2] * t + p[3]), np.cos(p[2] * t + p[3])
        return np.column_stack([e * s, -t * p[0] * e * s, t * p[0] * e * c, p[0] * e * c])

    return fun, jac, np.array([1.0, 0.5, 5.8, 0.0])


def test_same_numbers_as_least_squares():
    fun, jac, x0 = _problem()
    for kwargs in ({}, {"x_scale": 0.1}, {"x_scale": np.array([1.0, 0.1, 0.5, 0.01])},
                   {"max_nfev": 3}):  # fmt: skip
        ref = least_squares(fun, x0, jac=jac, method="lm", **kwargs)
        got = lm(fun, x0, jac, **kwargs)
        assert np.array_equal(got.x, ref.x), kwargs
        assert np.array_equal(got.fun, ref.fun)
        assert got.cost == ref.cost
        assert got.nfev == ref.nfev
    assert abs(lm(fun, x0, jac).x[2] - 6.0) < 0.05  # and it fits


def test_no_more_evaluations_than_least_squares():
    """leastsq checks the shapes at x0 before MINPACK starts there: computed once."""
    fun, jac, x0 = _problem()
    counts = {}

    def counted(f, name):
        def g(x):
            counts[name] = counts.get(name, 0) + 1
            return f(x)

        return g

    least_squares(counted(fun, "ls f"), x0, jac=counted(jac, "ls J"), method="lm")
    lm(counted(fun, "lm f"), x0, counted(jac, "lm J"))
    assert counts["lm f"] <= counts["ls f"] and counts["lm J"] <= counts["ls J"], counts
