"""The exact kernels' torch formulation adds every 3-term sum in one fixed order, whatever the device (review M, 1).

A reduction such as ``(x * y).sum(-1)`` leaves its order to the device: the CPU adds a size-3 last dimension in
sequence, ``(p0 + p1) + p2``, but CUDA's reduction kernel gives each output two threads and computes
``(p0 + p2) + p1``. The C++ (``triangle.h`` ``dot3``) and Triton kernels hard-code ``(x0*y0 + x1*y1) + x2*y2``, so on
a GPU the torch brute force chose other faces than the Triton kernel at near-ties (2.5 % of the selections of
``test_cuda_compiled_kernel_matches_bruteforce``'s case). These CPU tests emulate CUDA's order by intercepting
every last-dimension ``sum`` of size 3 and assert that no result changes: the formulation must not reduce.
"""

from __future__ import annotations

import pytest
import torch
import trimesh
from torch.utils._python_dispatch import TorchDispatchMode

from torchmeshmetric import closest_point_on_triangle, nearest_vertex_distance, point_mesh_distance
from torchmeshmetric.kernels._common import dot
from torchmeshmetric.temporal._diameter import squared_distances

aten = torch.ops.aten


class CudaSumOrder(TorchDispatchMode):
    """Computes every ``sum`` over a last dimension of size 3 in CUDA's order ``(p0 + p2) + p1``; counts them."""

    def __init__(self) -> None:
        super().__init__()
        self.reordered = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):  # type: ignore[no-untyped-def]
        kwargs = kwargs or {}
        if func is aten.sum.dim_IntList:
            x, dims = args[0], args[1]
            keepdim = args[2] if len(args) > 2 else kwargs.get("keepdim", False)
            if x.dim() > 0 and x.shape[-1] == 3 and dims is not None and [d % x.dim() for d in dims] == [x.dim() - 1]:
                self.reordered += 1
                p0, p1, p2 = x.unbind(-1)
                out = (p0 + p2) + p1
                return out.unsqueeze(-1) if keepdim else out
        return func(*args, **kwargs)


def _bits(t: torch.Tensor) -> torch.Tensor:
    """The bit pattern of a float tensor (so that -0.0 and 0.0, or two NaNs, are told apart)."""
    return t.contiguous().view(torch.int64 if t.dtype == torch.float64 else torch.int32)


def _assert_same_bits(a: tuple[torch.Tensor, ...], b: tuple[torch.Tensor, ...]) -> None:
    for x, y in zip(a, b, strict=True):
        if x.dtype.is_floating_point:
            assert torch.equal(_bits(x), _bits(y))
        else:
            assert torch.equal(x, y)


def _adversarial(n: int, dtype: torch.dtype, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Rows whose products ``p0, p1, p2`` mix magnitudes and signs, so that ``(p0 + p1) + p2 != (p0 + p2) + p1``."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 3, generator=g, dtype=dtype) * 10.0 ** torch.randint(-4, 5, (n, 3), generator=g).to(dtype)
    y = torch.randn(n, 3, generator=g, dtype=dtype)
    return x, y


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_dot_adds_in_the_kernels_order(dtype):
    x, y = _adversarial(100_000, dtype)
    p = x * y
    cuda_order = (p[:, 0] + p[:, 2]) + p[:, 1]
    ordered = (p[:, 0] + p[:, 1]) + p[:, 2]
    assert (cuda_order != ordered).sum() > 1000  # the inputs do tell the two orders apart
    assert torch.equal(_bits(dot(x, y)), _bits(ordered))
    with CudaSumOrder() as mode:
        got = dot(x, y)
    assert mode.reordered == 0
    assert torch.equal(_bits(got), _bits(ordered))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_selection_does_not_depend_on_the_reduction_order(dtype):
    # test_cuda_compiled_kernel_matches_bruteforce's case, smaller: with (x * y).sum(-1) in dot, CUDA's order changed
    # the face of 2.5 % of these points (and 100 of their distances by an ulp) against the sequential order.
    mesh = trimesh.creation.icosphere(subdivisions=3)
    verts = torch.tensor(mesh.vertices, dtype=dtype)
    faces = torch.tensor(mesh.faces)
    g = torch.Generator().manual_seed(13)
    points = torch.cat([torch.randn(6000, 3, generator=g, dtype=dtype) * 1.3, verts[:300]])
    for backend in ("bruteforce", "pruned"):
        plain = tuple(point_mesh_distance(points, verts, faces, backend=backend))
        with CudaSumOrder() as mode:
            emulated = tuple(point_mesh_distance(points, verts, faces, backend=backend))
        _assert_same_bits(plain, emulated)
        assert mode.reordered == 0, f"{backend}: the point->mesh formulation reduces over the coordinates"
        plain = tuple(nearest_vertex_distance(points, verts, backend=backend))
        with CudaSumOrder() as mode:
            emulated = tuple(nearest_vertex_distance(points, verts, backend=backend))
        _assert_same_bits(plain, emulated)
        assert mode.reordered == 0, f"{backend}: the nearest-point formulation reduces over the coordinates"


def test_primitive_and_diameter_do_not_reduce():
    x, y = _adversarial(3000, torch.float64, seed=1)
    a, b, c = x, x + y, x + torch.roll(y, 1, 0)
    q = x + 3 * torch.roll(y, 2, 0)
    with CudaSumOrder() as mode:
        closest_point_on_triangle(q, a, b, c)
        squared_distances(x[:, None], y[None])
    assert mode.reordered == 0
