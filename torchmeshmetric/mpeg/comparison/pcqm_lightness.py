"""The lightness PCQM compares: sRGB -> CIELAB L* (MATLAB's constants) -> LAB2000HL lightness by table.

PCQM (as mmetric embeds it) converts each point's 8-bit colour to CIELAB with MATLAB's sRGB matrix and D65 white,
then maps L* through the 1-D table of the hue-linearised LAB2000HL space (Lissner & Urban), sampled every 0.001 on
[0, 100] and interpolated linearly; L* above 100 takes the last entry. The table (100001 values with 4 decimals) is
stored as its integer steps in ``pcqm_lightness.npz`` (3.5 kB) and rebuilt exactly: ``k / 10000.0`` is the double
nearest to the printed decimal, as the C++ literal is. Only lightness enters the PCQM score (chroma and hue features
are computed by PCQM but carry no weight), so the a/b table is not needed.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError

__all__ = ["pcqm_lightness"]

_TABLE = Path(__file__).with_name("pcqm_lightness.npz")


@lru_cache(maxsize=1)
def _table() -> tuple[np.ndarray, np.ndarray]:
    """(grid, values): L* = i * 0.001 (PCQM's grid) and the LAB2000HL lightness at each."""
    steps = np.load(_TABLE)["steps"].astype(np.int64)
    values = np.concatenate([[0], np.cumsum(steps)]) / 10000.0
    grid = np.arange(values.shape[0], dtype=np.float64) * 0.001
    return grid, values


def _f(t: np.ndarray) -> np.ndarray:
    """CIELAB's f: cube root above 0.008856, the linear segment below."""
    return np.where(t > 0.008856, np.cbrt(t), (841.0 / 108.0) * t + 4.0 / 29.0)


def pcqm_lightness(colors: Tensor | np.ndarray) -> np.ndarray:
    """PCQM's LAB2000HL lightness of RGB colours.

    Colours are truncated to integers first (PCQM passes them to an ``int`` parameter), then linearised with the
    sRGB curve, ``Y = 0.212586 R + 0.71517 G + 0.0722005 B``, ``L* = 116 f(Y) - 16``, and mapped through the table.

    Args:
        colors: ``(N, 3)`` RGB in ``[0, 255]``.

    Returns:
        ``(N,)`` float64 lightness.

    Raises:
        ShapeError: ``colors`` is not ``(N, 3)``.
        ValueError: a colour is NaN or outside ``[0, 255]`` (a negative one extrapolated the table).

    Example:
        >>> pcqm_lightness(np.array([[0, 0, 0], [255, 255, 255]])).round(4).tolist()
        [0.0, 75.1522]
    """
    c = colors.detach().cpu().to(torch.float64).numpy() if isinstance(colors, Tensor) else np.asarray(colors)
    if c.ndim != 2 or c.shape[1] != 3:  # (N, 2) raised numpy's IndexError (found by review)
        raise ShapeError(f"colors: expected shape (N, 3), found {tuple(c.shape)}")
    c = c.astype(np.float64)
    if c.size and not (c.min() >= 0 and c.max() <= 255):  # NaN fails both
        raise ValueError(
            f"colors: expected RGB values in [0, 255], found values in [{np.nanmin(c):g}, {np.nanmax(c):g}]"
            + (" and NaN" if np.isnan(c).any() else "")
        )
    rgb = np.trunc(c) / 255.0
    lin = np.where(rgb > 0.0404482362771076, np.power((rgb + 0.055) / 1.055, 2.4), rgb / 12.92)
    y = (0.212586 * lin[:, 0] + 0.71517 * lin[:, 1]) + 0.0722005 * lin[:, 2]
    lstar = 116.0 * _f(y / 1.0) - 16.0
    grid, values = _table()
    pos = np.searchsorted(grid, lstar, side="right")  # std::upper_bound
    inside = pos < grid.shape[0]
    p = np.clip(pos, 1, grid.shape[0] - 1)
    x0, x1, y0, y1 = grid[p - 1], grid[p], values[p - 1], values[p]
    interp = y0 + ((lstar - x0) / (x1 - x0)) * (y1 - y0)
    return np.where(inside, interp, values[-1])
