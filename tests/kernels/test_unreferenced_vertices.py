"""A vertex no face references changes no distance (review I #1).

The kernels centre each mesh on a bounding box and take an exact power-of-two range scale from its extent. Both came
from every vertex, so one stray unreferenced vertex far away (captured frames carry them, ``add_capture_defects``)
moved the centre off the surface and float32 lost the digits of every short distance: a point 0.29 from a unit
sphere measured 3e-8 with a stray vertex at 1e9, and 0.291869 (0.5 % off) with one at 1e6. The box and the extent
now come from the referenced vertices, so a mesh with a stray vertex answers what the mesh without it answers, bit
for bit, and the float64 truth within the dtype's rounding.
"""

from __future__ import annotations

import pickle

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, MeshIndex, nearest_vertex_distance, point_mesh_distance
from torchmeshmetric.kernels._common import referenced_rows
from torchmeshmetric.metrics import (
    MeshSurfaceDistance,
    MeshSurfaceDistanceLoss,
    NearestVertexDistanceLoss,
    mesh_surface_distance_loss,
)
from torchmeshmetric.native import try_load

BACKENDS = ["bruteforce", "pruned", "bvh"]
# Stray positions per dtype: each broke the old centring (float32 at 1e4 already by 6e-6, beyond the 1e-6 bound), and
# 1e30 / 1e300 also forced the old range scale, which shrank the unit sphere's squared areas into subnormals.
STRAYS = [(torch.float32, 1e4), (torch.float32, 1e9), (torch.float32, 1e30), (torch.float64, 1e15)]
STRAYS += [(torch.float64, 1e300)]
# Largest error of a distance to the unit sphere against the float64 truth: 8 ulps of the coordinate scale (1).
ATOL = {torch.float32: 8 * torch.finfo(torch.float32).eps, torch.float64: 8 * torch.finfo(torch.float64).eps}


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    # The "bvh" backend is the C++ extension: compile (or load) it once, a missing compiler fails here.
    assert try_load("bvh") is not None


def sphere(dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
    s = trimesh.creation.icosphere(subdivisions=3)
    return torch.tensor(s.vertices, dtype=dtype), torch.tensor(s.faces)


def with_stray(verts: torch.Tensor, far: float, row: int | None = None) -> torch.Tensor:
    """``verts`` with an unreferenced vertex at ``(far, 0, 0)`` appended, or inserted before ``row`` (faces shift)."""
    stray = torch.tensor([[far, 0.0, 0.0]], dtype=verts.dtype)
    if row is None:
        return torch.cat([verts, stray])
    return torch.cat([verts[:row], stray, verts[row:]])


def queries(dtype: torch.dtype) -> torch.Tensor:
    """The review's two points (0.01 and 0.29 from the sphere) and points in and around it."""
    g = torch.Generator().manual_seed(0)
    named = torch.tensor([[0.0, 0.0, 1.01], [0.3, 0.4, 0.5]], dtype=dtype)
    return torch.cat([named, 1.5 * (2 * torch.rand(200, 3, generator=g, dtype=dtype) - 1)])


def truth(points: torch.Tensor) -> torch.Tensor:
    v, f = sphere(torch.float64)
    return point_mesh_distance(points.double(), v, f, backend="bruteforce").dists


def assert_same(got, clean) -> None:
    for name, a, b in zip(got._fields, got, clean, strict=True):
        assert torch.equal(a, b), f"{name} differs from the mesh without the stray vertex"


def test_the_reviews_repro_float32_point_0_29_from_the_sphere():
    v, f = sphere(torch.float32)
    q = torch.tensor([[0.0, 0.0, 1.01], [0.3, 0.4, 0.5]])
    for far in (1e4, 1e6, 1e9):
        d = point_mesh_distance(q, with_stray(v, far), f).dists
        # Old: 0.29038990 (1e4), 0.29186946 (1e6), 2.98e-08 (1e9); float64 truth 0.2903842758.
        assert d.tolist() == pytest.approx([0.00999999, 0.2903842758], abs=1e-7)
        assert torch.equal(d, point_mesh_distance(q, v, f).dists)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("dtype", "far"), STRAYS)
