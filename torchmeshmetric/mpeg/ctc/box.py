"""The one check of a CTC sequence box (``min_pos``/``max_pos``), for the ``ctc`` options, the manifest and the API.

Light on purpose (the standard library only): the ``ctc`` and ``ctc-campaign`` commands check their boxes before torch
is imported.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

__all__ = ["check_box"]

_FLOAT32_MAX = 3.4028234663852886e38  # numpy's finfo(float32).max, without numpy (this module is light)


def _float32(x: float) -> float:
    """``x`` rounded to float32 (as the grid sampler reads the box); beyond float32's range, ``x`` itself."""
    try:
        return float(struct.unpack("f", struct.pack("f", x))[0])
    except OverflowError:
        return x


def check_box(lo: Sequence[float], hi: Sequence[float], names: tuple[str, str] = ("min_pos", "max_pos")) -> None:
    """Refuse a box whose ``hi`` is below ``lo`` on an axis, or a line or a single point (in the sampler's float32).

    A box flat on one axis is accepted (a planar sequence): mmetric's quantisation steps are per axis, and a zero side
    only makes that axis' step zero. A box flat on two axes is a line: ``mm dequantize`` puts every vertex on it and
    ``mm sample --mode grid`` then generates 0 points (measured with mm v1.1.7, box ``-1 0 0`` / ``1 0 0``), so no
    frame could be compared; it is refused here, before any frame runs (review S).
    ``ctc`` refused a box that ``ctc-campaign`` accepted, and the other way
    round for a flat one (review R #9): both and :class:`~torchmeshmetric.mpeg.ctc.settings.CtcSettings` call this.

    Args:
        lo: the low corner, three numbers.
        hi: the high corner.
        names: how the messages name them (``"--min-pos"``, ``"'min_pos'"``...).

    Raises:
        ValueError: naming both corners; or the corner with a coordinate beyond float32's range.

    Example:
        >>> check_box([-1, -1, 0], [1, 1, 0])  # flat on z: accepted
        >>> check_box([-1, 0, 0], [1, 0, 0], ("--min-pos", "--max-pos"))  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: --max-pos: [1.0, 0.0, 0.0] equals --min-pos [-1.0, 0.0, 0.0] on y and z (the box is a line: ...)
        >>> check_box([0, 0, 0], [1, -1, 1], ("--min-pos", "--max-pos"))
        Traceback (most recent call last):
        ...
        ValueError: --max-pos: [1.0, -1.0, 1.0] is below --min-pos [0.0, 0.0, 0.0]
    """
    low, high = [float(x) for x in lo], [float(x) for x in hi]
    for name, values in zip(names, (low, high), strict=True):
        if any(abs(_float32(v)) > _FLOAT32_MAX for v in values):  # _float32 keeps a value it cannot round
            # 1e39 is finite but not a float32: it was refused later as "max_pos: expected 3 finite numbers, found
            # [1e+39, ...]" after numpy's overflow warning (review X F4)
            raise ValueError(f"{name}: {values} is beyond float32's range (mmetric reads the box as float32)")
    if any(h < x for x, h in zip(low, high, strict=True)):
        raise ValueError(f"{names[1]}: {high} is below {names[0]} {low}")
    flat = [a for a, x, h in zip("xyz", low, high, strict=True) if _float32(h) == _float32(x)]  # the sampler's float32
    if len(flat) == 3:
        raise ValueError(f"{names[1]}: {high} equals {names[0]} {low} (the box is a single point)")
    if len(flat) == 2:
        # mm dequantises every vertex onto the line and its grid sampling finds no point there: the frame then
        # failed on an empty point cloud, naming neither option (review S)
        raise ValueError(
            f"{names[1]}: {high} equals {names[0]} {low} on {flat[0]} and {flat[1]} (the box is a line: mm's "
            "dequantisation puts every vertex on it and its grid sampling finds no point)"
        )
