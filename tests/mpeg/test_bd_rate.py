"""BD-rate (the CTC spreadsheet's bdRateExtend) against independent float64 references and the bjontegaard package.

References: on monotone curves the interpolant is scipy's ``PchipInterpolator`` (integrated exactly by scipy); on any
curve, scipy's ``CubicHermiteSpline`` with the spreadsheet's slopes written out here from its formulas. Both agree
with ``bd_rate`` to ~1e-12 % (float64 rounding of the two integrations), so the tolerance is 1e-9 %.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator

from torchmeshmetric.mpeg.ctc.bd_rate import bd_rate

TOL = 1e-9  # percent


def _ref(ra: Sequence[float], qa: Sequence[float], rb: Sequence[float], qb: Sequence[float], interp: str) -> float:
    def fit(r: Sequence[float], q: Sequence[float]) -> PchipInterpolator | CubicHermiteSpline:
        o = np.argsort(q)
        x, y = np.asarray(q, float)[o], np.log10(np.asarray(r, float))[o]
        if interp == "pchip":
            return PchipInterpolator(x, y)
        h, d = np.diff(x), np.diff(y) / np.diff(x)
        s = np.empty(x.size)
        s[1:-1] = 3 * (h[:-1] + h[1:]) / ((2 * h[1:] + h[:-1]) / d[:-1] + (h[1:] + 2 * h[:-1]) / d[1:])

        def end(h1: float, h2: float, d1: float, d2: float) -> float:
            e = ((2 * h1 + h2) * d1 - h1 * d2) / (h1 + h2)
            return (
                0.0
                if np.sign(e) != np.sign(d1)
                else (3 * d1 if np.sign(d1) != np.sign(d2) and abs(e) > abs(3 * d1) else e)
            )

        s[0], s[-1] = end(h[0], h[1], d[0], d[1]), end(h[-1], h[-2], d[-1], d[-2])
        return CubicHermiteSpline(x, y, s)

    lo, hi = max(min(qa), min(qb)), min(max(qa), max(qb))
    fa, fb = fit(ra, qa), fit(rb, qb)
    avg = (fb.integrate(lo, hi) - fa.integrate(lo, hi)) / (hi - lo)
    return 100 * (10**avg - 1)


MONOTONE = [
    ([1000, 2000, 4000, 8000], [30.1, 33.4, 36.2, 38.9], [900, 1900, 3900, 8100], [30.5, 33.9, 36.4, 39.3]),
    ([120, 260, 530, 1100, 2400], [61.2, 64.8, 68.1, 71.0, 73.2],
     [100, 240, 500, 1000, 2000], [60.9, 64.1, 67.9, 70.2, 72.6]),
    ([5, 9, 17, 31], [40, 44, 47.5, 49], [6, 10, 18, 33], [41.2, 44.9, 48.3, 50.1]),
]  # fmt: skip


@pytest.mark.parametrize("case", range(len(MONOTONE)))
def test_monotone_equals_pchip(case: int) -> None:
    """Monotone curves: equal to a PCHIP fit integrated exactly (scipy)."""
    ra, qa, rb, qb = MONOTONE[case]
    assert abs(bd_rate(ra, qa, rb, qb) - _ref(ra, qa, rb, qb, "pchip")) < TOL


@pytest.mark.parametrize("case", range(len(MONOTONE)))
def test_monotone_equals_bjontegaard(case: int) -> None:
    """The bjontegaard package's pchip BD-rate (a test oracle; skipped where it is not installed)."""
    bd = pytest.importorskip("bjontegaard")
    ra, qa, rb, qb = MONOTONE[case]
    theirs = bd.bd_rate(ra, qa, rb, qb, method="pchip", min_overlap=0)
    assert abs(bd_rate(ra, qa, rb, qb) - theirs) < 1e-6


def test_non_monotone_keeps_the_harmonic_slope() -> None:
    """A curve whose log-rate turns back: interior slopes without pchip's zero-slope rule (the spreadsheet's)."""
    ra, qa = [1000, 2000, 1800, 8000], [30.0, 33.0, 36.0, 39.0]
    rb, qb = [900, 1900, 3900, 8100], [30.5, 33.9, 36.4, 39.3]
    ours = bd_rate(ra, qa, rb, qb)
    assert abs(ours - _ref(ra, qa, rb, qb, "hermite")) < TOL
    assert abs(ours - _ref(ra, qa, rb, qb, "pchip")) > 1e-3  # pchip's zero slope: 0.0135 % away, >> TOL


