"""Bjontegaard delta rate as the MPEG CTC spreadsheets compute it (their VBA function ``bdRateExtend``).

Each curve is a set of ``(rate, PSNR)`` points. ``log10(rate)`` is fitted as a piecewise cubic Hermite function of
PSNR: interior slopes are the weighted harmonic mean of the neighbouring secant slopes
``(3 h0 + 3 h1) / ((2 h1 + h0) / d0 + (h1 + 2 h0) / d1)`` (Fritsch-Carlson / Moler's ``pchip`` weights, but *without*
``pchip``'s zero slope where the secants change sign), end slopes the three-point formula with ``pchip``'s two end
rules (zero when its sign differs from the first secant's, ``3 d0`` when the secants change sign and it exceeds
that). Both curves are integrated exactly over the PSNR range where they overlap, and the BD-rate is
``10^((int B - int A) / (PSNR range)) - 1``, in percent. Curves that do not overlap give ``+100`` (A entirely above B
in PSNR) or ``-100``; an average log-rate difference above 10 gives ``+100``. Points with rate and PSNR both 0 are
ignored (the spreadsheet's empty cells); points are sorted by PSNR and repeated points dropped.

On monotone curves of 3 points or more the interpolant equals ``scipy.interpolate.PchipInterpolator`` and the
result the ``bjontegaard`` package's ``bd_rate(..., method="pchip")``. With 2 points it does not: the spreadsheet's
missing neighbours read as 0 (empty cells), so both end slopes are twice the secant (an S-shaped cubic where PCHIP
draws the secant line). Two straight lines in log-rate, ``(1000, 30), (2000, 33)`` against
``(900, 30.5), (1800, 33.5)``, give -18.5222 % here, as the sheet's formula, and -19.8191 % with PCHIP.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["bd_rate"]


def _real(value: object, name: str, i: int, what: str) -> float:
    # float() would take "3" and answer None with its own message: a number is asked for, by name and point
    if isinstance(value, (str, bytes, bool)) or value is None:
        raise TypeError(f"{name}: point {i}: expected a real {what}, found {value!r}")
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise TypeError(f"{name}: point {i}: expected a real {what}, found {value!r}") from None


def _points(rate: Sequence[float], psnr: Sequence[float], name: str) -> tuple[list[float], list[float]]:
    if len(rate) != len(psnr):
        raise ValueError(f"{name}: expected as many rates as PSNR values, found {len(rate)} and {len(psnr)}")
    pts = []
    for i, (r, q) in enumerate(zip(rate, psnr, strict=True)):
        r, q = _real(r, name, i, "rate"), _real(q, name, i, "PSNR")
        if r == 0 and q == 0:  # an empty spreadsheet cell
            continue
        if not (math.isfinite(r) and r > 0):
            raise ValueError(f"{name}: point {i}: expected a positive finite rate, found {r!r}")
        if not math.isfinite(q):
            raise ValueError(f"{name}: point {i}: expected a finite PSNR, found {q!r} (clip identical frames first)")
        pts.append((q, math.log10(r)))
    pts.sort(key=lambda p: p[0])  # stable, as the spreadsheet's bubble sort
    kept = [p for k, p in enumerate(pts) if k == 0 or p != pts[k - 1]]
    if len(kept) < 2 or len({q for q, _ in kept}) != len(kept):
        raise ValueError(f"{name}: expected at least 2 points with distinct PSNR values, found {[q for q, _ in kept]}")
    return [q for q, _ in kept], [r for _, r in kept]


def _end_slope(h1: float, h2: float, d1: float, d2: float) -> float:
    d = ((2 * h1 + h2) * d1 - h1 * d2) / (h1 + h2)
    if d * d1 < 0:
        return 0.0
    if d1 * d2 < 0 and abs(d) > abs(3 * d1):
        return 3 * d1
    return d


def _integral(x: list[float], y: list[float], low: float, high: float) -> float:
    """The spreadsheet's ``intCurve``: the Hermite interpolant of ``(x, y)`` integrated over ``[low, high]``."""
    n = len(x)
    h = [x[i + 1] - x[i] for i in range(n - 1)]
    delta = [(y[i + 1] - y[i]) / h[i] for i in range(n - 1)]
    # with two points the spreadsheet's missing neighbours read as 0 (empty VBA cells)
    h_at = lambda i: h[i] if 0 <= i < n - 1 else 0.0  # noqa: E731
    d_at = lambda i: delta[i] if 0 <= i < n - 1 else 0.0  # noqa: E731
    d = [0.0] * n
    d[0] = _end_slope(h_at(0), h_at(1), d_at(0), d_at(1))
    for i in range(1, n - 1):
        a, b = delta[i - 1], delta[i]
        if a == 0 or b == 0:  # the harmonic mean's limit (the spreadsheet divides by zero)
            d[i] = 0.0
        else:
            d[i] = (3 * h[i - 1] + 3 * h[i]) / ((2 * h[i] + h[i - 1]) / a + (h[i] + 2 * h[i - 1]) / b)
    d[n - 1] = _end_slope(h_at(n - 2), h_at(n - 3), d_at(n - 2), d_at(n - 3))
    result = 0.0
    for i in range(n - 1):
        c = (3 * delta[i] - 2 * d[i] - d[i + 1]) / h[i]
        b = (d[i] - 2 * delta[i] + d[i + 1]) / (h[i] * h[i])
        s0 = min(max(x[i], low), high) - x[i]
        s1 = min(max(x[i + 1], low), high) - x[i]
        if s1 > s0:
            result += (s1 - s0) * y[i]
            result += (s1 * s1 - s0 * s0) * d[i] / 2
            result += (s1**3 - s0**3) * c / 3
            result += (s1**4 - s0**4) * b / 4
    return result


def bd_rate(
    rate_a: Sequence[float], psnr_a: Sequence[float], rate_b: Sequence[float], psnr_b: Sequence[float]
) -> float:
    """BD-rate of curve B against anchor A in percent (negative: B needs less rate), as ``bdRateExtend``.

    Args:
        rate_a: the anchor's rates (any unit, > 0).
        psnr_a: its PSNR values (dB), one per rate.
        rate_b: the tested curve's rates.
        psnr_b: its PSNR values.

    Returns:
        The BD-rate in percent; ``+-100`` when the PSNR ranges do not overlap.

    Raises:
        ValueError: unequal lengths, fewer than 2 points, a non-positive rate or a non-finite PSNR.
        TypeError: a rate or PSNR that is not a real number (a string, ``None``).

    Example:
        >>> a = [100, 200, 400, 800]
        >>> round(bd_rate(a, [30, 33, 36, 39], [r / 2 for r in a], [30, 33, 36, 39]), 9)
        -50.0
    """
    xa, ya = _points(rate_a, psnr_a, "rate_a/psnr_a")
    xb, yb = _points(rate_b, psnr_b, "rate_b/psnr_b")
    if xa[0] > xb[-1]:
        return 100.0
    if xb[0] > xa[-1]:
        return -100.0
    low, high = max(xa[0], xb[0]), min(xa[-1], xb[-1])
    if high <= low:  # the curves touch at one PSNR value: no range to average over
        raise ValueError(f"psnr: the two curves overlap only at {low} dB; BD-rate needs a PSNR range")
    avg = (_integral(xb, yb, low, high) - _integral(xa, ya, low, high)) / (high - low)
    return 100.0 * (10.0**avg - 1.0) if avg <= 10 else 100.0
