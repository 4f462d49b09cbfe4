"""Decimal text to float32, correctly rounded (:mod:`torchmeshmetric._float32_text`): against exact rational
rounding on decimals at, just past and just short of float32 midpoints (normal, subnormal, the overflow threshold),
where float64-then-float32 rounds twice (review S)."""

from __future__ import annotations

from decimal import Decimal, getcontext
from fractions import Fraction

import numpy as np

from torchmeshmetric._float32_text import float32_from_text, float32_midpoints, float32_of_texts

_MAX = np.finfo(np.float32).max


def _exact(text: str) -> np.float32:
    """The float32 nearest the decimal (ties to even; beyond FLT_MAX + half an ulp: infinity), by rationals."""
    e = Fraction(text)
    limit = Fraction(float(_MAX)) + Fraction(2**103)
    if abs(e) >= limit:
        return np.float32(np.copysign(np.inf, float(e)))  # at the threshold: ties to "even" infinity
    with np.errstate(over="ignore"):
        a = np.float32(float(e))
    if not np.isfinite(a):
        a = np.float32(np.copysign(_MAX, float(e)))
    with np.errstate(over="ignore"):
        near = [a, np.nextafter(a, np.float32(-np.inf)), np.nextafter(a, np.float32(np.inf))]
    near = [c for c in near if np.isfinite(c)]
    return min(near, key=lambda c: (abs(Fraction(float(c)) - e), int(np.array(c).view(np.uint32)) & 1))


def _texts(seed: int) -> list[str]:
    getcontext().prec = 80
    rng = np.random.default_rng(seed)
    magnitudes = np.concatenate(
        [10.0 ** rng.uniform(-37, 38, 300), rng.uniform(0, 1.2e-38, 100), [float(_MAX), 1.4e-45, 1.0, 0.1]]
    )
    texts = []
    for m in magnitudes * rng.choice([-1.0, 1.0], magnitudes.size):
        f = np.float32(min(m, float(_MAX)))
        with np.errstate(over="ignore"):
            g = np.nextafter(f, np.float32(np.inf))
        hi = Decimal(float(g)) if np.isfinite(g) else Decimal(float(_MAX)) + Decimal(2) ** 104  # 2^128
        mid = (Decimal(float(f)) + hi) / 2
        for d in (mid, mid + mid.copy_abs() * Decimal("1e-40"), mid - mid.copy_abs() * Decimal("1e-40")):
            texts.append(str(d))
    return texts


def test_correct_rounding_at_midpoints() -> None:
    texts = _texts(0)
    values = np.array([float(t) for t in texts])
    out = float32_of_texts(values, lambda i: texts[i])
    with np.errstate(over="ignore"):
        want = np.array([_exact(t) for t in texts], np.float32)
        assert np.array_equal(out.view(np.uint32), want.view(np.uint32))
        assert (values.astype(np.float32) != want).sum() > 100  # float64 first is wrong for many of them


def test_scalars_and_shapes() -> None:
    assert float(float32_from_text("0.100000012665987014770507812501")) == 0.10000001639127731
    assert float(float32_from_text("0.100000005215406417846679687499")) == float(np.float32(0.1))
    assert float32_from_text("3.40282356779733661637539395458142568447e38") == _MAX  # just short of overflow
    assert np.isinf(float32_from_text("3.40282356779733661637539395458142568449e38"))
    assert float32_of_texts(np.zeros((2, 3)), lambda i: "0").shape == (2, 3)
    assert float32_midpoints(np.array([np.nan, np.inf, 0.0, 1.0])).size == 0
