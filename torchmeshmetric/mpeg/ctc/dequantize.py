"""mmetric's ``dequantize``: integer positions and UVs of a V-DMC frame back to model units, in its float32 arithmetic.

A V-DMC decoder outputs positions as integers ``0 .. 2**qp - 1`` over the sequence's box and UVs as integers
``0 .. 2**qt - 1`` over ``[0, 1]``. The CTC metric step turns both meshes back with ``mm dequantize --useFixedPoint``:
the box's min corner is rounded down and its max corner up to a multiple of 1/65536, the scale
``range / (2**qp - 1)`` (``range`` = the rounded box's longest side) is rounded *up* to a multiple of 1/65536, and each
coordinate becomes ``q * scale + min`` in float32. The result is not the float dequantisation ``q * range / (2**qp -
1) + min``: the fixed-point scale is slightly larger, which moves every grid sample.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Union

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import check_flag
from torchmeshmetric.mpeg.core.fixed_point import fixed_point_box, fixed_point_ceil

__all__ = ["dequantize_positions", "dequantize_uvs", "position_scale"]

Corner = Union[Sequence[float], np.ndarray, Tensor]  # noqa: UP007 (a runtime alias)


def _corner(x: Corner, name: str, n: int) -> np.ndarray:
    a = np.asarray(x.detach().cpu().numpy() if isinstance(x, Tensor) else x, dtype=np.float32).reshape(-1)
    if a.shape != (n,) or not np.isfinite(a).all():
        raise ValueError(f"{name}: expected {n} finite numbers, found {np.asarray(x).tolist()!r}")
    return a


def _quantised(x: Tensor | np.ndarray, name: str) -> np.ndarray:
    """Quantised values as float32, refusing what float32 would silently change: complex, NaN or infinite input."""
    a = np.asarray(x.detach().cpu().numpy() if isinstance(x, Tensor) else x)
    if np.iscomplexobj(a) or a.dtype.kind not in "biuf":
        raise TypeError(f"{name}: expected real integer values, found dtype {a.dtype}")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        bad = int((~np.isfinite(a)).sum())
        raise ValueError(f"{name}: expected finite quantised values, found {bad} NaN or infinite")
    return a.astype(np.float32)


def _bits(q: int, name: str) -> int:
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or not 0 <= int(q) <= 31:
        raise ValueError(f"{name}: expected an integer bit depth in 0..31, found {q!r}")
    return int(q)


def position_scale(qp: int, min_pos: Corner, max_pos: Corner, *, fixed_point: bool = True) -> tuple[np.ndarray, float]:
    """The float32 ``(min corner, scale)`` of mmetric's position dequantisation (``q * scale + min``).

    Args:
        qp: geometry bit depth (``>= 7``; mmetric leaves positions unchanged below 7).
        min_pos: ``(3,)`` min corner of the sequence's box (mmetric ``--minPos``).
        max_pos: ``(3,)`` max corner (``--maxPos``).
        fixed_point: ``--useFixedPoint`` (the CTC setting): box and scale rounded to 1/65536.

    Example:
        >>> lo, s = position_scale(10, [0, 0, 0], [1, 2, 1])
        >>> lo.tolist(), s * 65536
        ([0.0, 0.0, 0.0], 129.0)
    """
    fixed_point = check_flag(fixed_point, "fixed_point")
    qp = _bits(qp, "qp")
    lo, hi = _corner(min_pos, "min_pos", 3), _corner(max_pos, "max_pos", 3)
    if (hi < lo).any():
        raise ValueError(f"max_pos: {hi.tolist()} is below min_pos {lo.tolist()}")
    if fixed_point:
        lo, hi = fixed_point_box(lo, hi)
    diag = hi - lo
    rng = np.float32(max(diag[0], diag[1], diag[2]))
    scale = np.float32(rng / np.float32((1 << qp) - 1))
    if fixed_point:
        scale = np.float32(fixed_point_ceil(scale))
    return lo, float(scale)


def dequantize_positions(
    verts: Tensor | np.ndarray,
    qp: int,
    min_pos: Corner,
    max_pos: Corner,
    *,
    fixed_point: bool = True,
) -> Tensor:
    """Integer positions ``(V, 3)`` back to model units, as ``mm dequantize --qp QP [--useFixedPoint]`` does.

    Float32 arithmetic, one rounding per operation (``q * scale``, then ``+ min``), as mmetric's compiled code; a
    bit depth below 7 leaves the positions unchanged (mmetric's rule).

    Args:
        verts: ``(V, 3)`` quantised positions (integers stored in any dtype).
        qp: geometry bit depth.
        min_pos: ``(3,)`` the sequence box's min corner.
        max_pos: ``(3,)`` its max corner.
        fixed_point: mmetric's ``--useFixedPoint`` (the CTC setting).

    Returns:
        ``(V, 3)`` float32 positions (CPU).

    Raises:
        ValueError: a bad bit depth or box, NaN or infinite positions.
        TypeError: complex (or non-numeric) positions.

    Example:
        >>> q = torch.tensor([[0, 1023, 512]])
        >>> dequantize_positions(q, 10, [0, 0, 0], [1, 1, 1]).tolist()  # scale 1/1023 rounded up to 65/65536
        [[0.0, 1.0146331787109375, 0.5078125]]
        >>> dequantize_positions(q, 10, [0, 0, 0], [1, 1, 1], fixed_point=False).tolist()
        [[0.0, 1.0, 0.5004887580871582]]
    """
    fixed_point = check_flag(fixed_point, "fixed_point")
    v = _quantised(verts, "verts")
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"verts: expected shape (V, 3), found {tuple(v.shape)}")
    if _bits(qp, "qp") < 7:
        return torch.from_numpy(np.ascontiguousarray(v))
    lo, scale = position_scale(qp, min_pos, max_pos, fixed_point=fixed_point)
    out = (v * np.float32(scale)).astype(np.float32) + lo
    return torch.from_numpy(np.ascontiguousarray(out, dtype=np.float32))


def dequantize_uvs(
    uvs: Tensor | np.ndarray,
    qt: int,
    min_uv: Corner = (0.0, 0.0),
    max_uv: Corner = (1.0, 1.0),
) -> Tensor:
    """Integer texture coordinates back to ``[0, 1]``, as ``mm dequantize --qt QT`` does (no fixed point for UVs).

    Float32 ``q * range / (2**qt - 1) + min`` in that order (``range`` = the UV box's longer side); a bit depth below
    7 leaves the UVs unchanged.

    Args:
        uvs: ``(..., 2)`` quantised UVs.
        qt: texture-coordinate bit depth.
        min_uv: ``(2,)`` min corner (the CTC: ``0 0``).
        max_uv: ``(2,)`` max corner (the CTC: ``1 1``).

    Returns:
        float32 UVs, same shape (CPU).

    Example:
        >>> dequantize_uvs(torch.tensor([[0.0, 1023.0]]), 10).tolist()
        [[0.0, 1.0]]
    """
    u = _quantised(uvs, "uvs")
    if u.shape[-1:] != (2,):
        raise ValueError(f"uvs: expected shape (..., 2), found {tuple(u.shape)}")
    if _bits(qt, "qt") < 7:
        return torch.from_numpy(np.ascontiguousarray(u))
    lo, hi = _corner(min_uv, "min_uv", 2), _corner(max_uv, "max_uv", 2)
    diag = hi - lo
    rng = np.float32(max(diag[0], diag[1]))
    maxq = np.float32((1 << qt) - 1)
    out = ((u * rng).astype(np.float32) / maxq).astype(np.float32) + lo
    return torch.from_numpy(np.ascontiguousarray(out, dtype=np.float32))
