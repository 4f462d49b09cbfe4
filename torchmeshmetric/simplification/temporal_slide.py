r"""A learned vertex placement: slide a simplified frame towards the warped previous simplified frame.

Anchored QEM (:mod:`~torchmeshmetric.simplification.anchored_qem`) makes frame ``k`` take the previous frame's
tessellation where it can; its vertices still sit where frame ``k``'s quadrics put them. :class:`TemporalSlide` moves
each vertex ``x`` of the simplified frame ``k`` towards its closest point ``c`` on the warped simplified frame
``k-1`` (``W(S_{k-1})``) along the surface, and optionally across it:

.. math::

    x' = x + a_t(\phi)\, (c - x)_t \;[+\, a_n(\phi)\, (c - x)_n], \qquad a_t, a_n \in (0, 1),

with ``t``/``n`` the tangential/normal parts at ``x`` (its area-weighted vertex normal) and the gates read by a small
MLP, shared by all vertices and frames, from scale-free local features ``φ``: the tangential and signed normal
parts of ``c - x`` and the umbrella curvature, each divided by the vertex's mean edge length, and the cosine between
the vertex normal and the normal of the face of ``W(S_{k-1})`` it slides to. ``a = 1`` copies the previous frame
(no flicker, the registration's error on frame ``k``), ``a = 0`` keeps the frame-``k`` placement: the gates learn,
from the temporal-consistency loss, where following the previous frame costs little on frame ``k``. The default
slides along the surface only (``across=False``): a tangential slide changes the surface by second-order amounts, while
a normal one trades the two directions of the frame-``k`` error against each other (docs/training.md measures both).

The output is differentiable in the parameters, in ``x`` and in the warped previous vertices (through ``c``), so
the loss trains it end to end through a chain of frames.
"""

from __future__ import annotations

import numbers

import numpy as np
import torch
from torch import Tensor, nn

from torchmeshmetric._checks import DTypeError, EmptyInputError, check_flag, check_same_device
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["TemporalSlide", "vertex_normals_and_scale"]

_NUM_FEATURES = 4


