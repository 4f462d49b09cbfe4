"""glm's float32 vector arithmetic, operation by operation (no fused multiply-add), so results match bit for bit."""

from __future__ import annotations

import numpy as np

__all__ = ["area", "cross", "dot", "normalize", "roundf"]


def roundf(x: np.ndarray) -> np.ndarray:
    """C's ``roundf`` of float32 values (halves away from zero), exact, as float64.

    ``floor(|x| + 0.5)`` in float32 is not ``roundf``: ``0.49999997f + 0.5f`` rounds to 1 (review P). In float64 the sum
    of a float32 value and 0.5 is exact (24 significant bits and one more fit in 53), so the floor is.
    """
    c = np.asarray(x, np.float32).astype(np.float64)
    return np.sign(c) * np.floor(np.abs(c) + 0.5)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``glm::cross`` of ``(..., 3)`` float32 vectors."""
    x = a[..., 1] * b[..., 2] - b[..., 1] * a[..., 2]
    y = a[..., 2] * b[..., 0] - b[..., 2] * a[..., 0]
    z = a[..., 0] * b[..., 1] - b[..., 0] * a[..., 1]
    return np.stack([x, y, z], axis=-1)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``glm::dot``: ``(ax*bx + ay*by) + az*bz`` in float32."""
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]


def normalize(v: np.ndarray) -> np.ndarray:
    """``glm::normalize``: ``v * (1 / sqrt(dot(v, v)))`` in float32."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.float32(1.0) / np.sqrt(dot(v, v))
    return v * inv[..., None]


def area(v1: np.ndarray, v2: np.ndarray, v3: np.ndarray) -> np.ndarray:
    """The ``triangleArea`` of mmetric: ``0.5 * length(cross(v2 - v1, v3 - v1))`` (float32 length, double product)."""
    c = cross(v2 - v1, v3 - v1)
    return 0.5 * np.sqrt(dot(c, c)).astype(np.float64)
