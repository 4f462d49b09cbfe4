"""mmetric's colour space: 8-bit RGB to YCbCr (BT.709, values in [0, 1]), as mpeg-pcc-dmetric converts it."""

from __future__ import annotations

import numpy as np

from torchmeshmetric._checks import ShapeError

__all__ = ["rgb_to_ycbcr"]


def rgb_to_ycbcr(rgb: np.ndarray) -> np.ndarray:
    r"""BT.709 RGB to YCbCr as dmetric's ``convertRGBtoYUV`` (type 1): double arithmetic, float32 result.

    .. math::
        Y = (0.2126 R + 0.7152 G + 0.0722 B) / 255, \quad
        C_b = (-0.1146 R - 0.3854 G + 0.5 B) / 255 + 0.5, \\quad
        C_r = (0.5 R - 0.4542 G - 0.0458 B) / 255 + 0.5

    Args:
        rgb: ``(..., 3)`` 8-bit colours (any numeric dtype holding integers in ``[0, 255]``).

    Returns:
        ``(..., 3)`` float32 ``(Y, Cb, Cr)`` in ``[0, 1]``.

    Raises:
        ShapeError: the last dimension is not 3 (a fourth channel was dropped in silence).

    Example:
        >>> rgb_to_ycbcr(np.array([255, 255, 255])).round(4).tolist()
        [1.0, 0.5, 0.5]
    """
    c = np.asarray(rgb, dtype=np.float64)
    if c.ndim == 0 or c.shape[-1] != 3:
        raise ShapeError(f"rgb: expected shape (..., 3), found {tuple(c.shape)}")
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    y = (0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0
    cb = (-0.1146 * r - 0.3854 * g + 0.5000 * b) / 255.0 + 0.5000
    cr = (0.5000 * r - 0.4542 * g - 0.0458 * b) / 255.0 + 0.5000
    return np.stack([y, cb, cr], axis=-1).astype(np.float32)
