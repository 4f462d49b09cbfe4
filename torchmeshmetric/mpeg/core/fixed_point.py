"""mmetric's 16-bit fixed point (``--useFixedPoint``): values rounded to multiples of 1/65536, exactly in float32."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["fixed_point_box", "fixed_point_ceil"]

_FP16 = np.float32(1 << 16)


def fixed_point_ceil(x: np.ndarray | np.floating[Any]) -> np.ndarray:
    """Round float32 values up to a multiple of 1/65536 (mmetric's 16-bit fixed point; exact in float32).

    Example:
        >>> float(fixed_point_ceil(np.float32(0.1)) * 65536)
        6554.0
    """
    return (np.ceil(np.asarray(x, np.float32) * _FP16) / _FP16).astype(np.float32)


def fixed_point_box(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``--useFixedPoint`` box of mmetric: min corner rounded down, max corner up, to multiples of 1/65536.

    The products by 65536 and the quotients are exact in float32, so this equals mmetric's float32 arithmetic.

    Example:
        >>> lo, hi = fixed_point_box(np.float32([-0.1, 0, 0.1]), np.float32([0.1, 1, -0.05]))
        >>> (lo * 65536).tolist(), (hi * 65536).tolist()
        ([-6554.0, 0.0, 6553.0], [6554.0, 65536.0, -3276.0])
    """
    lo32, hi32 = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    return (np.floor(lo32 * _FP16) / _FP16).astype(np.float32), fixed_point_ceil(hi32)
