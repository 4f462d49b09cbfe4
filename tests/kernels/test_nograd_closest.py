"""The C++ closest-point kernel used without autograd is bit-identical to the torch recomputation.

``point_mesh_distance`` recomputes the closest point on the selected face with torch ops when something requires
grad, and with ``bvh_closest_points`` (C++) otherwise. Both must give the same distances, barycentrics and closest
points bit for bit, in every Voronoi region and for degenerate faces.
"""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric.kernels import mesh_index
from torchmeshmetric.kernels.accel import bvh_closest_points
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.kernels.select import Selector
from torchmeshmetric.kernels.triangle import closest_point_on_triangle
from torchmeshmetric.native import try_load


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    assert try_load("bvh") is not None


def _both(points: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor, **kw: torch.Tensor):
    fast = point_mesh_distance(points, verts, faces, backend="bvh", **kw)
    graded = point_mesh_distance(points, verts.clone().requires_grad_(), faces, backend="bvh", **kw)
    return fast, graded


def _assert_identical(points: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor, **kw: torch.Tensor) -> None:
    fast, graded = _both(points, verts, faces, **kw)
    assert torch.equal(fast.face_idx, graded.face_idx)
    for name in ("dists", "bary", "closest"):
        a, b = getattr(fast, name), getattr(graded, name).detach()
        assert a.dtype == b.dtype and torch.equal(a, b), name


def test_the_kernels_serve_calls_without_autograd(monkeypatch: pytest.MonkeyPatch) -> None:
    fused_calls: list[int | None] = []
    closest_calls: list[int] = []
    select_closest = Selector.select_closest

    def fused_spy(self: Selector, points: torch.Tensor, point_batch: torch.Tensor):
        out = select_closest(self, points, point_batch)
        fused_calls.append(None if out is None else out[0].shape[0])
        return out

    def closest_spy(*args: torch.Tensor):
        closest_calls.append(args[0].shape[0])
        return bvh_closest_points(*args)

    monkeypatch.setattr(Selector, "select_closest", fused_spy)
    monkeypatch.setattr(mesh_index, "bvh_closest_points", closest_spy)
    mesh = trimesh.creation.icosphere(subdivisions=2)
    verts, faces = torch.tensor(mesh.vertices, dtype=torch.float32), torch.tensor(mesh.faces)
    points = torch.randn(50, 3, generator=torch.Generator().manual_seed(0))
    point_mesh_distance(points, verts, faces, backend="bvh")
    assert (fused_calls, closest_calls) == ([50], [])  # the BVH's selection and closest point in one pass
    point_mesh_distance(points, verts, faces, backend="pruned")
    assert (fused_calls, closest_calls) == ([50, None], [50])  # no fused query: the C++ closest-point pass
    point_mesh_distance(points.requires_grad_(), verts, faces, backend="bvh")
    assert (fused_calls, closest_calls) == ([50, None], [50])  # autograd: the differentiable torch recomputation


@pytest.mark.parametrize("backend", ["bvh", "pruned"])
def test_fused_and_two_pass_answers_are_identical(backend: str) -> None:
    g = torch.Generator().manual_seed(4)
    verts = torch.randn(200, 3, generator=g)
    faces = torch.randint(0, 200, (400, 3), generator=g)
    points = torch.cat([torch.randn(500, 3, generator=g), verts[:50]])
    got = point_mesh_distance(points, verts, faces, backend=backend)
    ref = point_mesh_distance(points, verts, faces, backend="bruteforce")
    for a, b in zip(got, ref, strict=True):
        assert torch.equal(a, b)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_random_meshes_every_region(dtype: torch.dtype, offset: float) -> None:
    g = torch.Generator().manual_seed(1)
    verts = torch.randn(300, 3, generator=g, dtype=dtype) + offset
    faces = torch.randint(0, 300, (500, 3), generator=g)
    points = torch.cat(
        [
            torch.randn(3000, 3, generator=g, dtype=dtype) * 1.5 + offset,
            verts[:100],  # on vertices (vertex regions, distance 0)
            (verts[faces[:100, 0]] + verts[faces[:100, 1]]) / 2,  # on edges
            verts[faces[:100]].mean(1),  # centroids (face region)
        ]
    )
    _assert_identical(points, verts, faces)


def test_degenerate_faces() -> None:
    verts = torch.tensor(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [3, 0, 0], [1, 0, 0], [0, 0, 1], [0.5, 0.5, 0.0]],
        dtype=torch.float64,
    )
    faces = torch.tensor([[0, 1, 2], [1, 3, 2], [1, 4, 5], [4, 4, 4], [1, 6, 3], [0, 2, 7], [0, 1, 2], [8, 8, 1]])
    g = torch.Generator().manual_seed(2)
    points = torch.cat([torch.rand(2000, 3, generator=g, dtype=torch.float64) * 4 - 1, verts])
    _assert_identical(points, verts, faces)
    # Only the collinear and point faces: the face region never applies.
    _assert_identical(points, verts, faces[[2, 3, 7]])


def test_ragged_batch() -> None:
    g = torch.Generator().manual_seed(3)
    meshes = [trimesh.creation.icosphere(subdivisions=2), trimesh.creation.box(), trimesh.creation.torus(1.0, 0.3)]
    verts = [torch.tensor(m.vertices, dtype=torch.float32) + 5.0 * i for i, m in enumerate(meshes)]
    faces = [torch.tensor(m.faces) for m in meshes]
    clouds = [torch.randn(n, 3, generator=g) + 5.0 * i for i, n in enumerate((400, 3, 900))]
    _assert_identical(
        torch.cat(clouds),
        torch.cat(verts),
        torch.cat(faces),
        points_lengths=torch.tensor([len(c) for c in clouds]),
        verts_lengths=torch.tensor([len(v) for v in verts]),
        faces_lengths=torch.tensor([len(f) for f in faces]),
    )


def test_kernel_matches_closest_point_on_triangle_directly() -> None:
    # The kernel itself, on given (not selected) faces, against the public elementwise function.
    g = torch.Generator().manual_seed(4)
    verts = torch.randn(60, 3, generator=g)
    faces = torch.randint(0, 60, (80, 3), generator=g)
    points = torch.randn(5000, 3, generator=g) * 2
    face_idx = torch.randint(0, 80, (5000,), generator=g)
    out = bvh_closest_points(points, verts, faces, face_idx)
    assert out is not None
    tri = verts[faces[face_idx]]
    ref = closest_point_on_triangle(points, tri[:, 0], tri[:, 1], tri[:, 2])
    assert torch.equal(out[0], ref.sq_dists)
    assert torch.equal(out[1], ref.bary)
    assert torch.equal(out[2], ref.closest)


def test_not_used_off_the_cpu_or_for_half_precision() -> None:
    p = torch.zeros(2, 3, dtype=torch.float16)
    assert bvh_closest_points(p, p, torch.zeros(1, 3, dtype=torch.long), torch.zeros(2, dtype=torch.long)) is None
    m = torch.zeros(2, 3, device="meta")
    assert bvh_closest_points(m, m, torch.zeros(1, 3, dtype=torch.long), torch.zeros(2, dtype=torch.long)) is None