def vertex_normals_and_scale(verts: Tensor, faces: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Unit area-weighted normals ``(V, 3)``, mean incident edge lengths ``(V,)`` and umbrella heights ``(V,)``.

    The umbrella height is the normal component of the mean of the neighbours minus the vertex.
    """
    v = verts.detach()
    fn = torch.linalg.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])  # |fn| = 2 area
    normals = torch.zeros_like(v).index_add_(0, faces.reshape(-1), fn.repeat_interleave(3, 0))
    normals = normals / normals.norm(dim=1, keepdim=True).clamp_min(torch.finfo(v.dtype).tiny)
    edges = torch.cat([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    ends = torch.cat([edges, edges.flip(1)])
    ones = torch.ones(ends.shape[0], dtype=v.dtype)
    count = torch.zeros(v.shape[0], dtype=v.dtype).index_add_(0, ends[:, 0], ones).clamp_min(1)
    length = (v[ends[:, 0]] - v[ends[:, 1]]).norm(dim=1)
    scale = torch.zeros(v.shape[0], dtype=v.dtype).index_add_(0, ends[:, 0], length) / count
    mean_nb = torch.zeros_like(v).index_add_(0, ends[:, 0], v[ends[:, 1]]) / count[:, None]
    umbrella = ((mean_nb - v) * normals).sum(1)
    return normals, scale.clamp_min(torch.finfo(v.dtype).tiny), umbrella


class TemporalSlide(nn.Module):
    """Per-vertex gated slide towards the warped previous simplified frame (see the module docstring).

    Args:
        hidden: width of the MLP's two hidden layers.
        initial_gate: the gates' value before training, in ``(0, 1)`` (the last layer starts at zero): small keeps
            the frame-``k`` placement.
        across: also learn the normal gate ``a_n`` (default: tangential slide only).

    Example:
        >>> import trimesh
        >>> from torchmeshmetric import as_mesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=2)).to(dtype=torch.float64)
        >>> moved = Mesh(sphere.verts * 1.01, sphere.faces)
        >>> slide = TemporalSlide(initial_gate=0.5, across=True).double()
        >>> out = slide(sphere, moved)
        >>> out.shape, bool(((out.norm(dim=1) - 1.005).abs() < 1e-3).all())
        (torch.Size([162, 3]), True)
    """

    def __init__(self, hidden: int = 32, initial_gate: float = 0.01, across: bool = False) -> None:
        across = check_flag(across, "across")
        super().__init__()
        self.across = across
        if isinstance(hidden, (bool, np.bool_)) or not isinstance(hidden, numbers.Integral) or hidden < 1:
            raise ValueError(f"hidden: expected an int >= 1 (the hidden layers' width), found {hidden!r}")
        width = int(hidden)
        if not 0.0 < initial_gate < 1.0:
            raise ValueError(f"initial_gate: expected a float in (0, 1), found {initial_gate!r}")
        last = nn.Linear(width, 2 if across else 1)
        nn.init.zeros_(last.weight)
        nn.init.constant_(last.bias, float(torch.logit(torch.tensor(initial_gate))))
        hidden_layers = [nn.Linear(_NUM_FEATURES, width), nn.SiLU(), nn.Linear(width, width), nn.SiLU()]
        self.net: nn.Sequential = nn.Sequential(*hidden_layers, last)

    @property
    def dtype(self) -> torch.dtype:
        """The parameters' dtype (the slid vertices are computed in it)."""
        return next(self.parameters()).dtype

    def gates(self, features: Tensor) -> Tensor:
        """``(V, 2)`` tangential and normal gates in ``(0, 1)`` of ``features (V, 4)`` (``(V, 1)``: tangential only)."""
        return torch.sigmoid(self.net(features.to(self.dtype)))

    def forward(self, simplified_k: Mesh | MeshLike, warped_previous: Mesh | MeshLike) -> Tensor:
        """``(V, 3)`` slid vertices of ``simplified_k`` (its faces unchanged).

        Args:
            simplified_k: the simplified frame ``k`` (``V`` vertices).
            warped_previous: the simplified frame ``k-1`` moved onto frame ``k`` (its vertices may carry gradients).
        """
        simplified_k = as_mesh(simplified_k, name="simplified_k")
        warped_previous = as_mesh(warped_previous, name="warped_previous")
        for name, m in (("simplified_k", simplified_k), ("warped_previous", warped_previous)):
            if m.num_faces == 0:
                raise EmptyInputError(f"{name}: expected a mesh with faces, found {m.num_verts} vertices and none")
        check_same_device({"simplified_k": simplified_k.verts, "warped_previous": warped_previous.verts})
        if warped_previous.verts.dtype != simplified_k.verts.dtype:
            raise DTypeError(
                f"warped_previous: expected simplified_k's dtype {simplified_k.verts.dtype}, found "
                f"{warped_previous.verts.dtype}"
            )
        x = simplified_k.verts
        hit = point_mesh_distance(x, warped_previous.verts, warped_previous.faces)
        d = hit.closest - x
        normals, scale, umbrella = vertex_normals_and_scale(x, simplified_k.faces)
        dn = (d * normals).sum(1, keepdim=True)
        dt = d - dn * normals
        pv = warped_previous.verts.detach()
        tri = pv[warped_previous.faces[hit.face_idx]]
        fn = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        cos = (fn * normals).sum(1) / fn.norm(dim=1).clamp_min(torch.finfo(x.dtype).tiny)
        features = torch.stack(
            [dt.detach().norm(dim=1) / scale, dn.detach()[:, 0] / scale, umbrella / scale, cos], dim=1
        )
        g = self.gates(features).to(x.dtype)
        out = x + g[:, :1] * dt
        return out + g[:, 1:] * dn * normals if self.across else out
