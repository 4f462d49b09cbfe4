"""The dtype rule at the kernel entries: ``point_mesh_distance``, ``nearest_vertex_distance`` and ``MeshIndex`` queries.

Inputs of float32 and float64 answer in their promoted dtype, bit for bit the float64 computation on the float32
values widened when either is float64; gradients come back in each input's dtype. An index answers narrower or equal
points in its own dtype and refuses wider ones (they would be rounded), saying how to build it.
"""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric import DTypeError, Mesh, MeshIndex, nearest_vertex_distance, point_mesh_distance

F32, F64 = torch.float32, torch.float64
SPHERE = trimesh.creation.icosphere(subdivisions=2)
POINTS = torch.tensor(trimesh.creation.icosphere(subdivisions=1).vertices * 1.3 + 0.01)


def _points(dtype: torch.dtype, widened: bool = False) -> torch.Tensor:
    p = POINTS.to(dtype, copy=True)
    return (p.to(F64) if widened else p).requires_grad_(True)


def _mesh(form: str, widened: bool = False) -> tuple[object, torch.Tensor | None]:
    if form == "trimesh":
        return SPHERE, None
    dtype = F32 if form.endswith("32") else F64
    v = torch.tensor(SPHERE.vertices, dtype=dtype)
    v = (v.to(F64) if widened else v).requires_grad_(True)
    f = torch.tensor(SPHERE.faces)
    return ((v, f) if form.startswith("pair") else Mesh(v, f)), v


def _form_dtype(form: str) -> torch.dtype:
    return F32 if form.endswith("32") else F64


@pytest.mark.parametrize("mesh_form", ["pair32", "pair64", "Mesh32", "Mesh64", "trimesh"])
@pytest.mark.parametrize("points_dtype", [F32, F64])
@pytest.mark.parametrize("kernel", ["point_mesh_distance", "nearest_vertex_distance"])
def test_kernels_answer_in_the_promoted_dtype(kernel: str, points_dtype: torch.dtype, mesh_form: str) -> None:
    def run(widened: bool) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        p, (mesh, v) = _points(points_dtype, widened), _mesh(mesh_form, widened)
        if kernel == "point_mesh_distance":
            d = point_mesh_distance(p, mesh).dists
        else:
            ref = mesh.verts if isinstance(mesh, Mesh) else mesh[0] if isinstance(mesh, tuple) else SPHERE.vertices
            d = nearest_vertex_distance(p, torch.as_tensor(ref)).dists
        d.sum().backward()
        return d, p, v

    promoted = torch.promote_types(points_dtype, _form_dtype(mesh_form))
    d, p, v = run(widened=False)
    d64, p64, v64 = run(widened=True)
    assert d.dtype == promoted
    assert p.grad is not None and p.grad.dtype == points_dtype
    assert v is None or (v.grad is not None and v.grad.dtype == v.dtype)
    if promoted == F64:  # the same float64 computation on the same values: bit for bit, gradients rounded once
        assert torch.equal(d, d64)
        assert torch.equal(p.grad, p64.grad.to(points_dtype))
        assert v is None or torch.equal(v.grad, v64.grad.to(v.dtype))
    else:  # float32 within 2e-6 of the diagonal of a float64 oracle (docs/benchmarks.md, Exactness)
        torch.testing.assert_close(d.double(), d64.detach(), rtol=0, atol=2e-6 * 3.5)


@pytest.mark.parametrize("points_dtype", [F32, F64])
@pytest.mark.parametrize("index_dtype", [F32, F64])
@pytest.mark.parametrize("query", ["point_mesh_distance", "nearest_vertex_distance"])
def test_an_index_answers_narrower_points_and_refuses_wider_ones(
    query: str, index_dtype: torch.dtype, points_dtype: torch.dtype
) -> None:
    index = MeshIndex(torch.tensor(SPHERE.vertices, dtype=index_dtype), torch.tensor(SPHERE.faces))
    p = _points(points_dtype)
    if torch.promote_types(index_dtype, points_dtype) != index_dtype:
        wider = r"points: expected an index of dtype torch\.float64 .*MeshIndex\(mesh\.to"
        with pytest.raises(DTypeError, match=wider):
            getattr(index, query)(p)
        return
    d = getattr(index, query)(p).dists
    assert d.dtype == index_dtype
    # What the function answers for the same points and the index's mesh (the function promotes the same way).
    if query == "point_mesh_distance":
        expected = point_mesh_distance(p, index.verts, index.faces).dists
    else:
        expected = nearest_vertex_distance(p, index.ref_points.points).dists
    assert torch.equal(d, expected)
    d.sum().backward()
    assert p.grad is not None and p.grad.dtype == points_dtype
