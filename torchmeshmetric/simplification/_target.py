"""Shared target resolution of the simplifiers."""

from __future__ import annotations

import math
import numbers

__all__ = ["resolve_target"]


def resolve_target(target: int | float, num_faces: int, name: str = "target") -> int:
    """Turn ``target`` into a face count.

    An ``int`` is a face count in ``[1, num_faces]``; a ``float`` is the fraction of faces to **keep**, in
    ``(0, 1]`` (``0.5`` halves the mesh, ``0.03`` removes 97 % of the faces), rounded to the nearest count (at least 1).

    Raises:
        TypeError: ``target`` is neither an int nor a float (``bool`` is refused).
        ValueError: out of range.

    Example:
        >>> resolve_target(0.5, 40000), resolve_target(1200, 40000)
        (20000, 1200)
    """
    if isinstance(target, bool) or not isinstance(target, numbers.Real):
        raise TypeError(f"{name}: expected an int face count or a float ratio, found {type(target).__name__}")
    if isinstance(target, numbers.Integral):
        count = int(target)
        if not 1 <= count <= num_faces:
            raise ValueError(f"{name}: expected a face count in [1, {num_faces}], found {count}")
        return count
    ratio = float(target)
    if not (math.isfinite(ratio) and 0.0 < ratio <= 1.0):
        raise ValueError(f"{name}: expected a ratio of faces to keep in (0, 1], found {ratio!r}")
    return max(1, min(num_faces, round(ratio * num_faces)))
