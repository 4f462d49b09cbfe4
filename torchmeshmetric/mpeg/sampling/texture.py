"""Texture lookup at UV coordinates as mmetric does it (clamp to edge, v flipped, nearest or bilinear)."""

from __future__ import annotations

from typing import Any

import numpy as np

from torchmeshmetric._checks import NonFiniteError, ShapeError, check_flag

__all__ = ["sample_texture"]


def _fetch(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    col = np.clip(x, 0, w - 1)
    row = h - 1 - np.clip(y, 0, h - 1)  # v points up, image rows down
    return img[row, col, :3].astype(np.float32)


def sample_texture(texture: Any, uv: np.ndarray, *, bilinear: bool = True) -> np.ndarray:
    """Colours of a texture at UV coordinates, with mmetric's ``texture2D`` / ``texture2D_bilinear`` arithmetic.

    Nearest: texel ``(int(u * W), int(v * H))`` clamped to the image, ``v`` flipped. Bilinear: the four texels around
    ``uv * (W, H) - 0.5`` (each clamped), blended in float32 with ``glm::mix``.

    Args:
        texture: ``(H, W, C)`` uint8 image (C >= 3; a PIL image or array-like is converted).
        uv: ``(N, 2)`` float32 texture coordinates.
        bilinear: bilinear filtering (mmetric ``--bilinear``), nearest otherwise.

    Returns:
        ``(N, 3)`` float32 RGB in ``[0, 255]``.

    Raises:
        ShapeError: ``texture`` is not an ``(H, W)`` or ``(H, W, C >= 3)`` image with texels, or ``uv`` not
            ``(N, 2)``.
        NonFiniteError: ``uv`` holds NaN or Inf (they became arbitrary texels, with numpy's cast warnings).

    Example:
        >>> img = np.array([[[0, 0, 0], [255, 255, 255]]], np.uint8)  # 1 x 2 image
        >>> sample_texture(img, np.array([[0.5, 0.5]], np.float32)).tolist()
        [[127.5, 127.5, 127.5]]
        >>> sample_texture(img, np.array([[0.9, 0.5]], np.float32), bilinear=False).tolist()
        [[255.0, 255.0, 255.0]]
    """
    bilinear = check_flag(bilinear, "bilinear")
    img = np.asarray(texture)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.ndim != 3 or img.shape[2] < 3 or img.shape[0] == 0 or img.shape[1] == 0:
        raise ShapeError(f"texture: expected an (H, W, C >= 3) image with texels, found shape {tuple(img.shape)}")
    uv = np.asarray(uv, dtype=np.float32)
    if uv.ndim != 2 or uv.shape[1] != 2:  # (N, 3) was read as its first two columns
        raise ShapeError(f"uv: expected shape (N, 2), found {tuple(uv.shape)}")
    if not np.isfinite(uv).all():
        raise NonFiniteError(f"uv: expected finite values, found {int((~np.isfinite(uv)).sum())} NaN/Inf value(s)")
    h, w = img.shape[:2]
    if not bilinear:
        x = (uv[:, 0] * np.float32(w)).astype(np.int64)  # (int) truncates toward zero
        y = (uv[:, 1] * np.float32(h)).astype(np.int64)
        return _fetch(img, x, y)
    px = uv[:, 0] * np.float32(w) - np.float32(0.5)
    py = uv[:, 1] * np.float32(h) - np.float32(0.5)
    fx0, fy0 = np.floor(px), np.floor(py)
    x0, y0 = fx0.astype(np.int64), fy0.astype(np.int64)
    fx, fy = (px - fx0)[:, None], (py - fy0)[:, None]
    tl, tr = _fetch(img, x0, y0), _fetch(img, x0 + 1, y0)
    bl, br = _fetch(img, x0, y0 + 1), _fetch(img, x0 + 1, y0 + 1)
    one = np.float32(1.0)
    ta = tl * (one - fx) + tr * fx
    tb = bl * (one - fx) + br * fx
    return (ta * (one - fy) + tb * fy).astype(np.float32)
