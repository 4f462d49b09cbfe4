"""The canonical scale at which a simplifier with an absolute threshold runs, and the way back to the input's unit.

fast-simplification stops collapsing at an absolute squared-distance threshold, so its decisions depend on the unit of
the coordinates. :func:`canonical_factor` gives the factor ``s`` that brings the largest bounding-box side of the used
vertices to :data:`CANONICAL_EXTENT`; the simplifier runs on ``verts * s`` and :func:`original_rows` maps its output
back. Only correctly rounded IEEE operations are used (min and max, which are exact, one subtraction, one division,
elementwise products): the same bits on every CPU, whatever its SIMD width, and for an input scaled by ``2**j`` the
extent and ``s`` scale exactly, so the canonical copy is bit-identical.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["CANONICAL_EXTENT", "canonical_factor", "original_rows"]

#: The largest bounding-box side of the canonical copy: 2.0, the extent of a mesh normalised to ``[-1, 1]^3`` (which
#: is simplified as given, ``s = 1``) and a power of two (so a mesh whose extent is a power of two is scaled exactly).
CANONICAL_EXTENT = 2.0


def canonical_factor(verts: np.ndarray, faces: np.ndarray) -> float:
    """The factor ``s`` that brings the largest bounding-box side of the used vertices to :data:`CANONICAL_EXTENT`.

    Args:
        verts: ``(V, 3)`` float64 vertices.
        faces: ``(F, 3)`` int64 faces, ``F >= 1`` (the vertices they use set the extent).

    Returns:
        ``CANONICAL_EXTENT / extent``, correctly rounded; 1.0 when every used vertex is at one point (nothing to
        scale) or when ``s`` or the scaled coordinates would overflow (a surface tiny next to its distance from the
        origin: it is simplified as given).

    Example:
        >>> canonical_factor(np.array([[0.0, 0.0, 0.0], [4.0, 1.0, 0.0], [0.0, 3.0, 0.0]]), np.array([[0, 1, 2]]))
        0.5
    """
    used = verts[np.unique(faces)]
    extent = float((used.max(0) - used.min(0)).max())
    if extent == 0.0:
        return 1.0
    s = CANONICAL_EXTENT / extent
    # |v| * s is monotone in |v|: the largest product is finite exactly when every product is.
    if not (math.isfinite(s) and math.isfinite(float(np.abs(verts).max()) * s)):
        return 1.0
    return s


def _row_keys(rows: np.ndarray) -> np.ndarray:
    """One opaque 24-byte key per float64 row, equal exactly when the rows are equal (``-0.0`` taken as ``0.0``)."""
    return np.ascontiguousarray(rows + 0.0).view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()


def original_rows(
    out: np.ndarray, scaled: np.ndarray, verts: np.ndarray, s: float, survivors: np.ndarray | None
) -> np.ndarray:
    """The simplifier's output vertices ``out`` (canonical unit) in the unit of ``verts``.

    ``out / s`` is not exact (``s`` is no power of two in general): a vertex the simplifier did not move would come
    back an ulp off its input. Every output row at exactly the canonical position of an input vertex is therefore
    given that input vertex's own bits: first the row's own input vertex (``survivors[j]``, where known), then any
    input vertex at that canonical position (a collapse placed at one of its ends, or a vertex whose row was not
    known); where the scaling rounded two input vertices to one canonical position (only vertices within an ulp of
    each other can be), the first of them. Every other row is ``out / s``, correctly rounded: within half an ulp of
    the canonical position mapped back.

    Args:
        out: ``(M, 3)`` float64 output vertices, in the canonical unit.
        scaled: ``(V, 3)`` float64, ``verts * s``: the canonical copy the simplifier was given.
        verts: ``(V, 3)`` float64 input vertices.
        s: the factor (:func:`canonical_factor`).
        survivors: ``(M,)`` int64 index of the input vertex of each output row (the simplifier keeps the order of the
            vertices it keeps), or None where not known.

    Returns:
        ``(M, 3)`` float64 vertices in the input's unit.

    Example:
        >>> v = np.array([[0.1, 0.2, 0.3], [0.7, 0.0, 0.0]])
        >>> s = 3.0
        >>> back = original_rows(np.array([v[1] * s, [1.0, 1.0, 1.0]]), v * s, v, s, None)
        >>> bool((back[0] == v[1]).all()), bool((back[1] == 1.0 / s).all())
        (True, True)
    """
    back = out / s
    if s == 1.0:
        return back
    todo = np.ones(out.shape[0], dtype=bool)
    if survivors is not None and survivors.shape[0] == out.shape[0]:
        own = (out == scaled[survivors]).all(1)
        back[own] = verts[survivors[own]]
        todo = ~own
    if todo.any():
        keys, first = np.unique(_row_keys(scaled), return_index=True)  # sorted keys, first input vertex of each
        want = _row_keys(out[todo])
        at = np.minimum(np.searchsorted(keys, want), keys.size - 1)
        hit = keys[at] == want
        rows = np.flatnonzero(todo)[hit]
        back[rows] = verts[first[at[hit]]]
    return back