def test_point_mesh_distance_is_that_of_the_mesh_without_the_stray_vertex(backend, dtype, far):
    v, f = sphere(dtype)
    q = queries(dtype)
    clean = point_mesh_distance(q, v, f, backend=backend)
    got = point_mesh_distance(q, with_stray(v, far), f, backend=backend)
    assert_same(got, clean)
    torch.testing.assert_close(got.dists.double(), truth(q), rtol=0, atol=ATOL[dtype])
    # A stray row among the referenced ones (faces renumbered): the same answer, faces and all.
    row = 100
    got = point_mesh_distance(q, with_stray(v, far, row), f + (f >= row).long(), backend=backend)
    assert_same(got, clean)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("dtype", "far"), STRAYS)
def test_mesh_index_queries_refits_copies_and_gradients_ignore_the_stray_vertex(backend, dtype, far):
    v, f = sphere(dtype)
    q = queries(dtype)
    vs = with_stray(v, far)
    index, clean_index = MeshIndex(vs, f, backend=backend), MeshIndex(v, f, backend=backend)
    assert_same(index.point_mesh_distance(q), clean_index.point_mesh_distance(q))
    torch.testing.assert_close(index.point_mesh_distance(q).dists.double(), truth(q), rtol=0, atol=ATOL[dtype])
    # Refit: the surface moves by 0.25, the stray vertex elsewhere far away; the same rows stay the reference.
    moved = v + 0.25
    index.refit(torch.cat([moved, torch.tensor([[0.0, -far, far]], dtype=dtype)]))
    clean_index.refit(moved)
    assert_same(index.point_mesh_distance(q), clean_index.point_mesh_distance(q))
    # A copy over equal vertices, and a pickled index, keep the frame.
    assert_same(index.with_verts(index.verts.clone()).point_mesh_distance(q), clean_index.point_mesh_distance(q))
    assert_same(pickle.loads(pickle.dumps(index)).point_mesh_distance(q), clean_index.point_mesh_distance(q))
    # Gradients: to the points and to the referenced vertices those of the clean mesh, none to the stray vertex.
    grads = []
    for verts in (vs, v):
        x, p = verts.clone().requires_grad_(), q.clone().requires_grad_()
        MeshIndex(x, f, backend=backend).point_mesh_distance(p).dists.sum().backward()
        grads.append((x.grad, p.grad))
    assert torch.equal(grads[0][1], grads[1][1])
    assert torch.equal(grads[0][0][:-1], grads[1][0]) and not bool(grads[0][0][-1].any())


@pytest.mark.parametrize(("dtype", "far"), STRAYS)
def test_nearest_vertex_queries_of_an_index_ignore_the_stray_vertex(dtype, far):
    v, f = sphere(dtype)
    q = queries(dtype)
    got = MeshIndex(with_stray(v, far), f).nearest_vertex_distance(q)
    assert_same(got, nearest_vertex_distance(q, v))


@pytest.mark.parametrize(("dtype", "far"), STRAYS)
def test_a_ragged_batch_centres_each_item_on_its_own_referenced_vertices(dtype, far):
    v, f = sphere(dtype)
    q = queries(dtype)
    second = (v * 0.5 + 3.0, f)
    clean = point_mesh_distance([q, q + 3.0], [(v, f), second])
    got = point_mesh_distance([q, q + 3.0], [(with_stray(v, far), f), second])
    # Packed face rows are the same; the packed vertex rows of the second item are shifted by one.
    assert_same(got, clean)
    torch.testing.assert_close(got.dists[: q.shape[0]].double(), truth(q), rtol=0, atol=ATOL[dtype])


def test_referenced_rows_is_none_when_every_vertex_is_referenced():
    v, f = sphere(torch.float32)
    assert referenced_rows(f, v.shape[0]) is None
    rows = referenced_rows(f + (f >= 5).long(), v.shape[0] + 1)
    assert rows is not None and rows.tolist() == [r for r in range(v.shape[0] + 1) if r != 5]


@pytest.mark.parametrize(("dtype", "far"), [(torch.float32, 1e4), (torch.float32, 1e9), (torch.float64, 1e15)])
def test_mesh_surface_distance_metric_with_a_stray_vertex_in_the_reference(dtype, far):
    v, f = sphere(dtype)
    simplified = Mesh(v * 1.05, f)
    stats = []
    for ref in (Mesh(v, f), Mesh(with_stray(v, far), f)):
        metric = MeshSurfaceDistance()
        metric.update(simplified, ref)
        stats.append(metric.compute())
    # Old, float32, stray at 1e9: ave 4.895, max 64.0; clean 0.0500 / 0.0500.
    assert float(stats[1]["ave"]) == pytest.approx(0.05, abs=1e-3) and float(stats[1]["max"]) == pytest.approx(0.05)
    for key in ("ave", "max", "min", "mse"):
        assert torch.equal(stats[0][key], stats[1][key]), key


