"""mmetric's PSNR: ``10 log10(factor * peak^2 / mse)`` in double precision, infinite for a zero error."""

from __future__ import annotations

import math

__all__ = ["mpeg_psnr"]


def mpeg_psnr(mse: float, peak: float, factor: float = 3.0) -> float:
    r"""PSNR as MPEG's point-cloud metric (mpeg-pcc-dmetric ``getPSNR``) computes it.

    .. math:: \mathrm{PSNR} = 10 \log_{10} \frac{\mathrm{factor} \cdot \mathrm{peak}^2}{\mathrm{mse}}

    ``factor`` is 3 for geometry (D1, D2, Hausdorff: the peak is a box diagonal, the error a 3-D squared distance)
    and 1 for colour (peak 1 in YCbCr). The division is done in double precision as mmetric does, so a zero error,
    or a ratio beyond the largest double (mmetric's Hausdorff of identical clouds is the smallest double, not 0),
    gives ``inf``.

    Args:
        mse: mean squared error (or squared Hausdorff distance), ``>= 0``.
        peak: the signal peak (the reference's bounding-box diagonal for geometry).
        factor: 3 for geometry, 1 for colour.

    Returns:
        The PSNR in dB (``inf`` when the ratio overflows or ``mse`` is 0).

    Example:
        >>> round(mpeg_psnr(1e-4, 1.0), 4)
        44.7712
        >>> mpeg_psnr(0.0, 1.0)
        inf
    """
    ratio = math.inf if mse == 0 else factor * peak * peak / mse
    if math.isinf(ratio) or ratio > 1.7976931348623157e308:
        return math.inf
    return 10.0 * math.log10(ratio)
