"""The result of measuring a batch in one or both directions (simplified → reference, reference → simplified)."""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

__all__ = ["DirectedDistances"]


class DirectedDistances(NamedTuple):
    """Per-point distances of a ragged batch, packed, in one or both directions.

    Attributes:
        forward: ``(sum P_b,)`` distances from the simplified points to the reference (the paper's direction).
        forward_lengths: ``(B,)`` points per item.
        reverse: ``(sum R_b,)`` distances from the reference points to the simplified mesh (two-sided only, else
            ``None``).
        reverse_lengths: ``(B,)`` reference points per item (two-sided only, else ``None``).
        peak: ``(B,)`` bounding-box diagonal of each reference mesh (the default PSNR peak).

    Example:
        >>> import torch
        >>> from torchmeshmetric import mesh_surface_distance_sets
        >>> triangle = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> lifted = (triangle[0] + torch.tensor([0.0, 0.0, 0.5]), triangle[1])
        >>> d = mesh_surface_distance_sets(lifted, triangle, two_sided=True)
        >>> d.forward.tolist(), d.forward_lengths.tolist(), d.reverse.tolist(), round(d.peak.item(), 6)
        ([0.5, 0.5, 0.5], [3], [0.5, 0.5, 0.5], 1.414214)
    """

    forward: Tensor
    forward_lengths: Tensor
    reverse: Tensor | None
    reverse_lengths: Tensor | None
    peak: Tensor


def lengths_of(items: list[Tensor]) -> Tensor:
    """``(B,)`` int64 row counts of a list of tensors."""
    return torch.tensor([t.shape[0] for t in items], dtype=torch.long, device=items[0].device)


def packed(items: list[Tensor]) -> Tensor:
    """The rows of ``items`` in one tensor (a single item as it is: no copy; ``torch.cat`` promotes mixed dtypes)."""
    return items[0] if len(items) == 1 else torch.cat(items)
