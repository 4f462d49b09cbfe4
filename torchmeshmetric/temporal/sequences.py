"""The one input check of the temporal metrics: an original and a distorted ``(..., F, V, 3)`` sequence pair."""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError, check_faces, check_finite, check_float, check_same_device, check_tensor
from torchmeshmetric.structures import power_of_two_above

__all__ = ["check_faces_of", "check_sequence_pair", "power_of_two_scale"]


def check_sequence_pair(original: Tensor, distorted: Tensor, *, min_frames: int = 1) -> tuple[Tensor, Tensor]:
    """Validate two same-connectivity sequences and bring them to one dtype (torch's type promotion).

    Args:
        original: ``(..., F, V, 3)`` vertex positions of the original sequence (leading dimensions are a batch).
        distorted: the distorted sequence, same shape.
        min_frames: the fewest frames the metric needs.

    Returns:
        The two tensors in their promoted dtype (float32 with float64 gives float64).

    Raises:
        TypeError: an argument is not a tensor.
        DTypeError: integer or half-precision coordinates.
        ShapeError: not ``(..., F, V, 3)``, different shapes, or fewer than ``min_frames`` frames.
        NonFiniteError: NaN or Inf coordinates.
        DeviceError: the two tensors live on different devices.

    Example:
        >>> a, b = check_sequence_pair(torch.zeros(2, 4, 3), torch.zeros(2, 4, 3, dtype=torch.float64))
        >>> a.dtype
        torch.float64
    """
    for name, x in (("original", original), ("distorted", distorted)):
        check_tensor(x, name, "a torch.Tensor of shape (..., F, V, 3)")
        check_float(x, name)
        if x.dim() < 3 or x.shape[-1] != 3:
            raise ShapeError(f"{name}: expected shape (..., F, V, 3), found {tuple(x.shape)}")
        if x.shape[-3] < min_frames:
            raise ShapeError(f"{name}: expected at least {min_frames} frame(s) along dim -3, found {x.shape[-3]}")
        if x.shape[-2] == 0:
            raise ShapeError(f"{name}: expected at least one vertex along dim -2, found shape {tuple(x.shape)}")
        check_finite(x, name)
    if original.shape != distorted.shape:
        raise ShapeError(
            f"distorted: expected the shape of original {tuple(original.shape)} (same connectivity), "
            f"found {tuple(distorted.shape)}"
        )
    check_same_device({"original": original, "distorted": distorted})
    dtype = torch.promote_types(original.dtype, distorted.dtype)
    return original.to(dtype), distorted.to(dtype)


def check_faces_of(faces: Tensor, num_verts: int) -> Tensor:
    """Validate the ``(T, 3)`` faces shared by every frame and return them as int64 (see ``check_faces``)."""
    check_tensor(faces, "faces", "a torch.Tensor of shape (T, 3)")
    check_faces(faces, num_verts, "faces")
    if faces.shape[0] == 0:
        raise ShapeError("faces: expected at least one face, found shape (0, 3)")
    return faces.long()


def power_of_two_scale(*sequences: Tensor) -> Tensor:
    """The power of two above the largest coordinate of each item of ``(..., F, V, 3)`` sequences: ``(..., 1, 1, 1)``.

    The temporal metrics square coordinates: float32 positions above ~1.8e19 overflowed to ``inf`` (KG and STED came
    out NaN) and below ~1e-19 underflowed to 0. Divided by this power of two the largest is in [0.5, 1); the division
    is exact, so every figure computed on the scaled sequences is the unscaled one bit for bit wherever the latter
    neither overflows nor underflows. Not differentiated (a constant of the inputs).

    Example:
        >>> power_of_two_scale(torch.tensor([[[3.0, -5.0, 0.0]]])).flatten().tolist()
        [8.0]
    """
    largest = torch.stack([s.detach().abs().amax(dim=(-3, -2, -1)) for s in sequences]).amax(0)
    return power_of_two_above(largest)[..., None, None, None]
