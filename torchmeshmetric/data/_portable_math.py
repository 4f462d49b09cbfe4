"""Elementary functions that give the same bits on every CPU: what the built-in sequence is computed with.

numpy's ``exp``/``log``/``sin``/``cos`` and its BLAS-backed ``@``/``einsum`` are dispatched per instruction set
(SSE, AVX2, AVX-512 kernels, FMA or not) and differ in their last bits from one CPU to the next; the built-in
frames, meshed from a field, moved by float32 ulps between machines, and every figure computed on them with them
(issue 38). These functions use only operations that IEEE 754 defines to the bit — ``+ - * /``, ``sqrt``, ``rint``,
``ldexp``, ``frexp`` — elementwise and in a fixed order, so their results are identical wherever numpy runs. They are
not correctly rounded (within ~2 ulps of the exact value), which is all a generator needs: the same input, the same
output, everywhere.

Algorithms: Cody & Waite's argument reduction (Cody and Waite, *Software Manual for the Elementary Functions*, 1980)
followed by a Taylor polynomial in Horner form (exp, sin, cos) and the ``atanh`` series of the reduced mantissa (log).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["cos_deg", "dot3", "exp", "log", "matmul3", "matvec3", "sin_deg"]

# ln 2 split so that n * _LN2_HI is exact for |n| < 2**11 (_LN2_HI has 32 trailing zero bits), as in fdlibm.
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e00
_SQRT_HALF = math.sqrt(0.5)
# Taylor coefficients 1/k! for exp on |r| <= ln(2)/2 (the k = 14 term is below 2**-60 there).
_EXP_COEF = tuple(1.0 / math.factorial(k) for k in range(15))
# 1/(2k+1) for the atanh series of log: |s| <= 0.1716 on the reduced mantissa, s**24/25 < 2**-62.
_LOG_COEF = tuple(1.0 / (2 * k + 1) for k in range(12))


def _horner(x: np.ndarray, coef: tuple[float, ...]) -> np.ndarray:
    """``sum_k coef[k] * x**k`` by Horner's rule (highest degree first, a fixed order of roundings)."""
    acc = np.full_like(x, coef[-1])
    for c in reversed(coef[:-1]):
        acc = acc * x + c
    return acc


def exp(x: np.ndarray) -> np.ndarray:
    """``e**x`` elementwise, float64, the same bits on every CPU (within 2 ulps of the exact value).

    Args:
        x: float64 array; values below -745 give 0 and above 709 give ``inf``, as ``numpy.exp``.

    Example:
        >>> float(abs(exp(np.array([1.0]))[0] - math.e)) < 1e-15
        True
    """
    x = np.asarray(x, dtype=np.float64)
    n = np.rint(np.clip(np.where(np.isfinite(x), x, 0.0), -1100.0, 1100.0) * _INV_LN2)
    r = (x - n * _LN2_HI) - n * _LN2_LO  # |r| <= ln(2)/2 (plus rounding)
    # ldexp of the polynomial by n in two steps so that 2**n alone never overflows or underflows early.
    half = np.trunc(n / 2.0)
    with np.errstate(over="ignore", under="ignore"):  # inf and 0 are the answers there, as numpy.exp's
        out = np.ldexp(np.ldexp(_horner(r, _EXP_COEF), half.astype(np.int64)), (n - half).astype(np.int64))
    return np.where(np.isfinite(x), out, np.where(x > 0, np.inf, np.where(x < 0, 0.0, x)))  # inf, 0, nan


def log(x: np.ndarray) -> np.ndarray:
    """Natural logarithm elementwise for positive finite float64 values, the same bits on every CPU.

    ``x = m * 2**e`` with ``m`` in ``[sqrt(1/2), sqrt(2))`` (``frexp`` is exact); ``log m = 2 atanh(s)`` with
    ``s = (m - 1) / (m + 1)``; ``log x = e ln 2 + log m``.

    Args:
        x: float64 array of positive finite values (the caller guarantees it: no NaN/inf handling here).

    Example:
        >>> float(abs(log(np.array([10.0]))[0] - math.log(10.0))) < 1e-15
        True
    """
    x = np.asarray(x, dtype=np.float64)
    m, e = np.frexp(x)  # m in [0.5, 1)
    low = m < _SQRT_HALF
    m = np.where(low, m * 2.0, m)
    e = (e - low).astype(np.float64)
    s = (m - 1.0) / (m + 1.0)
    log_m = 2.0 * s * _horner(s * s, _LOG_COEF)
    return e * _LN2_HI + (log_m + e * _LN2_LO)


def _sin_cos_reduced(deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadrant ``q`` (mod 4) and sine, cosine of ``deg - 90 q`` (in ``[-45, 45]`` degrees) by Taylor series."""
    deg = np.asarray(deg, dtype=np.float64)
    q = np.rint(deg / 90.0)
    r = (deg - 90.0 * q) * (math.pi / 180.0)  # |r| <= pi/4: the degree-21 terms are below 2**-60
    r2 = r * r
    sin_r = r * _horner(r2, tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(11)))
    cos_r = _horner(r2, tuple((-1.0) ** k / math.factorial(2 * k) for k in range(11)))
    return np.mod(q, 4.0), sin_r, cos_r


def sin_deg(deg: np.ndarray) -> np.ndarray:
    """Sine of angles in degrees, float64, the same bits on every CPU (exact multiples of 90 exact).

    Example:
        >>> sin_deg(np.array([30.0, 90.0, 270.0])).round(15).tolist()
        [0.5, 1.0, -1.0]
    """
    q, s, c = _sin_cos_reduced(deg)
    return np.select([q == 0, q == 1, q == 2], [s, c, -s], -c)


def cos_deg(deg: np.ndarray) -> np.ndarray:
    """Cosine of angles in degrees, float64, the same bits on every CPU.

    Example:
        >>> cos_deg(np.array([60.0, 180.0])).round(15).tolist()
        [0.5, -1.0]
    """
    q, s, c = _sin_cos_reduced(deg)
    return np.select([q == 0, q == 1, q == 2], [c, -s, -c], s)


def dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., 3) . (..., 3) -> (...)`` as ``a0 b0 + a1 b1 + a2 b2`` in that order (no BLAS, no FMA)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def matvec3(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(..., 3, 3) @ (..., 3) -> (..., 3)`` in a fixed order of roundings (broadcasting as numpy)."""
    return dot3(m, v[..., None, :])


def matmul3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., 3, 3) @ (..., 3, 3) -> (..., 3, 3)`` in a fixed order of roundings (broadcasting as numpy)."""
    return dot3(a[..., :, None, :], np.swapaxes(b, -1, -2)[..., None, :, :])
