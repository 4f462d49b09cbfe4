r"""The KG error (Karni & Gotsman 2004) and KSO's E_RMS (Kavan, Sloan & O'Sullivan 2010) of a sequence pair.

Both compare two animations with one connectivity, vertex by vertex and frame by frame, as the dynamic-mesh
compression literature reports them. With :math:`A` the original ``(F, V, 3)`` positions, :math:`\hat A` the
distorted ones and :math:`E(A)` the animation whose every vertex is its own frame's centroid:

.. math::

    \mathrm{KG} = 100\,\frac{\lVert A - \hat A\rVert_F}{\lVert A - E(A)\rVert_F},\qquad
    \mathrm{KSO} = 1000\,\frac{\lVert (A - E(A)) - (\hat A - E(\hat A))\rVert_F}{\sqrt{3VF}}.

KSO follows the MIT-licensed reference of CraGL's Hyperspectral Inverse Skinning (``error_compare.py``): each frame
centred on its centroid, no scaling (its ``NORMALIZE = False``; Kavan et al. scale the animation to a unit bounding
sphere first, which ``scale`` reproduces with the reference's choice, half the bounding-box diagonal of frame 0).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from torchmeshmetric._checks import check_flag
from torchmeshmetric.temporal.sequences import check_sequence_pair, power_of_two_scale

__all__ = ["kg_error", "kso_error"]


def _frobenius(x: Tensor) -> Tensor:
    """The Frobenius norm of each ``(F, V, 3)`` item of ``(..., F, V, 3)``."""
    return torch.linalg.vector_norm(x.flatten(-3), dim=-1)


def _centred(x: Tensor) -> Tensor:
    """Each frame minus its centroid (the reference's ``centered``)."""
    return x - x.mean(dim=-2, keepdim=True)


def kg_error(original: Tensor, distorted: Tensor) -> Tensor:
    r"""The KG error of Karni & Gotsman (2004), in percent (see the module docstring).

    Args:
        original: ``(..., F, V, 3)`` original vertex positions (leading dimensions are a batch).
        distorted: ``(..., F, V, 3)`` distorted positions, same vertices.

    Returns:
        ``(...)`` KG error per sequence, in the promoted dtype; differentiable in both arguments where the
        difference is not zero.

    Raises:
        ShapeError, DTypeError, NonFiniteError, DeviceError: see
            :func:`~torchmeshmetric.temporal.sequences.check_sequence_pair`.
        ValueError: an original whose every frame is a single point (the denominator is zero).

    Example:
        >>> a = torch.tensor([[[0.0, 0, 0], [2.0, 0, 0]]], dtype=torch.float64)  # one frame, two vertices
        >>> round(kg_error(a, a + torch.tensor([0.1, 0.0, 0.0], dtype=torch.float64)).item(), 12)  # 100 * 0.1
        10.0
    """
    a, b = check_sequence_pair(original, distorted)
    scale = power_of_two_scale(a, b)  # KG is a ratio: the same figure, without overflow (see power_of_two_scale)
    a, b = a / scale, b / scale
    bottom = _frobenius(_centred(a))
    if bool((bottom == 0).any()):
        raise ValueError("original: every frame is a single point (||A - E(A)|| = 0), the KG error is undefined")
    return 100.0 * _frobenius(a - b) / bottom


def kso_error(original: Tensor, distorted: Tensor, *, scale: bool = False) -> Tensor:
    r"""Kavan, Sloan & O'Sullivan's E_RMS (2010), as CraGL's reference computes it (see the module docstring).

    Args:
        original: ``(..., F, V, 3)`` original vertex positions.
        distorted: ``(..., F, V, 3)`` distorted positions, same vertices.
        scale: first scale both animations by the reference's ``normalizing_scale`` of the original (the inverse of
            half the bounding-box diagonal of frame 0), Kavan et al.'s unit-size normalisation; default ``False``
            (the reference's default).

    Returns:
        ``(...)`` E_RMS per sequence.

    Example:
        >>> a = torch.zeros(1, 2, 3, dtype=torch.float64)
        >>> b = torch.tensor([[[0.0, 0, 0], [0.0, 0, 0.6]]], dtype=torch.float64)
        >>> round(kso_error(a, b).item(), 12)  # 1000 * sqrt(2 * 0.3**2) / sqrt(6)
        173.205080756888
    """
    a, b = check_sequence_pair(original, distorted)
    check_flag(scale, "scale")  # "no" would scale
    unit = power_of_two_scale(a, b)  # squares without overflow; the figure is multiplied back below
    a, b = a / unit, b / unit
    diff = _centred(a) - _centred(b)
    if scale:
        first = a[..., 0, :, :]
        half_diagonal = 0.5 * torch.linalg.vector_norm(first.amax(dim=-2) - first.amin(dim=-2), dim=-1)
        if bool((half_diagonal == 0).any()):
            raise ValueError("original: frame 0 is a single point, its bounding box gives no scale")
        diff = diff / half_diagonal[..., None, None, None]
    norm = _frobenius(diff) if scale else _frobenius(diff) * unit.reshape(unit.shape[:-3])  # exact: a power of two
    return 1000.0 * norm / math.sqrt(3 * a.shape[-2] * a.shape[-3])
