"""Typed input checks shared by the whole library.

Every check raises an error that names the argument, what was found and what was expected, e.g.
``ShapeError: points: expected shape (P, 3), found (10, 2)``. The error classes subclass the built-in
``ValueError`` / ``TypeError`` so callers that already catch those keep working.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

__all__ = [
    "DeviceError",
    "DoubleBackwardError",
    "DTypeError",
    "EmptyInputError",
    "IndexRangeError",
    "NonFiniteError",
    "ShapeError",
    "StaleIndexError",
    "all_finite",
    "check_finite",
    "check_float",
    "check_lengths",
    "check_non_empty",
    "check_same_device",
    "check_shape",
    "check_faces",
]


class ShapeError(ValueError):
    """A tensor has the wrong number of dimensions or the wrong size along one of them."""


class DoubleBackwardError(RuntimeError):
    """A second derivative was asked of an operation that is differentiable once only (e.g. Danskin's gradient)."""


class DTypeError(TypeError):
    """A tensor has an unsupported dtype (e.g. integer coordinates or floating-point face indices)."""


class DeviceError(ValueError):
    """Tensors that must live on one device live on several."""


class NonFiniteError(ValueError):
    """A tensor holds NaN or Inf where only finite values make sense."""


class IndexRangeError(ValueError):
    """Indices (face corners, lengths) point outside the array they index."""


class EmptyInputError(ValueError):
    """A mesh or point set is empty where at least one element is required."""


class StaleIndexError(ValueError):
    """A kept index is queried after a tensor it was built from changed in place (refit it, or build a new one)."""


def _fmt_shape(shape: Sequence[int | str]) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ")"


def check_shape(x: Tensor, pattern: Sequence[str | int], name: str) -> None:
    """Check ``x`` against a pattern such as ``("P", 3)``: strings are free sizes, integers fixed ones.

    Raises:
        TypeError: ``x`` is not a tensor.
        ShapeError: the number of dimensions or a fixed size differs.
    """
    if not isinstance(x, Tensor):
        raise TypeError(f"{name}: expected a torch.Tensor, found {type(x).__name__}")
    expected = _fmt_shape([str(p) for p in pattern])
    if x.dim() != len(pattern) or any(isinstance(p, int) and s != p for s, p in zip(x.shape, pattern, strict=False)):
        raise ShapeError(f"{name}: expected shape {expected}, found {_fmt_shape(x.shape)}")


def check_float(x: Tensor, name: str) -> None:
    """Require float32 or float64 coordinates.

    Half precision (float16, bfloat16) is refused with a typed error on every entry point and every backend: its
    3 significant digits cannot give exact distances, and float16 overflows at squared distances above 65504. The
    caller converts (``x.float()``), which keeps the gradient flowing back to the half-precision tensor.
    """
    if x.dtype in (torch.float16, torch.bfloat16):
        raise DTypeError(
            f"{name}: expected float32 or float64, found dtype {x.dtype}; half precision cannot hold exact distances "
            "(convert with .float(): the gradient still reaches the half-precision tensor)"
        )
    if not x.is_floating_point():
        raise DTypeError(
            f"{name}: expected a floating-point tensor (float32 or float64), found dtype {x.dtype}; "
            "convert integer coordinates with .float() or .double()"
        )


def all_finite(x: Tensor) -> bool:
    """Whether every value of ``x`` is finite (no NaN, no Inf).

    A sum is finite only if all its terms are (NaN and Inf propagate through it), and one reduction costs a tenth of
    the elementwise ``isfinite``; only a non-finite sum (a NaN or Inf term, or finite terms whose sum overflows) is
    decided elementwise.
    """
    x = x.detach()
    return bool(torch.isfinite(x.sum())) or bool(torch.isfinite(x).all())


def check_finite(x: Tensor, name: str) -> None:
    """Require every value of ``x`` to be finite (no NaN, no Inf)."""
    if x.numel() and not all_finite(x):
        n_bad = int((~torch.isfinite(x)).sum())
        raise NonFiniteError(f"{name}: expected finite values, found {n_bad} NaN/Inf value(s)")


def check_non_empty(x: Tensor, name: str) -> None:
    """Require at least one row."""
    if x.shape[0] == 0:
        raise EmptyInputError(
            f"{name}: expected at least one element, found an empty tensor of shape {_fmt_shape(x.shape)}"
        )


def check_same_device(name_to_tensor: dict[str, Tensor]) -> None:
    """Require all tensors to live on one device."""
    devices = {n: t.device for n, t in name_to_tensor.items()}
    if len(set(devices.values())) > 1:
        found = ", ".join(f"{n} on {d}" for n, d in devices.items())
        raise DeviceError(f"expected all inputs on one device, found {found}")


def check_faces(faces: Tensor, num_verts: int, name: str = "faces") -> None:
    """Require an integer ``(F, 3)`` tensor whose entries index ``num_verts`` vertices."""
    check_shape(faces, ("F", 3), name)
    if faces.is_floating_point() or faces.dtype == torch.bool or faces.is_complex():
        raise DTypeError(f"{name}: expected an integer tensor of vertex indices, found dtype {faces.dtype}")
    if faces.numel():
        lo, hi = (int(x) for x in torch.stack(torch.aminmax(faces)).tolist())  # one device-to-host read
        if lo < 0 or hi >= num_verts:
            raise IndexRangeError(
                f"{name}: expected vertex indices in [0, {num_verts - 1}], found values in [{lo}, {hi}]"
            )


def check_lengths(lengths: Tensor, total: int, name: str) -> None:
    """Require a 1-D non-negative integer tensor of per-item sizes that sum to ``total``."""
    check_shape(lengths, ("B",), name)
    if lengths.is_floating_point():
        raise DTypeError(f"{name}: expected an integer tensor, found dtype {lengths.dtype}")
    if lengths.numel() and int(lengths.min()) < 0:
        raise IndexRangeError(f"{name}: expected non-negative lengths, found {lengths.tolist()}")
    if int(lengths.sum()) != total:
        raise ShapeError(f"{name}: expected lengths summing to {total}, found sum {int(lengths.sum())}")