def test_hand_checked_values() -> None:
    """Hand-checked: a curve at half the rate everywhere is -50 %; straight lines give the secant slopes."""
    a = [100.0, 200.0, 400.0, 800.0]
    q = [30.0, 33.0, 36.0, 39.0]
    assert abs(bd_rate(a, q, [r / 2 for r in a], q) + 50.0) < 1e-12
    assert abs(bd_rate(a, q, [r * 2 for r in a], q) - 100.0) < 1e-12
    # B: log10(rate) = log10(100) + (q - 30) / 10, i.e. 10^(1/10) x the rate per 1 dB -- integrated by hand against
    # A (log10(rate) = 2 + (q - 30) * log10(2) / 3) over [30, 39]: mean difference = 4.5 * (0.1 - log10(2) / 3)
    b = [100 * 10 ** ((x - 30) / 10) for x in q]
    expected = 100 * (10 ** (4.5 * (0.1 - math.log10(2) / 3)) - 1)
    assert abs(bd_rate(a, q, b, q) - expected) < 1e-10


def test_two_points_are_not_pchip() -> None:
    """Two rate points: the spreadsheet's missing neighbours read as 0 (empty cells), so both end slopes are twice
    the secant (pchipend(h, 0, d, 0) = 2 d), an S-shaped cubic, not PCHIP's straight line. Measured (review B #5):
    two straight lines in log-rate give -18.5222 % where PCHIP, scipy and the bjontegaard package give -19.8191 %
    (10^(log10 0.9 - (0.5 / 3) log10 2) - 1). Reference: scipy's CubicHermiteSpline with slopes 2 d, exactly."""
    ra, qa, rb, qb = [1000, 2000], [30.0, 33.0], [900, 1800], [30.5, 33.5]
    lo, hi = 30.5, 33.0

    def spline(r: list[int], q: list[float], k: float) -> CubicHermiteSpline:
        y = np.log10(np.asarray(r, float))
        d = (y[1] - y[0]) / (q[1] - q[0])
        return CubicHermiteSpline(np.asarray(q), y, [k * d, k * d])

    def ref(k: float) -> float:
        return 100 * (10 ** ((spline(rb, qb, k).integrate(lo, hi) - spline(ra, qa, k).integrate(lo, hi)) / 2.5) - 1)

    ours = bd_rate(ra, qa, rb, qb)
    assert abs(ours - ref(2.0)) < TOL and abs(ours - (-18.522230687968)) < 1e-9
    straight = 100 * (10 ** (math.log10(0.9) - (0.5 / 3) * math.log10(2)) - 1)
    assert abs(ref(1.0) - straight) < TOL and abs(_ref(ra, qa, rb, qb, "pchip") - straight) < TOL  # PCHIP: a line
    assert abs(ours - straight) > 1.29  # -18.52 % against -19.82 %


def test_no_overlap_and_bad_input() -> None:
    """Disjoint PSNR ranges give +-100 %, as bdRateExtend; typed errors name the argument."""
    assert bd_rate([1, 2, 3], [40, 41, 42], [1, 2, 3], [30, 31, 32]) == 100.0
    assert bd_rate([1, 2, 3], [30, 31, 32], [1, 2, 3], [40, 41, 42]) == -100.0
    with pytest.raises(ValueError, match="rate_a/psnr_a: point 1: expected a positive finite rate"):
        bd_rate([1, -2, 3], [30, 31, 32], [1, 2, 3], [30, 31, 32])
    with pytest.raises(ValueError, match="rate_b/psnr_b: point 2: expected a finite PSNR"):
        bd_rate([1, 2, 3], [30, 31, 32], [1, 2, 3], [30, 31, math.inf])
    with pytest.raises(ValueError, match="as many rates"):
        bd_rate([1, 2], [30, 31, 32], [1, 2, 3], [30, 31, 32])
    with pytest.raises(ValueError, match="at least 2 points"):
        bd_rate([1, 1], [30, 30], [1, 2, 3], [30, 31, 32])
    # spreadsheet conventions: (0, 0) rows are empty cells; points in any order
    assert bd_rate([4, 1, 0, 2], [32, 30, 0, 31], [1, 2, 4], [30, 31, 32]) == pytest.approx(0.0, abs=1e-12)