@pytest.mark.parametrize("far", [1e4, 1e5, 1e6])
def test_the_reviews_plausible_stray_vertex_keeps_the_max(far):
    v, f = sphere(torch.float32)
    metric = MeshSurfaceDistance()
    metric.update(Mesh(v * 1.001, f), Mesh(with_stray(v, far), f))
    # Old: 0.00159 (1e4), 0.00459 (1e5), 0.0351 (1e6); clean 0.00100.
    assert float(metric.compute()["max"]) == pytest.approx(0.001, rel=1e-3)


@pytest.mark.parametrize(("dtype", "far"), [(torch.float32, 1e9), (torch.float64, 1e15)])
@pytest.mark.parametrize("two_sided", [False, True])
def test_surface_and_vertex_losses_and_gradients_ignore_the_stray_vertex(dtype, far, two_sided):
    v, f = sphere(dtype)
    g = torch.Generator().manual_seed(1)
    moved = v * 1.02 + 0.01 * torch.randn(v.shape, generator=g, dtype=dtype)
    out = []
    for ref in (Mesh(v, f), Mesh(with_stray(v, far), f)):
        terms = []
        for loss in (
            lambda s, r: mesh_surface_distance_loss(s, r, two_sided=two_sided, power=2),
            MeshSurfaceDistanceLoss(two_sided=two_sided),
            NearestVertexDistanceLoss(two_sided=two_sided),
        ):
            x = moved.clone().requires_grad_()
            value = loss(Mesh(x, f), ref)
            value.backward()
            terms.append((value.detach(), x.grad))
        out.append(terms)
    for (value_clean, grad_clean), (value, grad) in zip(*out, strict=True):
        assert torch.equal(value, value_clean) and torch.equal(grad, grad_clean)
        assert bool(torch.isfinite(grad).all()) and float(value) > 0


def test_an_index_pickled_when_every_vertex_set_the_centre_is_recentred_on_unpickling():
    # Indexes pickled before this fix carry the all-vertex centre and no `_centre_rows`: unpickled, they centre on the
    # referenced vertices as a new index does (their structures are rebuilt on the first query anyway).
    from torchmeshmetric.kernels._common import centred, range_scale
    from torchmeshmetric.kernels.contract import FaceSet

    v, f = sphere(torch.float32)
    q = queries(torch.float32)
    vs = with_stray(v, 1e9)
    state = MeshIndex(vs, f).__getstate__()
    del state["_centre_rows"]
    centers, row_centers, _ = centred(vs, state["verts_lengths"])  # the old frame: every vertex
    old_c = vs - row_centers
    scale = range_scale(float(old_c.abs().amax()), vs.dtype, 4)
    assert scale is not None  # the old frame was scaled for the stray vertex (2**-29)
    state.update(_centers=centers, _vert_center=row_centers, _scale=scale)
    state["_faceset"] = FaceSet(old_c * scale, *state["_faceset"][1:])
    index = MeshIndex.__new__(MeshIndex)
    index.__setstate__(state)
    assert_same(index.point_mesh_distance(q), MeshIndex(v, f).point_mesh_distance(q))


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_stray_vertex_that_a_tiny_meshs_scale_overflows_is_never_read(backend):
    # A float32 sphere of 1e-20 units is scaled by 2**67; a stray vertex at 1e30 becomes Inf in that frame, in a row
    # no face reads. Before, the scale came from the stray vertex (2**-100) and the sphere underflowed to 0.
    v, f = sphere(torch.float32)
    v = v * 1e-20
    q = queries(torch.float32) * 1e-20
    vs = with_stray(v, 1e30)
    assert_same(point_mesh_distance(q, vs, f, backend=backend), point_mesh_distance(q, v, f, backend=backend))
    x, p = vs.clone().requires_grad_(), q.clone().requires_grad_()
    got = MeshIndex(x, f, backend=backend).point_mesh_distance(p)
    got.dists.sum().backward()
    assert torch.equal(got.dists.detach(), point_mesh_distance(q, v, f, backend=backend).dists)
    assert bool(torch.isfinite(x.grad).all()) and bool(torch.isfinite(p.grad).all()) and not bool(x.grad[-1].any())
    truth = point_mesh_distance(q.double() * 1e20, v.double() * 1e20, f, backend="bruteforce").dists * 1e-20
    torch.testing.assert_close(got.dists.detach().double(), truth, rtol=0, atol=ATOL[torch.float32] * 1e-20)
