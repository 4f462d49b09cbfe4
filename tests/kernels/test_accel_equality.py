"""Accelerated backends ("bvh", "pruned") against the brute-force reference: values, faces, gradients."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric.kernels.accel import bruteforce, pruned_faces
from torchmeshmetric.kernels.contract import FaceSet
from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.native import try_load

BACKENDS = ["bvh", "pruned"]
DTYPES = [torch.float32, torch.float64]


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    # Compile (or load from the cache) once for the module; a missing compiler would warn and fail here.
    assert try_load("bvh") is not None


def assert_same_faces(points, verts, faces, backend, **kw):
    ref = point_mesh_distance(points, verts, faces, backend="bruteforce", **kw)
    got = point_mesh_distance(points, verts, faces, backend=backend, **kw)
    diag = float((verts.amax(0) - verts.amin(0)).norm())
    torch.testing.assert_close(got.dists, ref.dists, rtol=0, atol=1e-6 * diag)
    same = got.face_idx == ref.face_idx
    if not bool(same.all()):
        # Only an equidistant face may differ (same brute-force squared distance, i.e. an exact tie).
        bad = (~same).nonzero()[:, 0]
        assert torch.equal(got.dists[bad], ref.dists[bad]), f"{backend}: different non-tied faces at {bad[:5]}"
    return ref, got


def _random_mesh(g: torch.Generator, nv: int, nf: int, dtype: torch.dtype):
    verts = torch.randn(nv, 3, generator=g, dtype=dtype)
    faces = torch.randint(0, nv, (nf, 3), generator=g)
    return verts, faces


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_random_meshes_exact_same_faces(backend, dtype):
    g = torch.Generator().manual_seed(1)
    verts, faces = _random_mesh(g, 300, 600, dtype)
    points = torch.randn(800, 3, generator=g, dtype=dtype) * 2
    ref, got = assert_same_faces(points, verts, faces, backend)
    assert torch.equal(got.face_idx, ref.face_idx)  # random data: no ties, identical faces


def _degenerate_mesh(dtype):
    verts = torch.tensor(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [3, 0, 0], [1, 0, 0], [0, 0, 1], [0.5, 0.5, 0.0]],
        dtype=dtype,
    )
    faces = torch.tensor(
        [
            [0, 1, 2],  # regular
            [1, 3, 2],  # shares an edge
            [1, 4, 5],  # collinear
            [4, 4, 4],  # a point
            [1, 6, 3],  # duplicated vertex (1 == 6 in position): zero area
            [0, 2, 7],  # perpendicular
            [0, 1, 2],  # duplicated face: exact tie everywhere
            [8, 8, 1],  # segment inside the first face
        ]
    )
    return verts, faces


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_degenerate_faces_vertices_and_edges(backend, dtype):
    verts, faces = _degenerate_mesh(dtype)
    g = torch.Generator().manual_seed(3)
    pts = [verts, 0.5 * (verts[faces[:, 0]] + verts[faces[:, 1]]), verts[faces].mean(1)]
    pts.append(torch.rand(400, 3, generator=g, dtype=dtype) * 4 - 1)
    points = torch.cat(pts)
    ref, got = assert_same_faces(points, verts, faces, backend)
    # Exact ties (duplicated faces, shared vertices/edges) resolve to the lowest index, like the brute force.
    assert torch.equal(got.face_idx, ref.face_idx)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(
    "mesh",
    [
        trimesh.creation.icosphere(subdivisions=3),
        trimesh.creation.capsule(height=2.0, radius=0.5, count=[24, 24]),
        trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=48, minor_sections=24),
    ],
    ids=["icosphere", "capsule", "torus"],
)
def test_real_shaped_meshes_near_surface_and_on_vertices(backend, mesh):
    rng = np.random.default_rng(4)
    verts = torch.tensor(mesh.vertices, dtype=torch.float32)
    faces = torch.tensor(mesh.faces)
    near = mesh.sample(800, seed=4) + rng.normal(scale=0.01, size=(800, 3))
    far = rng.normal(size=(300, 3)) * 5
    points = torch.cat([torch.tensor(np.concatenate([near, far]), dtype=torch.float32), verts[:500]])
    ref, got = assert_same_faces(points, verts, faces, backend)
    assert torch.equal(got.face_idx, ref.face_idx)


@pytest.mark.parametrize("backend", BACKENDS)
def test_marching_cubes_blob(backend):
    skimage = pytest.importorskip("skimage")
    x = np.linspace(-1.5, 1.5, 20)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    field = np.sqrt(X**2 + Y**2 + Z**2) - 1 + 0.2 * np.sin(3 * X) * np.cos(2 * Y)
    v, f, _, _ = skimage.measure.marching_cubes(field, 0.0, spacing=(x[1] - x[0],) * 3)
    verts, faces = torch.tensor(v.copy(), dtype=torch.float64), torch.tensor(f.astype(np.int64))
    g = torch.Generator().manual_seed(5)
    points = verts[torch.randint(0, len(verts), (800,), generator=g)] + 0.02 * torch.randn(
        800, 3, generator=g, dtype=torch.float64
    )
    assert_same_faces(points, verts, faces, backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_far_from_origin(backend, dtype):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    offset = torch.tensor([1e6, -2e6, 3e6], dtype=torch.float64)
    verts = (torch.tensor(mesh.vertices) + offset).to(dtype)
    faces = torch.tensor(mesh.faces)
    g = torch.Generator().manual_seed(6)
    points = (torch.randn(1000, 3, generator=g, dtype=torch.float64) * 1.2 + offset).to(dtype)
    points = torch.cat([points, verts[:100]])
    assert_same_faces(points, verts, faces, backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_ragged_batch(backend):
    g = torch.Generator().manual_seed(7)
    meshes, clouds = [], []
    for i, (nv, nf, npt) in enumerate([(50, 90, 150), (300, 600, 10), (4, 2, 100), (200, 400, 300)]):
        v, f = _random_mesh(g, nv, nf, torch.float64)
        meshes.append((v + 10.0 * i, f))
        clouds.append(torch.randn(npt, 3, generator=g, dtype=torch.float64) + 10.0 * i)
    # Packed tensors with lengths (local face indices per item).
    kw = {
        "points_lengths": torch.tensor([len(c) for c in clouds]),
        "verts_lengths": torch.tensor([len(v) for v, _ in meshes]),
        "faces_lengths": torch.tensor([len(f) for _, f in meshes]),
    }
    args = (torch.cat(clouds), torch.cat([v for v, _ in meshes]), torch.cat([f for _, f in meshes]))
    ref = point_mesh_distance(*args, backend="bruteforce", **kw)
    got = point_mesh_distance(*args, backend=backend, **kw)
    torch.testing.assert_close(got.dists, ref.dists, rtol=0, atol=1e-12)
    assert torch.equal(got.face_idx, ref.face_idx)


@pytest.mark.parametrize("backend", BACKENDS)
def test_gradients_equal_bruteforce(backend):
    g = torch.Generator().manual_seed(8)
    v0, faces = _random_mesh(g, 60, 120, torch.float64)
    p0 = torch.randn(200, 3, generator=g, dtype=torch.float64)
    grads = []
    for b in ("bruteforce", backend):
        v, p = v0.clone().requires_grad_(), p0.clone().requires_grad_()
        point_mesh_distance(p, v, faces, backend=b).dists.square().sum().backward()
        grads.append((p.grad, v.grad))
    torch.testing.assert_close(grads[1][0], grads[0][0], rtol=0, atol=0)
    torch.testing.assert_close(grads[1][1], grads[0][1], rtol=0, atol=0)


def test_pruned_respects_small_memory_budget():
    g = torch.Generator().manual_seed(9)
    verts, faces = _random_mesh(g, 200, 400, torch.float64)
    points = torch.randn(300, 3, generator=g, dtype=torch.float64)
    zeros = torch.zeros(300, dtype=torch.long)
    off = torch.tensor([0, 400])
    fb = torch.zeros(400, dtype=torch.long)
    small = pruned_faces(points, zeros, verts, faces, fb, off, 1 << 14)
    assert torch.equal(small, bruteforce.query_faces(None, FaceSet(verts, faces, fb, off), points, zeros, 1 << 24))


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    nv=st.integers(3, 40),
    nf=st.integers(1, 60),
    grid=st.booleans(),
    dtype=st.sampled_from(DTYPES),
)
def test_property_bvh_and_pruned_match_bruteforce(seed, nv, nf, grid, dtype):
    g = torch.Generator().manual_seed(seed)
    verts = torch.randn(nv, 3, generator=g, dtype=dtype)
    points = torch.randn(64, 3, generator=g, dtype=dtype)
    if grid:  # integer lattice: many exact ties and degenerate faces
        verts, points = verts.mul(2).round(), points.mul(2).round()
    faces = torch.randint(0, nv, (nf, 3), generator=g)
    ref = point_mesh_distance(points, verts, faces, backend="bruteforce")
    for backend in BACKENDS:
        got = point_mesh_distance(points, verts, faces, backend=backend)
        assert torch.equal(got.face_idx, ref.face_idx), backend
        assert torch.equal(got.dists, ref.dists), backend


# ------------------------------------------------------------------ nearest vertex


def assert_same_nearest(points, ref_points, backend, **kw):
    ref = nearest_vertex_distance(points, ref_points, backend="bruteforce", **kw)
    got = nearest_vertex_distance(points, ref_points, backend=backend, **kw)
    rp = ref_points
    diag = float((rp.amax(0) - rp.amin(0)).norm())
    torch.testing.assert_close(got.dists, ref.dists, rtol=0, atol=1e-6 * diag)
    # Every backend selects by the same computed squared distance, lowest index among equal ones.
    assert torch.equal(got.idx, ref.idx)
    assert torch.equal(got.dists, ref.dists)
    return ref, got


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_nearest_random_and_duplicates(backend, dtype):
    g = torch.Generator().manual_seed(10)
    ref_points = torch.randn(3000, 3, generator=g, dtype=dtype)
    ref_points[100:200] = ref_points[:100]  # exact duplicates: lowest index must win
    points = torch.cat([torch.randn(2000, 3, generator=g, dtype=dtype) * 1.5, ref_points[:300]])
    ref, got = assert_same_nearest(points, ref_points, backend)
    assert torch.equal(got.idx[-300:], ref.idx[-300:])
    assert bool((got.idx[-200:-100] < 100).all())


@pytest.mark.parametrize("backend", BACKENDS)
def test_nearest_lattice_ties_far_from_origin_and_ragged(backend):
    g = torch.Generator().manual_seed(11)
    lattice = torch.stack(torch.meshgrid(*[torch.arange(8.0, dtype=torch.float64)] * 3, indexing="ij"), -1)
    lattice = lattice.reshape(-1, 3) + 1e6
    points = torch.randint(0, 16, (500, 3), generator=g).double() / 2 + 1e6  # on midpoints: exact ties
    ref, got = assert_same_nearest(points, lattice, backend)
    assert torch.equal(got.idx, ref.idx)
    clouds = [torch.randn(n, 3, generator=g, dtype=torch.float32) + i for i, n in enumerate([100, 7, 900])]
    refs = [torch.randn(n, 3, generator=g, dtype=torch.float32) + i for i, n in enumerate([400, 1000, 1])]
    assert_same_nearest(
        torch.cat(clouds),
        torch.cat(refs),
        backend,
        points_lengths=torch.tensor([len(c) for c in clouds]),
        ref_lengths=torch.tensor([len(r) for r in refs]),
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_nearest_gradients_equal_bruteforce(backend):
    g = torch.Generator().manual_seed(12)
    p0, r0 = (
        torch.randn(300, 3, generator=g, dtype=torch.float64),
        torch.randn(200, 3, generator=g, dtype=torch.float64),
    )
    grads = []
    for b in ("bruteforce", backend):
        p, r = p0.clone().requires_grad_(), r0.clone().requires_grad_()
        nearest_vertex_distance(p, r, backend=b).dists.sum().backward()
        grads.append((p.grad, r.grad))
    assert torch.equal(grads[0][0], grads[1][0]) and torch.equal(grads[0][1], grads[1][1])


def test_auto_picks_bvh_on_cpu_at_every_size_and_bruteforce_or_pruned_without_it(monkeypatch):
    from torchmeshmetric import native
    from torchmeshmetric.kernels import select

    cpu = torch.device("cpu")
    small, large = 10 * 10, 5000 * 1000
    # Where the extension cannot be built: small problems on the brute force, large ones pruned.
    monkeypatch.setattr(native, "try_load", lambda name: None)
    assert select.auto_backend_name(cpu, torch.float32, small) == "bruteforce"
    assert select.auto_backend_name(cpu, torch.float32, large) == "pruned"
    # Otherwise the BVH at every size (built first where needed, whether or not a build existed).
    monkeypatch.setattr(native, "try_load", lambda name: object())
    assert select.auto_backend_name(cpu, torch.float32, small) == "bvh"
    assert select.auto_backend_name(cpu, torch.float32, large) == "bvh"


def test_bvh_ready_reflects_the_compiled_extension():
    from torchmeshmetric.native import ready

    assert try_load("bvh") is not None and ready("bvh")


@pytest.mark.cuda
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("backend", BACKENDS)
def test_cuda_matches_cpu_bruteforce(backend):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    verts, faces = torch.tensor(mesh.vertices, dtype=torch.float32), torch.tensor(mesh.faces)
    points = torch.randn(2000, 3, generator=torch.Generator().manual_seed(13)) * 1.3
    ref = point_mesh_distance(points, verts, faces, backend="bruteforce")
    got = point_mesh_distance(points.cuda(), verts.cuda(), faces.cuda(), backend=backend)
    diag = float((verts.amax(0) - verts.amin(0)).norm())
    torch.testing.assert_close(got.dists.cpu(), ref.dists, rtol=0, atol=1e-6 * diag)
