r"""The ``flicker`` set: how far the simplified frame ``k`` is from the simplified frame ``k-1`` moved onto frame ``k``.

The paper's ``k-1`` sets compare the simplified frame ``k`` with the *original* frame ``k-1`` (registered onto
frame ``k``). A simplifier whose output jumps from frame to frame — what a viewer sees as temporal inconsistency —
can score the same there as a stable one, because each simplified frame may be equally close to the originals while
being far from its own predecessor. The ``flicker`` set compares consecutive *simplified* frames directly:

.. math::

    D^{(k)}_{flicker} = \{\, d(v, W(S_{k-1})) : v \in V(S_k) \,\},

the exact surface distance (Eq. 4) from each vertex of the simplified frame ``k`` to the simplified frame ``k-1``
whose vertices are moved by the registration's deformation ``W`` of original ``k-1`` onto original ``k`` (same
faces). When two-sided, the reverse set measures from the moved vertices of ``S_{k-1}`` to ``S_k``.

What it measures: changes of the simplified *surface* between consecutive frames beyond the motion (popping,
alternating offsets, a region simplified differently). What it misses: vertices sliding *along* the surface
(the surface does not change), and it carries the registration's error (its noise floor, see
``docs/statistics.md``). Frame 0 has no flicker set.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import check_finite, check_flag, common_dtype
from torchmeshmetric.kernels import point_mesh_distance, vertex_set
from torchmeshmetric.registration.warp import Warp, check_warped
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["FLICKER", "FlickerDistances", "flicker_distances"]

#: Key of the flicker set in :class:`~torchmeshmetric.evaluation.PairEvaluation` and the reports.
FLICKER = "flicker"


class FlickerDistances(NamedTuple):
    """Result of :func:`flicker_distances`.

    Attributes:
        dists: ``(V_k,)`` distance of each (referenced) vertex of the simplified frame ``k`` to the moved simplified
            frame ``k-1``.
        reverse: ``(V_{k-1},)`` distance of each moved (referenced) vertex of the simplified frame ``k-1`` to the
            simplified frame ``k``; ``None`` when one-sided.
        moved: the simplified frame ``k-1`` moved onto frame ``k`` (its faces, warped vertices).

    Example:
        >>> import torch, trimesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=1))
        >>> lifted = Mesh(sphere.verts + torch.tensor([0.0, 0.0, 0.01], dtype=sphere.dtype), sphere.faces)
        >>> r = flicker_distances(lifted, sphere, lambda points: points)  # a static registration: the lift is flicker
        >>> tuple(r.dists.shape), round(r.dists.max().item(), 12), r.moved.num_faces
        ((42,), 0.01, 80)
    """

    dists: Tensor
    reverse: Tensor | None
    moved: Mesh


def flicker_distances(
    simplified_k: MeshLike, simplified_k_minus_1: MeshLike, warp: Warp, *, two_sided: bool = True
) -> FlickerDistances:
    """The ``flicker`` set of one frame pair (see the module docstring).

    Args:
        simplified_k: the simplified frame ``k``.
        simplified_k_minus_1: the simplified frame ``k-1`` (any connectivity, in frame ``k-1``'s space).
        warp: the registration's map of frame ``k-1`` points to frame ``k`` (e.g.
            :class:`~torchmeshmetric.registration.RegistrationWarp`).
        two_sided: also measure from the moved frame ``k-1`` to frame ``k``.

    Returns:
        :class:`FlickerDistances` (computed without gradient, on ``simplified_k``'s device, in the promoted dtype
        of the two frames).

    Raises:
        TypeError: the warp's output is not a tensor.
        ShapeError: it is not ``(V_{k-1}, 3)``, one row per vertex of ``simplified_k_minus_1``.
        DTypeError: it is not floating point (float32 or float64).
        NonFiniteError: it holds NaN or Inf.

    Example:
        >>> import torch, trimesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> shift = torch.tensor([0.1, 0.0, 0.0], dtype=sphere.dtype)
        >>> moved_by_motion = Mesh(sphere.verts + shift, sphere.faces)  # frame k: the same mesh, moved
        >>> r = flicker_distances(moved_by_motion, sphere, lambda p: p + shift)
        >>> float(r.dists.max()) < 1e-12, float(r.reverse.max()) < 1e-12  # a stable simplification: no flicker
        (True, True)
    """
    two_sided = check_flag(two_sided, "two_sided")
    s_k = as_mesh(simplified_k, name="simplified_k")
    s_km1 = as_mesh(simplified_k_minus_1, name="simplified_k_minus_1")
    dtype = common_dtype(s_k.dtype, s_km1.dtype)  # the dtype rule (docs/concepts.md, Precision)
    s_k, s_km1 = s_k.to(dtype=dtype), s_km1.to(s_k.device, dtype)
    with torch.no_grad():
        moved_verts = warp(s_km1.verts.detach())
        # a registration's output is checked here, or the wrong shape crashed deep in the distance kernel (fewer
        # rows), gave a plausible number (extra rows), and a NaN blamed an overflow on `points` (found by review)
        name = "warp(simplified_k_minus_1.verts)"
        check_finite(check_warped(moved_verts, s_km1.verts, name), name)
        moved = Mesh(moved_verts.to(s_k.device, s_k.dtype), s_km1.faces, validate=False)
        dists = point_mesh_distance(vertex_set(s_k).detach(), moved).dists
        reverse = point_mesh_distance(vertex_set(moved), s_k.detach()).dists if two_sided else None
    return FlickerDistances(dists, reverse, moved)
