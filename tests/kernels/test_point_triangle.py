"""closest_point_on_triangle and point_mesh_distance against the Ericson reference, trimesh and analytic cases."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from tests import reference
from torchmeshmetric import (
    DeviceError,
    DTypeError,
    EmptyInputError,
    IndexRangeError,
    Mesh,
    NonFiniteError,
    ShapeError,
    closest_point_on_triangle,
    point_mesh_distance,
)
from torchmeshmetric.kernels._common import pair_chunks

A, B, C = np.array([0.0, 0, 0]), np.array([2.0, 0, 0]), np.array([0.0, 2, 0])

# One query point in each of the seven Voronoi regions of triangle ABC, with its known closest point.
VORONOI = {
    "vertex_a": ([-1.0, -1.0, 0.5], [0.0, 0.0, 0.0]),
    "vertex_b": ([3.0, -0.5, -1.0], [2.0, 0.0, 0.0]),
    "vertex_c": ([-0.5, 3.0, 2.0], [0.0, 2.0, 0.0]),
    "edge_ab": ([1.0, -1.0, 0.3], [1.0, 0.0, 0.0]),
    "edge_ac": ([-1.0, 1.5, -0.7], [0.0, 1.5, 0.0]),
    "edge_bc": ([1.5, 1.5, 1.0], [1.0, 1.0, 0.0]),
    "face": ([0.5, 0.5, -2.0], [0.5, 0.5, 0.0]),
}


@pytest.mark.parametrize("region", list(VORONOI))
def test_each_voronoi_region(region: str, dtype: torch.dtype, device: str) -> None:
    p, expected = VORONOI[region]
    t = [torch.tensor(x, dtype=dtype, device=device) for x in (p, A, B, C)]
    r = closest_point_on_triangle(*t)
    torch.testing.assert_close(r.closest.cpu(), torch.tensor(expected, dtype=dtype), rtol=0, atol=1e-6)
    np.testing.assert_allclose(
        r.closest.cpu().double().numpy(), reference.closest_point_triangle(p, A, B, C), atol=1e-6
    )
    # Barycentrics reproduce the point and sum to one.
    recon = r.bary[0] * t[1] + r.bary[1] * t[2] + r.bary[2] * t[3]
    torch.testing.assert_close(recon, r.closest, rtol=0, atol=1e-6)
    assert float(r.bary.sum()) == pytest.approx(1.0, abs=1e-6)
    assert float(r.sq_dists) == pytest.approx(float(((np.array(p) - np.array(expected)) ** 2).sum()), rel=1e-6)


DEGENERATE = {
    "collinear": ([0.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]),
    "collinear_middle_last": ([0.0, 0, 0], [3.0, 0, 0], [1.0, 0, 0]),
    "repeated_vertex": ([0.0, 0, 0], [0.0, 0, 0], [0.0, 2, 0]),
    "single_point": ([1.0, 1, 1], [1.0, 1, 1], [1.0, 1, 1]),
}


@pytest.mark.parametrize("name", list(DEGENERATE))
def test_degenerate_triangles_match_reference(name: str, dtype: torch.dtype) -> None:
    a, b, c = (np.array(x) for x in DEGENERATE[name])
    g = np.random.default_rng(0)
    pts = g.normal(scale=2.0, size=(200, 3))
    r = closest_point_on_triangle(torch.tensor(pts, dtype=dtype), *(torch.tensor(x, dtype=dtype) for x in (a, b, c)))
    assert torch.isfinite(r.closest).all() and torch.isfinite(r.bary).all()
    ref = np.stack([reference.closest_point_triangle(p, a, b, c) for p in pts])
    np.testing.assert_allclose(r.closest.double().numpy(), ref, atol=1e-5 if dtype == torch.float32 else 1e-12)


def test_random_triangles_match_reference_and_trimesh() -> None:
    g = np.random.default_rng(1)
    tri = g.normal(size=(500, 3, 3))
    pts = g.normal(scale=2.0, size=(500, 3))
    r = closest_point_on_triangle(*(torch.from_numpy(x) for x in (pts, tri[:, 0], tri[:, 1], tri[:, 2])))
    ref = np.stack([reference.closest_point_triangle(p, *t) for p, t in zip(pts, tri, strict=True)])
    np.testing.assert_allclose(r.closest.numpy(), ref, atol=1e-12)
    oracle = trimesh.triangles.closest_point(tri, pts)
    np.testing.assert_allclose(r.closest.numpy(), oracle, atol=1e-10)


finite = st.floats(min_value=-10, max_value=10, allow_nan=False, allow_subnormal=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(finite, min_size=12, max_size=12))
def test_property_never_farther_than_reference(xs: list[float]) -> None:
    p, a, b, c = (np.array(xs[i : i + 3]) for i in range(0, 12, 3))
    r = closest_point_on_triangle(*(torch.tensor(x) for x in (p, a, b, c)))
    q = reference.closest_point_triangle_exact(p, a, b, c)
    d_ref = float(np.sqrt(((p - q) ** 2).sum()))
    scale = max(1.0, float(np.abs(np.stack([p, a, b, c])).max()))
    assert float(r.sq_dists.sqrt()) == pytest.approx(d_ref, abs=1e-9 * scale)
    # The returned point lies on the triangle: barycentrics in [0, 1] that sum to one.
    assert bool((r.bary >= 0).all()) and bool((r.bary <= 1).all())
    assert float(r.bary.sum()) == pytest.approx(1.0, abs=1e-12)


def _icosphere(sub: int = 2, dtype: torch.dtype = torch.float64) -> Mesh:
    s = trimesh.creation.icosphere(subdivisions=sub)
    return Mesh(torch.tensor(s.vertices, dtype=dtype), torch.tensor(s.faces))


def test_sphere_analytic_distance_one(dtype: torch.dtype, device: str) -> None:
    # Points at radius 2 along vertex directions of an icosphere inscribed in the unit sphere: the vertex is the
    # closest point (radial direction lies in the vertex's normal cone), so the distance is exactly 1.
    m = _icosphere(2, dtype).to(device)
    r = point_mesh_distance(2 * m.verts, m)
    torch.testing.assert_close(r.dists, torch.ones_like(r.dists), rtol=0, atol=4 * torch.finfo(dtype).eps)
    torch.testing.assert_close(r.closest, m.verts, rtol=0, atol=8 * torch.finfo(dtype).eps)


def test_plane_analytic(dtype: torch.dtype) -> None:
    grid = trimesh.creation.box(extents=(4, 4, 0.0))  # a flat (zero-thickness) box is 12 faces, 4 degenerate
    plane = Mesh(torch.tensor(grid.vertices, dtype=dtype), torch.tensor(grid.faces))
    g = torch.Generator().manual_seed(0)
    xy = torch.rand(300, 2, generator=g, dtype=dtype) * 3.6 - 1.8
    h = torch.randn(300, generator=g, dtype=dtype)
    pts = torch.cat([xy, h[:, None]], 1)
    r = point_mesh_distance(pts, plane)
    torch.testing.assert_close(r.dists, h.abs(), rtol=0, atol=8 * torch.finfo(dtype).eps)
    torch.testing.assert_close(r.closest[:, :2], xy, rtol=0, atol=8 * torch.finfo(dtype).eps)


def test_mesh_matches_reference_and_trimesh_oracle() -> None:
    s = trimesh.creation.capsule(height=1.0, radius=0.4, count=[8, 8])
    g = np.random.default_rng(3)
    pts = g.normal(scale=0.8, size=(150, 3))
    r = point_mesh_distance(torch.from_numpy(pts), s)
    d_ref, q_ref = reference.point_mesh_distance(pts, s.vertices, s.faces)
    np.testing.assert_allclose(r.dists.numpy(), d_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.closest.numpy(), q_ref, rtol=0, atol=1e-12)
    _, d_tm, _ = trimesh.proximity.closest_point(s, pts)
    np.testing.assert_allclose(r.dists.numpy(), d_tm, rtol=0, atol=1e-10)
    # face_idx/bary/closest are consistent with each other.
    tri = torch.tensor(s.vertices)[torch.tensor(s.faces)[r.face_idx]]
    torch.testing.assert_close((r.bary[:, :, None] * tri).sum(1), r.closest)


def test_float32_far_from_origin_keeps_relative_accuracy() -> None:
    m64 = _icosphere(2)
    offset = torch.tensor([1e6, -2e6, 5e5], dtype=torch.float64)
    g = torch.Generator().manual_seed(0)
    pts = torch.randn(200, 3, generator=g, dtype=torch.float64) * 1.5
    v32, p32 = (m64.verts + offset).float(), (pts + offset).float()
    r32 = point_mesh_distance(p32, v32, m64.faces)
    # Reference on exactly the same (float32-rounded) inputs, in float64.
    r64 = point_mesh_distance(p32.double(), v32.double(), m64.faces)
    diag = float(m64.bbox_diagonal())
    assert float((r32.dists.double() - r64.dists).abs().max()) <= 1e-6 * diag


def test_points_on_vertices_and_edges_have_zero_distance(dtype: torch.dtype) -> None:
    m = _icosphere(1, dtype)
    e = m.verts[m.faces[:, [0, 1]]]
    pts = torch.cat([m.verts, 0.5 * (e[:, 0] + e[:, 1])])
    r = point_mesh_distance(pts, m)
    assert float(r.dists.max()) <= 4 * torch.finfo(dtype).eps


def test_degenerate_mesh_matches_reference() -> None:
    g = np.random.default_rng(5)
    v = g.normal(size=(30, 3))
    v[10] = v[3]  # duplicated vertex
    v[11] = 0.5 * (v[0] + v[1])  # collinear with 0, 1
    faces = np.concatenate([g.integers(0, 30, size=(40, 3)), [[0, 1, 11], [3, 10, 4], [5, 5, 5], [6, 6, 7]]])
    pts = g.normal(size=(80, 3))
    r = point_mesh_distance(torch.from_numpy(pts), torch.from_numpy(v), torch.from_numpy(faces))
    d_ref, _ = reference.point_mesh_distance(pts, v, faces)
    np.testing.assert_allclose(r.dists.numpy(), d_ref, atol=1e-12)


def test_ragged_batch_equals_individual_calls_and_is_memory_independent(dtype: torch.dtype) -> None:
    meshes = [
        _icosphere(1, dtype),
        Mesh(torch.tensor(trimesh.creation.box().vertices, dtype=dtype), torch.tensor(trimesh.creation.box().faces)),
    ]
    meshes[1] = Mesh(meshes[1].verts + 3.0, meshes[1].faces)
    g = torch.Generator().manual_seed(0)
    pts = [torch.randn(37, 3, generator=g, dtype=dtype), torch.randn(11, 3, generator=g, dtype=dtype) + 3.0]
    batched = point_mesh_distance(pts, meshes)
    singles = [point_mesh_distance(p, m) for p, m in zip(pts, meshes, strict=True)]
    torch.testing.assert_close(batched.dists, torch.cat([s.dists for s in singles]))
    torch.testing.assert_close(batched.face_idx, torch.cat([singles[0].face_idx, singles[1].face_idx + 80]))
    # Same result from packed tensors with lengths, and with a tiny memory budget (many chunks).
    packed = point_mesh_distance(
        torch.cat(pts),
        torch.cat([m.verts for m in meshes]),
        torch.cat([m.faces for m in meshes]),
        points_lengths=torch.tensor([37, 11]),
        verts_lengths=torch.tensor([m.num_verts for m in meshes]),
        faces_lengths=torch.tensor([m.num_faces for m in meshes]),
        max_memory=4096,
    )
    torch.testing.assert_close(packed.dists, batched.dists)
    torch.testing.assert_close(packed.face_idx, batched.face_idx)


def test_chunks_respect_memory_budget() -> None:
    for rows_total, cols_total, budget in [(10**6, 10**6, 256 * 2**20), (10, 12, 10**9), (3, 10**7, 1000)]:
        rows, cols = pair_chunks(rows_total, cols_total, 160, budget)
        assert 1 <= rows <= rows_total and 1 <= cols <= cols_total
        assert rows * cols * 160 <= max(budget, 160)
    with pytest.raises(ValueError, match="max_memory"):
        pair_chunks(10, 10, 160, 0)


def test_gradcheck_points_and_verts() -> None:
    g = torch.Generator().manual_seed(0)
    m = _icosphere(0)
    pts = (torch.randn(6, 3, generator=g, dtype=torch.float64) * 1.5).requires_grad_()
    verts = m.verts.clone().requires_grad_()

    def f(p: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        r = point_mesh_distance(p, v, m.faces)
        return r.dists, r.closest

    assert torch.autograd.gradcheck(f, (pts, verts))


def test_gradients_finite_at_zero_distance_and_zero_area_faces() -> None:
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [2, 0, 0], [2, 0, 0]], dtype=torch.float64)
    f = torch.tensor([[0, 1, 2], [3, 4, 5], [0, 1, 3]])
    v.requires_grad_()
    pts = torch.tensor([[0.25, 0.25, 0.0], [2.0, 0.0, 0.0], [2.5, 0.1, 0.0], [1.0, 0.0, 0.0]], dtype=torch.float64)
    pts.requires_grad_()
    r = point_mesh_distance(pts, v, f)
    (r.dists.sum() + r.closest.sum()).backward()
    assert pts.grad is not None and v.grad is not None
    assert torch.isfinite(pts.grad).all() and torch.isfinite(v.grad).all()
    assert float(r.dists[0].detach()) == 0.0 and float(r.dists[1].detach()) == 0.0


def test_gradient_value_matches_analytic() -> None:
    # d/dp |p - q| = (p - q)/|p - q| in the face region (q moves with p along the plane).
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=torch.float64)
    f = torch.tensor([[0, 1, 2]])
    p = torch.tensor([[0.2, 0.3, 0.5]], dtype=torch.float64, requires_grad=True)
    point_mesh_distance(p, v, f).dists.sum().backward()
    assert p.grad is not None
    torch.testing.assert_close(p.grad, torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64))


@pytest.mark.cuda
@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA")
def test_cpu_and_cuda_agree() -> None:
    m = _icosphere(3, torch.float32)
    pts = torch.randn(2000, 3) * 1.5
    rc = point_mesh_distance(pts, m)
    rg = point_mesh_distance(pts.cuda(), m.to("cuda"))
    assert float((rc.dists - rg.dists.cpu()).abs().max()) <= 1e-6 * float(m.bbox_diagonal())


class TestBadInput:
    verts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    faces = torch.tensor([[0, 1, 2]])
    pts = torch.zeros(4, 3)

    def test_wrong_point_shape(self) -> None:
        with pytest.raises(ShapeError, match=r"points: expected shape \(P, 3\), found \(4, 2\)"):
            point_mesh_distance(torch.zeros(4, 2), self.verts, self.faces)

    def test_wrong_face_shape(self) -> None:
        with pytest.raises(ShapeError, match=r"faces: expected shape \(F, 3\), found \(1, 4\)"):
            point_mesh_distance(self.pts, self.verts, torch.tensor([[0, 1, 2, 0]]))

    def test_nan_points(self) -> None:
        with pytest.raises(NonFiniteError, match="points: expected finite values, found 1 NaN/Inf"):
            point_mesh_distance(torch.tensor([[0.0, float("nan"), 0]]), self.verts, self.faces)

    def test_inf_verts(self) -> None:
        v = self.verts.clone()
        v[0, 0] = float("inf")
        with pytest.raises(NonFiniteError, match="verts"):
            point_mesh_distance(self.pts, v, self.faces)

    def test_face_index_out_of_range(self) -> None:
        with pytest.raises(
            IndexRangeError, match=r"faces: expected vertex indices in \[0, 2\], found values in \[0, 5\]"
        ):
            point_mesh_distance(self.pts, self.verts, torch.tensor([[0, 1, 5]]))

    def test_negative_face_index(self) -> None:
        with pytest.raises(IndexRangeError, match="faces"):
            point_mesh_distance(self.pts, self.verts, torch.tensor([[0, -1, 2]]))

    def test_float_faces(self) -> None:
        with pytest.raises(DTypeError, match="faces: expected an integer tensor"):
            point_mesh_distance(self.pts, self.verts, self.faces.float())

    def test_integer_coordinates(self) -> None:
        with pytest.raises(DTypeError, match="points: expected a floating-point tensor"):
            point_mesh_distance(torch.zeros(4, 3, dtype=torch.long), self.verts, self.faces)
        with pytest.raises(DTypeError, match="verts"):
            point_mesh_distance(self.pts, self.verts.long(), self.faces)

    def test_empty_points(self) -> None:
        with pytest.raises(EmptyInputError, match="points"):
            point_mesh_distance(torch.zeros(0, 3), self.verts, self.faces)

    def test_empty_mesh(self) -> None:
        with pytest.raises(EmptyInputError, match="faces: mesh 0 has no faces"):
            point_mesh_distance(self.pts, self.verts, torch.zeros(0, 3, dtype=torch.long))

    def test_a_mesh_without_faces_in_a_batch(self) -> None:
        batch = [(self.verts, self.faces), (self.verts, torch.zeros(0, 3, dtype=torch.long))]
        with pytest.raises(EmptyInputError, match="faces: mesh 1 has no faces but 3 query points"):
            point_mesh_distance([self.pts[:2], self.pts[:3]], batch)
        # without query points of its own, a mesh without faces is no error
        assert point_mesh_distance([self.pts[:2], self.pts[:0]], batch).dists.shape == (2,)

    def test_wrong_mesh_type(self) -> None:
        with pytest.raises(TypeError, match=r"mesh: expected a Mesh, a \(verts, faces\) tuple or a trimesh\.Trimesh"):
            point_mesh_distance(self.pts, "not a mesh")  # type: ignore[arg-type]

    def test_mismatched_batch_sizes(self) -> None:
        with pytest.raises(ValueError, match="points: expected 2 point sets"):
            point_mesh_distance(self.pts, [(self.verts, self.faces), (self.verts, self.faces)])

    def test_bad_backend(self) -> None:
        with pytest.raises(ValueError, match="backend: expected one of"):
            point_mesh_distance(self.pts, self.verts, self.faces, backend="nope")

    def test_errors_subclass_builtins(self) -> None:
        assert issubclass(ShapeError, ValueError) and issubclass(DTypeError, TypeError)

    @pytest.mark.cuda
    @pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA")
    def test_mixed_devices(self) -> None:
        with pytest.raises(DeviceError, match="points on cpu"):
            point_mesh_distance(self.pts, self.verts.cuda(), self.faces.cuda())


def test_points_above_an_edge_get_barycentrics_on_the_triangle() -> None:
    # Found by hypothesis (2026-12-07): the face region's test was v + w <= 1 while the returned u is 1 - v - w,
    # and the two round differently: a point above edge BC was taken as inside with u = -1.1e-16 (7 % of such points
    # of random triangles), a closest point off the triangle by rounding. Every backend tests u as computed.
    p = torch.tensor([-3.945273770120485, 9.937690189904185, 3.372209607946025], dtype=torch.float64)
    a = torch.tensor([8.414953682439204, 2.900482402455296, 5.822957843606073], dtype=torch.float64)
    b = torch.tensor([-1.3656812081152214, 5.33282322482351, 0.48245037969146765], dtype=torch.float64)
    c = torch.tensor([-6.318535550460076, 7.812886404208022, 5.187602572734299], dtype=torch.float64)
    r = closest_point_on_triangle(p, a, b, c)
    assert float(r.bary.min()) >= 0.0 and float(r.bary[0]) == 0.0  # on edge BC
    g = torch.Generator().manual_seed(0)
    tri = torch.rand(3, 20000, 3, generator=g, dtype=torch.float64) * 20 - 10
    a, b, c = tri
    t = torch.rand(20000, 1, generator=g, dtype=torch.float64)
    n = torch.linalg.cross(b - a, c - a)
    points = b + t * (c - b) + n * torch.rand(20000, 1, generator=g, dtype=torch.float64) * 0.1
    r = closest_point_on_triangle(points, a, b, c)
    assert bool((r.bary >= 0).all())
    mesh = Mesh(tri.transpose(0, 1).reshape(-1, 3), torch.arange(60000).reshape(-1, 3))
    for backend in ("bruteforce", "bvh", "pruned"):
        out = point_mesh_distance(points[:2000], Mesh(mesh.verts[:6000], mesh.faces[:2000]), backend=backend)
        if backend == "bruteforce":
            first = out
        else:  # every backend picks the same face and the same bits
            assert torch.equal(out.dists, first.dists) and torch.equal(out.face_idx, first.face_idx)


def _random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    g = np.random.default_rng(seed)
    return g.normal(scale=2.0, size=(n, 3)), g.normal(size=(n, 3, 3))


@pytest.mark.parametrize(
    ("dtype", "exponent"),
    [
        (torch.float32, 34),
        (torch.float32, 58),
        (torch.float32, -40),
        (torch.float32, -135),
        (torch.float64, 270),
        (torch.float64, -340),
        (torch.float64, -1040),
    ],
)
def test_large_and_tiny_triangles_keep_their_voronoi_region(dtype: torch.dtype, exponent: int) -> None:
    # Review V, F1: the region test's degree-4 products overflowed (float32 edges >~1.4e9, float64 >~4e76): the face
    # candidate was dropped and an edge point returned, 5x the squared distance at float32 1e10, NaN at 2e19; tiny
    # triangles underflowed the squared normal the same way. Reference: the exact closest point of the same (rounded)
    # inputs, computed at unit magnitude (a power of two scales exactly).
    scale = 2.0**exponent
    pts, tri = _random_pairs(300, 7)
    p, a, b, c = (torch.from_numpy(x).to(dtype) * scale for x in (pts, tri[:, 0], tri[:, 1], tri[:, 2]))
    assert bool(torch.isfinite(torch.stack([p, a, b, c])).all())
    r = closest_point_on_triangle(p, a, b, c)
    unit = [x.double().numpy() / scale for x in (p, a, b, c)]
    ref = np.stack([reference.closest_point_triangle_exact(*q) for q in zip(*unit, strict=True)])
    ref_sq = ((unit[0] - ref) ** 2).sum(-1)
    size = float(np.abs(np.stack(unit)).max())
    eps, spacing = torch.finfo(dtype).eps, torch.finfo(dtype).tiny * torch.finfo(dtype).eps
    # Measured at unit magnitude: float32 <= 4e-7, float64 <= 1e-15 of the size. A subnormal closest point is formed
    # as three products and two sums, each rounded to the subnormal grid (half its spacing each: measured <= 1.3
    # spacings), which at 2**-135 is 2**-14 of the size.
    atol = 16 * eps * size + 4 * spacing / scale
    np.testing.assert_allclose(r.closest.double().numpy() / scale, ref, rtol=0, atol=atol)
    sq = r.sq_dists.double().numpy()
    np.testing.assert_allclose(sq, ref_sq * scale * scale, rtol=0, atol=(32 * eps * size**2) * scale * scale + spacing)
    assert bool((r.bary >= 0).all()) and bool((r.bary <= 1).all())


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_range_scaling_leaves_ordinary_pairs_bit_for_bit(dtype: torch.dtype) -> None:
    # Pairs of ordinary size give the unscaled computation's bits, also beside pairs that need scaling.
    from torchmeshmetric.kernels.triangle import closest_point_on_triangle_unchecked

    pts, tri = _random_pairs(2000, 11)
    sizes = 10.0 ** np.random.default_rng(12).uniform(-3, 3, size=(2000, 1))
    p, a, b, c = (torch.from_numpy(x * sizes).to(dtype) for x in (pts, tri[:, 0], tri[:, 1], tri[:, 2]))
    want = closest_point_on_triangle_unchecked(p, a, b, c)
    for got in (closest_point_on_triangle(p, a, b, c), closest_point_on_triangle(p[None], a[None], b[None], c[None])):
        for g, w in zip(got, want, strict=True):
            assert torch.equal(g.reshape(w.shape), w)
    big = 1e15 if dtype == torch.float32 else 1e100  # needs scaling (and its squares fit): in the same call
    mixed = closest_point_on_triangle(*(torch.cat([x, x[:5] * big]) for x in (p, a, b, c)))
    for g, w in zip(mixed, want, strict=True):
        assert torch.equal(g[:2000], w)


def test_unrepresentable_squared_distance_is_an_error() -> None:
    a, b, c = torch.tensor([-3e38, 0, 0]), torch.tensor([-3e38, 1, 0]), torch.tensor([-3e38, 0, 1])
    with pytest.raises(NonFiniteError, match=r"points: the distances overflow torch\.float32"):
        closest_point_on_triangle(torch.tensor([3e38, 0, 0]), a, b, c)


def test_scaled_pairs_have_the_unit_gradient() -> None:
    pts, tri = _random_pairs(50, 3)
    unit = [torch.from_numpy(x) for x in (pts, tri[:, 0], tri[:, 1], tri[:, 2])]
    scale = 2.0**300
    big = [(x * scale).requires_grad_() for x in unit]
    small = [x.clone().requires_grad_() for x in unit]
    closest_point_on_triangle(*big).sq_dists.sum().backward()
    closest_point_on_triangle(*small).sq_dists.sum().backward()
    for x, y in zip(big, small, strict=True):
        assert x.grad is not None and y.grad is not None
        torch.testing.assert_close(x.grad / scale, y.grad, rtol=1e-12, atol=1e-12)
