"""The exact-rounding helpers of tests/reference.py, against what rounds correctly by definition."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.reference import fma, round_to_binary

finite64 = st.floats(min_value=-1e100, max_value=1e100, allow_nan=False, allow_infinity=False).filter(
    lambda x: x == 0 or abs(x) > 1e-100
)
finite32 = st.floats(min_value=-1e10, max_value=1e10, width=32).filter(lambda x: x == 0 or abs(x) > 1e-10)


@settings(max_examples=200, deadline=None)  # no timing limit: CI's 2 cores are shared (as every test here)
@given(finite64, finite64, finite64)
def test_float64_rounding_is_pythons_correctly_rounded_fraction(a: float, b: float, c: float) -> None:
    q = Fraction(a) * Fraction(b) + Fraction(c)
    assert round_to_binary(q, np.float64) == float(q)  # int / int true division rounds correctly (CPython)


@settings(max_examples=200, deadline=None)
@given(finite32, finite32, finite32)
def test_float32_rounding_is_the_nearest_float32(a: float, b: float, c: float) -> None:
    q = Fraction(a) * Fraction(b) + Fraction(c)
    r = fma(a, b, c, np.float32)
    assert np.float32(r) == r  # representable
    if q == 0:
        assert r == 0
        return
    up, down = (float(np.nextafter(np.float32(r), np.float32(s * np.inf))) for s in (1, -1))
    err = abs(q - Fraction(r))
    assert err <= abs(q - Fraction(up)) and err <= abs(q - Fraction(down))
    if err == abs(q - Fraction(up)) or err == abs(q - Fraction(down)):  # a tie goes to the even significand
        assert int(np.float32(r).view(np.int32)) % 2 == 0


def test_ties_go_to_even_and_double_rounding_is_avoided() -> None:
    one = Fraction(1)
    half_ulp = Fraction(1, 2**24)
    assert round_to_binary(one + half_ulp, np.float32) == 1.0  # tie, 1.0 is even
    assert round_to_binary(one + 3 * half_ulp, np.float32) == 1.0 + 2.0**-22  # tie, up to the even one
    # just above a tie: float64 first would round to the tie, then float32 to even (down): twice rounded, wrong
    q = one + half_ulp + Fraction(1, 2**60)
    assert float(np.float32(float(q))) == 1.0
    assert round_to_binary(q, np.float32) == 1.0 + 2.0**-23
