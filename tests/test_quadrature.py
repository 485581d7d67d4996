"""Chebyshev series evaluation (hzd/quadrature.py): ``cos(k arccos x) @ coef`` against
numpy's Clenshaw recurrence (``chebval``), inside, at and next to the interval ends (to
1e-13 of the sum of |coefficients|: the rounding of arccos grows with k near x = +-1)."""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev

from thrustwalk_cli.hzd.quadrature import ChebSeries


def test_fast_evaluation_equals_chebval_including_the_ends():
    rng = np.random.default_rng(11)
    a, b = 0.27, -0.31  # alpha may decrease over a step
    for n, trailing in ((65, ()), (257, (3,)), (4097, ())):
        coef = rng.normal(size=(n,) + trailing) / (1 + np.arange(n)).reshape((n,) + (1,) *
                                                                              len(trailing))
        series = ChebSeries(a, b, coef)
        eps = np.finfo(float).eps
        t = np.concatenate([[a, b, a + 4 * eps * np.sign(b - a), b - 4 * eps * np.sign(b - a)],
                            rng.uniform(min(a, b), max(a, b), 200)])
        x = (2 * t - (a + b)) / (b - a)
        ref = np.moveaxis(np.asarray(chebyshev.chebval(x, coef, tensor=True)), -1, 0)
        scale = np.abs(coef).sum(axis=0).max()
        np.testing.assert_allclose(series(t), ref, rtol=0, atol=1e-13 * scale,
                                   err_msg=f"n = {n}")
        assert series(np.array(a)).shape == trailing


def test_outside_the_interval_falls_back_to_chebval():
    coef = np.array([1.0, 2.0, 3.0])
    series = ChebSeries(0.0, 1.0, coef)
    t = np.array([1.5, -0.2])
    np.testing.assert_allclose(series(t), chebyshev.chebval(2 * t - 1, coef), rtol=1e-15)
