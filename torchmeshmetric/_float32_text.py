"""Decimal text to float32, correctly rounded, as C's ``strtof`` reads it (mmetric's PLY reader, its ``--epsilon``).

Parsing to float64 and then rounding to float32 rounds twice: a decimal just past a float32 midpoint first rounds to
the midpoint itself (in float64), and ties-to-even then picks the wrong neighbour. ``0.100000012665987014770507812501``
is correctly 0.10000001639 in float32, but 0.10000000894 through float64 (review S). numpy parses text to float32
through float64 too (``np.float32("...")``, ``astype``), so it rounds twice as well.

Double rounding errs only where the float64 value lies *exactly* on a float32 midpoint (a float64 that is not one
rounds to the float32 the decimal rounds to). Those are found vectorised and re-rounded from their text, exactly,
with :class:`fractions.Fraction`: a handful of values in practice, none in most files. Subnormal float32 results
(midpoints are odd multiples of 2^-150) and the overflow threshold (FLT_MAX + half an ulp, which ties to infinity)
are midpoints like any other here, as the test is against the two float32 neighbours themselves.

The standard library and numpy only: the ``mpeg`` command's options use it before torch is imported.
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction

import numpy as np

__all__ = ["float32_from_text", "float32_midpoints", "float32_of_texts"]

_BEYOND = 2.0**128  # where float32's next value would be after FLT_MAX: infinity's place when rounding


def float32_midpoints(x: np.ndarray) -> np.ndarray:
    """Indices (flat) of the float64 values ``x`` that lie exactly on a float32 midpoint (where rounding x errs).

    Example:
        >>> a = np.float64(np.float32(0.1)); b = np.float64(np.nextafter(np.float32(0.1), np.float32(1)))
        >>> float32_midpoints(np.array([0.1, (a + b) / 2, 1.0])).tolist()
        [1]
    """
    flat = np.asarray(x, dtype=np.float64).reshape(-1)
    with np.errstate(over="ignore"):
        f = flat.astype(np.float32)
    back = f.astype(np.float64)
    # quick filter: a midpoint has its low 29 mantissa bits 1 then zeros (normal float32 range); subnormal float32
    # results and overflow are checked in full (rare)
    bits = flat.view(np.uint64)
    tiny_or_huge = (np.abs(flat) < 2.0**-126) | np.isinf(back)
    near = np.flatnonzero(((bits & 0x1FFFFFFF) == 0x10000000) | tiny_or_huge)
    near = near[np.isfinite(flat[near]) & (flat[near] != back[near])]
    if not near.size:
        return near
    v, fv = flat[near], f[near]
    with np.errstate(over="ignore"):
        away = np.nextafter(fv, np.where(v > back[near], np.float32(np.inf), np.float32(-np.inf)))
    here = np.where(np.isinf(fv), np.copysign(_BEYOND, v), back[near])  # infinity stands at +-2^128
    there = np.where(np.isinf(away), np.copysign(_BEYOND, v), away.astype(np.float64))
    return near[v == (here + there) / 2]  # exact: float32 neighbours and their midpoint fit a float64


def _round_exact(text: str, approx: float) -> np.float32:
    """The float32 nearest the decimal ``text`` (ties to even), given ``approx``: its float64 (a float32 midpoint)."""
    try:
        exact = Fraction(text.strip())
    except (ValueError, ZeroDivisionError):  # hexadecimal or other notation numpy accepted: as numpy rounds it
        with np.errstate(over="ignore"):
            return np.float32(approx)
    mid = Fraction(approx)
    with np.errstate(over="ignore"):
        f = np.float32(approx)  # ties to even: one of approx's two float32 neighbours (infinity beyond FLT_MAX)
    if exact == mid:
        return f  # a true tie: ties-to-even is right
    with np.errstate(over="ignore"):
        if float(f) > approx:
            lo, hi = np.nextafter(f, np.float32(-np.inf)), f
        else:
            lo, hi = f, np.nextafter(f, np.float32(np.inf))
    return hi if exact > mid else lo


def float32_of_texts(values: np.ndarray, text: Callable[[int], str]) -> np.ndarray:
    """``values`` (float64, parsed from decimal text) as float32, each the correctly rounded float32 of its text.

    Args:
        values: the float64 parse of the texts, any shape.
        text: the text of the value at a flat index (asked only for the values on a float32 midpoint).

    Example:
        >>> s = "0.100000012665987014770507812501"
        >>> float(np.float64(s).astype(np.float32)), float(float32_of_texts(np.array([float(s)]), lambda i: s)[0])
        (0.10000000894069672, 0.10000001639127731)
    """
    x = np.asarray(values, dtype=np.float64)
    with np.errstate(over="ignore"):
        out = x.astype(np.float32)
    flat = out.reshape(-1)
    for i in float32_midpoints(x).tolist():
        flat[i] = _round_exact(text(i), float(x.reshape(-1)[i]))
    return out


def float32_from_text(text: str) -> np.float32:
    """One decimal text as float32, correctly rounded (``strtof``); an argparse ``type`` for mmetric's float options.

    Raises:
        ValueError: ``text`` is not a number (Python's ``float`` syntax).

    Example:
        >>> float(float32_from_text("0.100000012665987014770507812501"))
        0.10000001639127731
    """
    x = float(text)
    return float32_of_texts(np.array([x]), lambda _: text)[0]
