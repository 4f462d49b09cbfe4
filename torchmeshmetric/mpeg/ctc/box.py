"""The one check of a CTC sequence box (``min_pos``/``max_pos``), for the ``ctc`` options, the manifest and the API.

Light on purpose (the standard library only): the ``ctc`` and ``ctc-campaign`` commands check their boxes before torch
is imported.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

__all__ = ["check_box"]


def _float32(x: float) -> float:
    """``x`` rounded to float32 (as the grid sampler reads the box); beyond float32's range, ``x`` itself."""
    try:
        return float(struct.unpack("f", struct.pack("f", x))[0])
    except OverflowError:
        return x


def check_box(lo: Sequence[float], hi: Sequence[float], names: tuple[str, str] = ("min_pos", "max_pos")) -> None:
    """Refuse a box whose ``hi`` is below ``lo`` on an axis, or that is a single point (in the sampler's float32).

    A box flat on one or two axes is accepted (a planar sequence): mmetric's quantisation steps are per axis, and a
    zero side only makes that axis' step zero. ``ctc`` refused a box that ``ctc-campaign`` accepted, and the other way
    round for a flat one (review R #9): both and :class:`~torchmeshmetric.mpeg.ctc.settings.CtcSettings` call this.

    Args:
        lo: the low corner, three numbers.
        hi: the high corner.
        names: how the messages name them (``"--min-pos"``, ``"'min_pos'"``...).

    Raises:
        ValueError: naming both corners.

    Example:
        >>> check_box([-1, -1, 0], [1, 1, 0])  # flat on z: accepted
        >>> check_box([0, 0, 0], [1, -1, 1], ("--min-pos", "--max-pos"))
        Traceback (most recent call last):
        ...
        ValueError: --max-pos: [1.0, -1.0, 1.0] is below --min-pos [0.0, 0.0, 0.0]
    """
    low, high = [float(x) for x in lo], [float(x) for x in hi]
    if any(h < x for x, h in zip(low, high, strict=True)):
        raise ValueError(f"{names[1]}: {high} is below {names[0]} {low}")
    if all(_float32(h) == _float32(x) for x, h in zip(low, high, strict=True)):  # the sampler's float32 corners
        raise ValueError(f"{names[1]}: {high} equals {names[0]} {low} (the box is a single point)")
