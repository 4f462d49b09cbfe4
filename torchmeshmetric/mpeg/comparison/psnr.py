"""mmetric's PSNR: ``10 log10(factor * peak^2 / mse)`` in double precision, infinite for a zero error."""

from __future__ import annotations

import math

import numpy as np

from torchmeshmetric._checks import check_positive_real

__all__ = ["check_mpeg_peak", "mpeg_psnr"]


def check_mpeg_peak(peak: object, name: str = "peak") -> float:
    """A PSNR peak given by the caller, rounded to float32 as mmetric passes it to dmetric.

    Zero, negative, NaN or infinite peaks gave an untyped "math domain error", a silently squared-away sign or a
    NaN/inf PSNR (found by review); a peak beyond float32's range became inf, a tiny one 0.

    Args:
        peak: a positive finite number (numpy's numbers and one-element tensors too).
        name: its name in the error.

    Returns:
        The peak rounded to float32, as a float.

    Raises:
        TypeError: ``peak`` is not a real number.
        ValueError: ``peak`` is not positive and finite, in float32 too.

    Example:
        >>> check_mpeg_peak(0.1)
        0.10000000149011612
        >>> check_mpeg_peak(-1.0)
        Traceback (most recent call last):
        ...
        ValueError: peak: expected a positive finite number, found -1.0
    """
    value = check_positive_real(peak, name)
    with np.errstate(over="ignore", under="ignore"):
        rounded = float(np.float32(value))
    if not (math.isfinite(rounded) and rounded > 0):
        raise ValueError(
            f"{name}: expected a positive number within float32's range (mmetric rounds the peak to float32), found "
            f"{value!r}, which rounds to {rounded!r}"
        )
    return rounded


def mpeg_psnr(mse: float, peak: float, factor: float = 3.0) -> float:
    r"""PSNR as MPEG's point-cloud metric (mpeg-pcc-dmetric ``getPSNR``) computes it.

    .. math:: \mathrm{PSNR} = 10 \log_{10} \frac{\mathrm{factor} \cdot \mathrm{peak}^2}{\mathrm{mse}}

    ``factor`` is 3 for geometry (D1, D2, Hausdorff: the peak is a box diagonal, the error a 3-D squared distance)
    and 1 for colour (peak 1 in YCbCr). The division is done in double precision as mmetric does, so a zero error,
    or a ratio beyond the largest double (mmetric's Hausdorff of identical clouds is the smallest double, not 0),
    gives ``inf``.

    A zero peak (a reference whose bounding box is one point) gives mmetric's figures too: ``-inf`` for a positive
    error (``log10(0)``) and NaN for a zero one (``0 / 0``); mm prints ``-inf`` / ``-nan`` there.

    Args:
        mse: mean squared error (or squared Hausdorff distance), ``>= 0`` (NaN gives NaN: D2 without normals).
        peak: the signal peak (the reference's bounding-box diagonal for geometry), finite and ``>= 0``.
        factor: 3 for geometry, 1 for colour.

    Returns:
        The PSNR in dB (``inf`` when the ratio overflows or ``mse`` is 0 with a positive peak).

    Raises:
        ValueError: a negative ``mse``, or a negative, NaN or infinite ``peak``.

    Example:
        >>> round(mpeg_psnr(1e-4, 1.0), 4)
        44.7712
        >>> mpeg_psnr(0.0, 1.0)
        inf
        >>> mpeg_psnr(1.0, 0.0)  # a one-point reference box, as mm prints it
        -inf
    """
    if not (math.isfinite(peak) and peak >= 0):
        raise ValueError(f"peak: expected a finite number >= 0, found {peak!r}")
    if mse < 0:
        raise ValueError(f"mse: expected a squared error >= 0, found {mse!r}")
    if math.isnan(mse):
        return math.nan
    if peak == 0:  # IEEE arithmetic, as dmetric's: 0 / mse = 0 -> log10 = -inf; 0 / 0 = NaN
        return math.nan if mse == 0 else -math.inf
    ratio = math.inf if mse == 0 else factor * peak * peak / mse
    if math.isinf(ratio) or ratio > 1.7976931348623157e308:
        return math.inf
    if ratio == 0:  # an infinite error, or a quotient below the smallest double: log10(0), as in C
        return -math.inf
    return 10.0 * math.log10(ratio)
