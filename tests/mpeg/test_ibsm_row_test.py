"""The identity behind IBSM's row test of the third edge (``native/ibsm_raster.cpp``, ``draw_band``).

The rasterizer drops a pixel before its divisions where ``fl(ux + uy) > uz`` (``uz >= +0``; ``<`` for
``uz <= -0``), standing in for its later test ``1 - fl((ux + uy) / uz) < 0``. The two agree for every pair of floats:
no float lies strictly between ``uz`` and ``uz * (1 + 2**-24)`` (the least quotient that rounds above 1), rounding
is monotone, and the zero, infinite and NaN cases agree as well. Checked here on IEEE float32 (numpy's division is
correctly rounded, as C++'s): adjacent floats around each ``uz``, subnormals, zeros of both signs, infinities, NaN.
"""

from __future__ import annotations

import numpy as np


def _division_test(s: np.ndarray, uz: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        return (np.float32(1.0) - s / uz) < 0


def _row_test(s: np.ndarray, uz: np.ndarray) -> np.ndarray:
    return np.where(np.signbit(uz), s < uz, s > uz)


def test_third_edge_row_test_equals_the_division() -> None:
    rng = np.random.default_rng(0)
    uz = np.concatenate([
        rng.uniform(-1e4, 1e4, 20000), rng.standard_normal(20000) * 1e-3, np.ldexp(1.0, np.arange(-149, 128)),
        -np.ldexp(1.0, np.arange(-149, 128)), [0.0, -0.0, np.inf, -np.inf, np.nan, 1.0, -1.0, 3.0],
    ]).astype(np.float32)  # fmt: skip
    # s: uz itself, its neighbours up to 3 ulps away on both sides, and unrelated values
    near = [uz]
    for _ in range(3):
        near.append(np.nextafter(near[-1], np.float32(np.inf)))
    down = uz
    for _ in range(3):
        down = np.nextafter(down, np.float32(-np.inf))
        near.append(down)
    s = np.concatenate([*near, rng.permutation(uz), np.zeros_like(uz), -np.zeros_like(uz), np.full_like(uz, np.nan)])
    z = np.tile(uz, len(near) + 4)
    assert s.dtype == z.dtype == np.float32 and s.shape == z.shape
    row, div = _row_test(s, z), _division_test(s, z)
    assert np.array_equal(row, div), (s[row != div][:5], z[row != div][:5])
    # the pairs on either side of the boundary are present (the identity is exercised where it can fail)
    assert row.sum() > 50000 and (~row).sum() > 50000
