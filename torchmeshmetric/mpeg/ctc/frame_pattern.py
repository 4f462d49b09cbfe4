"""Frame file names from printf patterns such as ``dec_%04d.obj`` (mmetric's and the test model's convention).

Light on purpose (the standard library only): the ``ctc`` and ``ctc-campaign`` commands check their patterns with it
before torch is imported.
"""

from __future__ import annotations

import re

__all__ = ["frame_path"]

_FIELD = re.compile(r"%[-+ #0]*\d*[diu]")


def frame_path(pattern: str, frame: int, option: str = "PATTERN") -> str:
    """One frame's file name from a printf frame pattern such as ``dec_%04d.obj`` (mmetric's convention).

    Raises:
        ValueError: the pattern has no integer field, or more than one conversion.

    Example:
        >>> frame_path("dec_%04d.obj", 7)
        'dec_0007.obj'
    """
    fields = _FIELD.findall(pattern.replace("%%", ""))
    if len(fields) != 1 or pattern.replace("%%", "").count("%") != 1:
        raise ValueError(f"{option}: expected one printf integer field such as dec_%04d.obj, found {pattern!r}")
    return pattern % frame
